"""`mobman-eval`: benchmark policies side by side (`run`), sweep a grid (`sweep`), reproduce the paper (`paper`),
measure speed (`speed`).

```
mobman-eval run --env WheeledPuma-Circle-v0 --policy nnbc --policy jmpi --episodes 20 --dynamics kinematic
mobman-eval run ... --backend ray --address auto    # the same episodes as Ray tasks on a cluster
mobman-eval sweep --config sweep.yaml --workers 2   # a resumable grid (`--example` prints one)
mobman-eval paper                # the paper's section IV, both dynamics modes, 20 reported seeds
mobman-eval speed                # env steps/s, predict microseconds, episodes/s
```

`main(argv=None)` parses into a frozen config and calls one function, so tests call it in-process. Bad input
(unknown env id or policy, missing model file, existing non-empty --out, malformed --env-kwargs) stops before
any rollout with exit code 2 and a message naming the bad value and what is accepted.
"""

from __future__ import annotations

import argparse
import json
import sys

from eval.config import BACKEND_CHOICES, DYNAMICS_CHOICES, SAVE_ARRAYS_CHOICES, EvalConfig, EvalError
from eval.metrics import DEFAULT_TOLERANCE


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows "(default: X)" only where X says something (not None/False) and the help does not already."""

    def _get_help_string(self, action):
        text = action.help or ""
        if action.default in (None, False, argparse.SUPPRESS) or "default:" in text:
            return text
        return super()._get_help_string(action)


def _policy_help() -> str:
    try:
        from policies.registry import KNOWN_POLICIES, SPEC_FORMS

        items = {**KNOWN_POLICIES, **SPEC_FORMS}
        return "; ".join(f"{k}: {v}" for k, v in items.items())
    except Exception:
        return "nnbc, nnbc-full, nnbc-plus, jmpi, jmpi-full, oracle, oracle-full, zero, random, sb3:PATH, module:attr"


def _env_kwargs(text: str) -> dict:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(
            f'--env-kwargs must be a JSON object such as \'{{"path": {{"type": "circle", "duration": 2.0}}}}\' ({exc})'
        ) from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"--env-kwargs must be a JSON object, got {text!r}")
    return value


def add_backend_arguments(p) -> None:
    """--workers, --backend and --address (run and sweep)."""
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        help="parallel episodes: worker processes (one PyBullet client each), or with --backend ray and "
        "no --address the CPUs of the local Ray instance started for the run",
    )
    p.add_argument(
        "--backend",
        choices=BACKEND_CHOICES,
        default="local",
        help='where episodes run: local processes, or one Ray task per episode (pip install "mobman[ray]")',
    )
    p.add_argument(
        "--address",
        default=None,
        metavar="ADDRESS",
        help="with --backend ray: the cluster to join (auto, HOST:6379, ray://HOST:10001); default: a "
        "local Ray instance",
    )


def _add_run(sub) -> None:
    p = sub.add_parser(
        "run",
        help="benchmark policies on identical episodes",
        description="Run every policy on the same episodes (episode k of every env/dynamics/policy uses "
        "seed S + k) and write results.json, results.csv, summary.md, plots and config.json.",
        formatter_class=HelpFormatter,
    )
    p.add_argument(
        "--env", action="append", dest="envs", metavar="ID", help="env id, repeatable (default: WheeledPuma-Circle-v0)"
    )
    p.add_argument(
        "--policy",
        action="append",
        dest="policies",
        metavar="SPEC",
        help="policy spec, repeatable (default: nnbc, jmpi, oracle). " + _policy_help(),
    )
    p.add_argument("--episodes", type=int, default=5, help="episodes per env, dynamics mode and policy")
    p.add_argument("--seed", type=int, default=10_000, help="seed of episode 0 (episode k uses seed + k)")
    p.add_argument("--out", default=None, help="output directory (default: runs/run-<UTC timestamp>)")
    p.add_argument("--overwrite", action="store_true", help="write into an existing non-empty --out")
    add_backend_arguments(p)
    p.add_argument(
        "--dynamics", action="append", choices=DYNAMICS_CHOICES, help="dynamics mode, repeatable (default: physics)"
    )
    p.add_argument(
        "--model-error",
        type=float,
        default=None,
        help="relative std of the true robot's lengths (default: the env's, 0.05)",
    )
    p.add_argument("--obs-noise", type=float, default=None, help="position sensor noise std, m (default: 0)")
    p.add_argument(
        "--env-kwargs",
        type=_env_kwargs,
        default={},
        metavar="JSON",
        help='further env arguments as JSON, e.g. \'{"path": {"type": "circle", "duration": 2.0}}\'',
    )
    p.add_argument(
        "--tolerance", type=float, default=DEFAULT_TOLERANCE, help="success threshold on the max tracking error, m"
    )
    p.add_argument("--video", action="store_true", help="also write an MP4 (or GIF) of episode 0 per policy")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument(
        "--save-arrays",
        choices=SAVE_ARRAYS_CHOICES,
        default="first",
        help="per-step arrays in episodes.npz: episode 0 of each condition (first), every episode (all: "
        "about 0.3 MB of memory per 20 s episode until the end of the run), or none",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar and no table")


def _run(args) -> int:
    from eval.runner import run

    config = EvalConfig(
        envs=tuple(args.envs or ("WheeledPuma-Circle-v0",)),
        policies=tuple(args.policies or ("nnbc", "jmpi", "oracle")),
        episodes=args.episodes,
        seed=args.seed,
        out=args.out,
        overwrite=args.overwrite,
        workers=args.workers,
        backend=args.backend,
        address=args.address,
        dynamics=tuple(args.dynamics or ("physics",)),
        model_error=args.model_error,
        obs_noise=args.obs_noise,
        env_kwargs=args.env_kwargs,
        tolerance=args.tolerance,
        video=args.video,
        plots=not args.no_plots,
        save_arrays=args.save_arrays,
        progress=not args.quiet,
    )
    result = run(config)
    n_failed = sum(r["status"] != "ok" for r in result.episodes)
    if n_failed:
        print(f"warning: {n_failed} episode(s) failed; tracebacks in {result.out / 'results.json'}", file=sys.stderr)
    return 0


def build_parser() -> argparse.ArgumentParser:
    from eval import paper, speed, sweep

    parser = argparse.ArgumentParser(prog="mobman-eval", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", metavar="{run,sweep,paper,speed}")
    sub.required = True
    _add_run(sub)
    sweep.add_parser(sub)
    paper.add_parser(sub)
    speed.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.command == "run":
            return _run(args)
        return args.func(args)
    except EvalError as exc:
        print(f"mobman-eval {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

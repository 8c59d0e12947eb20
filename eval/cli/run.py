"""`mobman-eval run`: benchmark policies on identical episodes (parses into `EvalConfig`, calls `eval.runner.run`)."""

from __future__ import annotations

import sys

from eval.cli.common import (
    HelpFormatter,
    add_backend_arguments,
    default,
    env_kwargs_arg,
    policy_help,
)
from eval.config import DYNAMICS_CHOICES, SAVE_ARRAYS_CHOICES, STDOUT_FORMATS, EvalConfig
from eval.runner import run


def add_parser(sub) -> None:
    p = sub.add_parser(
        "run",
        help="benchmark policies on identical episodes",
        description="Run every policy on the same episodes (episode k of every env/dynamics/policy uses "
        "seed S + k) and write results.json, results.csv, summary.md, plots and config.json.",
        formatter_class=HelpFormatter,
    )
    p.add_argument(
        "--env",
        action="append",
        dest="envs",
        metavar="ID",
        help=f"env id, repeatable (default: {', '.join(default(EvalConfig, 'envs'))})",
    )
    p.add_argument(
        "--policy",
        action="append",
        dest="policies",
        metavar="SPEC",
        help=f"policy spec, repeatable (default: {', '.join(default(EvalConfig, 'policies'))}). " + policy_help(),
    )
    p.add_argument(
        "--episodes",
        type=int,
        default=default(EvalConfig, "episodes"),
        help="episodes per env, dynamics mode and policy",
    )
    p.add_argument(
        "--seed", type=int, default=default(EvalConfig, "seed"), help="seed of episode 0 (episode k uses seed + k)"
    )
    p.add_argument("--out", default=None, help="output directory (default: runs/run-<UTC timestamp>)")
    p.add_argument("--overwrite", action="store_true", help="write into an existing non-empty --out")
    add_backend_arguments(p)
    p.add_argument(
        "--dynamics",
        action="append",
        choices=DYNAMICS_CHOICES,
        help=f"dynamics mode, repeatable (default: {', '.join(default(EvalConfig, 'dynamics'))})",
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
        type=env_kwargs_arg,
        default={},
        metavar="JSON",
        help='further env arguments as JSON, e.g. \'{"path": {"type": "circle", "duration": 2.0}}\'',
    )
    p.add_argument(
        "--tolerance",
        type=float,
        default=default(EvalConfig, "tolerance"),
        help="success threshold on the max tracking error, m",
    )
    p.add_argument(
        "--settle-time",
        type=float,
        default=default(EvalConfig, "settle_time"),
        metavar="S",
        help="steady-state errors (steady_max_error_m, steady_rms_error_m) use the samples at t >= S, s",
    )
    p.add_argument("--video", action="store_true", help="also write an MP4 (or GIF) of episode 0 per policy")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument(
        "--save-arrays",
        choices=SAVE_ARRAYS_CHOICES,
        default=default(EvalConfig, "save_arrays"),
        help="per-step arrays in episodes.npz: episode 0 of each condition (first), every episode (all: "
        "about 0.3 MB of memory per 20 s episode until the end of the run), or none",
    )
    p.add_argument(
        "--format",
        dest="stdout_format",
        choices=STDOUT_FORMATS,
        default=default(EvalConfig, "stdout_format"),
        help="what is printed on stdout at the end: a console table, or the content of summary.md (markdown), "
        "results.json (json) or results.csv (csv), e.g. to pipe it; the files are written in any case and "
        "progress goes to stderr",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar and nothing on stdout")


def main(args) -> int:
    config = EvalConfig(
        envs=tuple(args.envs or default(EvalConfig, "envs")),
        policies=tuple(args.policies or default(EvalConfig, "policies")),
        episodes=args.episodes,
        seed=args.seed,
        out=args.out,
        overwrite=args.overwrite,
        workers=args.workers,
        batch_size=args.batch_size,
        backend=args.backend,
        address=args.address,
        dynamics=tuple(args.dynamics or default(EvalConfig, "dynamics")),
        model_error=args.model_error,
        obs_noise=args.obs_noise,
        env_kwargs=args.env_kwargs,
        tolerance=args.tolerance,
        settle_time=args.settle_time,
        video=args.video,
        plots=not args.no_plots,
        save_arrays=args.save_arrays,
        progress=not args.quiet,
        stdout_format=args.stdout_format,
    )
    result = run(config)
    n_failed = sum(r["status"] != "ok" for r in result.episodes)
    if n_failed:
        print(f"warning: {n_failed} episode(s) failed; tracebacks in {result.out / 'results.json'}", file=sys.stderr)
    return 0

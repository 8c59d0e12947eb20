"""`mobman-train` (also `python -m train`; `train.cli.main(argv)` in-process).

    mobman-train --algo sac --env WheeledPuma-Circle-v0 --timesteps 100000 --seed 0 --out runs/sac-circle
    mobman-train --resume runs/sac-circle [--timesteps 200000]
    mobman-train report runs/ppo-s0 runs/ppo-s1 ... --out docs/results/rl-v2   # several seeds: train.report

Every argument is checked (and the envs built once) before training starts. Exit codes: 0 done, 2 bad
arguments, 1 trained but the final evaluation failed (the
command to rerun it is logged), 130 interrupted by Ctrl-C (a checkpoint was saved; `--resume DIR` continues).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from mobman_env import __version__
from mobman_env.sim import DYNAMICS_MODES
from train import algos, zoo
from train.config import LEARNING_ENV_KWARGS, TrainConfig

#: CLI options that may be given with --resume (everything else comes from the run's config.json).
RESUME_OPTIONS = ("timesteps", "no_progress")


def build_parser() -> argparse.ArgumentParser:
    d = TrainConfig()
    p = argparse.ArgumentParser(
        prog="mobman-train",
        description="Train a Stable-Baselines3 agent on a mobman env; the run folder holds model.zip, "
        "vecnormalize.pkl and config.json, which `mobman-eval run --policy sb3:DIR/model.zip` loads.",
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    p.add_argument("--algo", choices=algos.algo_names(), help=f"algorithm (default {d.algo})")
    p.add_argument("--env", dest="env_id", metavar="ID", help=f"env id (default {d.env_id})")
    p.add_argument("--timesteps", type=int, metavar="N", help=f"total env steps (default {d.timesteps})")
    p.add_argument(
        "--n-envs", type=int, metavar="K", help=f"parallel envs; SubprocVecEnv when > 1 (default {d.n_envs})"
    )
    p.add_argument("--seed", type=int, metavar="S", help=f"training seed, a development seed 0-999 (default {d.seed})")
    p.add_argument("--out", metavar="DIR", help="run folder (default runs/train-<algo>-<task>-<timestamp>)")
    p.add_argument("--overwrite", action="store_true", help="allow a non-empty --out")
    p.add_argument("--dynamics", choices=DYNAMICS_MODES, help=f"env dynamics (default {d.dynamics})")
    p.add_argument(
        "--env-kwargs",
        metavar="JSON",
        help=f"extra env arguments as a JSON object, merged over the learning defaults "
        f'{json.dumps(LEARNING_ENV_KWARGS)} (use null to unset one, e.g. {{"error_bound": null}})',
    )
    p.add_argument("--alive-bonus", type=float, metavar="R", help=f"training reward per step (default {d.alive_bonus})")
    p.add_argument(
        "--hyperparams",
        metavar="FILE",
        help="YAML or JSON file of hyperparameters overriding the algorithm's defaults: a flat mapping, a "
        "mapping per algorithm name, or an rl-baselines3-zoo file (a mapping per env id, e.g. "
        "train/hyperparams/ppo.yml; its n_timesteps, normalize and env_wrapper set those settings; see train.zoo)",
    )
    p.add_argument(
        "--eval-freq",
        type=int,
        metavar="N",
        help=f"evaluate on development seeds every N steps, 0: never (default {d.eval_freq})",
    )
    p.add_argument(
        "--eval-episodes", type=int, metavar="N", help=f"episodes per evaluation (default {d.eval_episodes})"
    )
    p.add_argument(
        "--final-eval-episodes",
        type=int,
        metavar="N",
        help=f"episodes of the final evaluation on reported seeds, 0: skip (default {d.final_eval_episodes})",
    )
    p.add_argument(
        "--checkpoint-freq", type=int, metavar="N", help=f"checkpoint every N steps (default {d.checkpoint_freq})"
    )
    p.add_argument("--torch-threads", type=int, metavar="T", help=f"torch threads (default {d.torch_threads})")
    p.add_argument("--device", help=f"torch device (default {d.device})")
    p.add_argument("--tensorboard", action="store_true", help="write TensorBoard logs to DIR/tensorboard")
    p.add_argument(
        "--no-progress",
        "--quiet",
        action="store_true",
        help="no progress bar (there is none either when stderr is not a terminal, e.g. in CI logs)",
    )
    p.add_argument("--verbose", type=int, choices=(0, 1, 2), help="SB3 verbosity")
    p.add_argument("--resume", metavar="DIR", help="continue the run in DIR from its latest checkpoint")
    return p


def load_hyperparams(path: str, algo: str, env_id: str | None = None) -> dict:
    """Read a YAML/JSON hyperparameter file into TrainConfig fields ("hyperparams" and, for an rl-zoo entry,
    the fields its zoo keys set, `train.zoo`): a flat mapping of hyperparameters, one mapping per algorithm
    name, or rl-baselines3-zoo's format, one entry per env id (the entry of `env_id` is taken)."""
    file = Path(path)
    if not file.is_file():
        raise ValueError(f"--hyperparams {path}: no such file")
    text = file.read_text()
    try:
        if file.suffix.lower() == ".json":
            data = json.loads(text)
        else:
            import yaml

            data = yaml.safe_load(text)
    except Exception as exc:
        raise ValueError(f"--hyperparams {path}: cannot parse ({exc})") from None
    if not isinstance(data, dict):
        raise ValueError(f"--hyperparams {path}: expected a mapping of hyperparameters, got {type(data).__name__}")
    if zoo.is_env_keyed(data):
        env_id = env_id or TrainConfig().env_id
        if env_id not in data:
            raise ValueError(
                f"--hyperparams {path} is an rl-zoo file with entries for {sorted(data)} but not for --env {env_id}"
            )
        return zoo.entry_fields(data[env_id], f"--hyperparams {path} ({env_id})")
    if set(data) & set(algos.ALGOS):
        if algo not in data:
            raise ValueError(
                f"--hyperparams {path} has entries for {sorted(set(data) & set(algos.ALGOS))} but not for --algo {algo}"
            )
        data = data[algo]
    return {"hyperparams": dict(data or {})}


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    fields = {}
    for name in (
        "algo",
        "env_id",
        "timesteps",
        "n_envs",
        "seed",
        "out",
        "dynamics",
        "alive_bonus",
        "eval_freq",
        "eval_episodes",
        "final_eval_episodes",
        "checkpoint_freq",
        "torch_threads",
        "device",
        "verbose",
    ):
        value = getattr(args, name)
        if value is not None:
            fields[name] = value
    fields["overwrite"] = args.overwrite
    fields["tensorboard"] = args.tensorboard
    fields["progress_bar"] = _progress(args)
    if args.env_kwargs is not None:
        try:
            extra = json.loads(args.env_kwargs)
        except json.JSONDecodeError as exc:
            raise ValueError(
                f"--env-kwargs is not valid JSON ({exc}): {args.env_kwargs!r}; e.g. '{{\"model_error\": 0.0}}'"
            ) from None
        if not isinstance(extra, dict):
            raise ValueError(f"--env-kwargs must be a JSON object, got {args.env_kwargs!r}")
        merged = {**json.loads(json.dumps(LEARNING_ENV_KWARGS)), **extra}
        fields["env_kwargs"] = {k: v for k, v in merged.items() if v is not None}
    if args.hyperparams is not None:  # what the command line sets wins over the file
        file_fields = load_hyperparams(args.hyperparams, args.algo or TrainConfig().algo, args.env_id)
        fields = {**file_fields, **fields}
    return TrainConfig(**fields)


def _progress(args: argparse.Namespace) -> bool:
    """A progress bar unless --no-progress, and only on a terminal (a CI log would get one line per update)."""
    return not args.no_progress and hasattr(sys.stderr, "isatty") and sys.stderr.isatty()


def require_rl() -> None:
    """Raise ValueError naming the extra to install when Stable-Baselines3 or torch is missing."""
    try:
        import stable_baselines3  # noqa: F401
        import torch  # noqa: F401
    except ImportError as exc:
        raise ValueError(
            f"mobman-train needs Stable-Baselines3 and torch, which are not installed here ({exc}); install "
            f'them with pip install "mobman[rl]"'
        ) from None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["report"]:
        from train.report_cli import main as report_main

        return report_main(argv[1:])
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        require_rl()
    except ValueError as exc:
        print(f"mobman-train: error: {exc}", file=sys.stderr)
        return 2
    from train.run import TrainingInterrupted, resume, run

    try:
        if args.resume:
            given = [
                a for a, v in vars(args).items() if a not in RESUME_OPTIONS + ("resume",) and v not in (None, False)
            ]
            if given:
                raise ValueError(
                    f"--resume takes its settings from the run's config.json; only --timesteps and "
                    f"--no-progress may be given with it, not {', '.join('--' + g.replace('_', '-') for g in given)}"
                )
            summary = resume(args.resume, timesteps=args.timesteps, progress_bar=_progress(args))
        else:
            summary = run(config_from_args(args))
    except TrainingInterrupted as exc:
        print(f"mobman-train: {exc}", file=sys.stderr)
        return 130
    except ValueError as exc:
        print(f"mobman-train: error: {exc}", file=sys.stderr)
        return 2
    print(json.dumps({k: v for k, v in summary.items() if k != "final_eval_error"}, indent=2))
    if "final_eval_error" in summary:
        print(
            "mobman-train: training finished and the model is saved, but the final evaluation failed (see "
            f"{summary['run_dir']}/train.log)",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())

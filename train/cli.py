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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from eval.cli.options import Opt, add_options, build, field_default, flags, given, json_object
from mobman_env import __version__
from mobman_env.sim import DYNAMICS_MODES
from train import algos, report_cli, zoo
from train.config import LEARNING_ENV_KWARGS, TrainConfig

#: The --help note on --resume (checkpoints hold pickles), beside mobman-eval's note on agents.
RESUME_TRUST_NOTE = (
    "Resume only run folders you trust: a checkpoint's model zip, vecnormalize_*.pkl and replay_buffer.pkl hold "
    "pickles; mobman reads them with a restricted unpickler (an allow-list of SB3, gymnasium, torch and numpy "
    "names), which narrows but does not sandbox what a crafted file can do. The same holds for agents given to "
    "`mobman-eval` and `mobman-train report`."
)

#: TrainConfig fields whose options may be given with --resume (everything else comes from the run's config.json).
RESUME_OPTIONS = ("timesteps", "progress_bar")


#: the options of a training run (`TrainConfig`'s fields)
OPTIONS = (
    Opt("algo", choices=algos.algo_names()),
    Opt("env_id", flag="--env", metavar="ID"),
    Opt("timesteps", metavar="N"),
    Opt("n_envs", metavar="K"),
    Opt("seed", metavar="S"),
    Opt("dynamics", choices=DYNAMICS_MODES),
    Opt(
        "env_kwargs",
        metavar="JSON",
        parse=str,  # a JSON object merged over LEARNING_ENV_KWARGS by config_from_args (null unsets a key)
        more='Given as a JSON object, merged over the default (null unsets a key, e.g. {"error_bound": null}).',
    ),
    Opt("alive_bonus", metavar="R"),
    Opt(
        "hyperparams",
        metavar="FILE",
        parse=str,  # read by load_hyperparams
        more="The file holds a flat mapping, a mapping per algorithm name, or an rl-baselines3-zoo entry per env id "
        "(e.g. train/hyperparams/ppo.yml; its n_timesteps, normalize and env_wrapper set those settings; see "
        "train.zoo). What the command line sets wins over the file.",
    ),
    Opt("eval_freq", metavar="N"),
    Opt("eval_episodes", metavar="N"),
    Opt("final_eval_episodes", metavar="N"),
    Opt("checkpoint_freq", metavar="N"),
    Opt("torch_threads", metavar="T"),
    "device",
    "tensorboard",
    Opt("out", metavar="DIR"),
    "overwrite",
    Opt("progress_bar", flag="--quiet", old=("--no-progress",)),
    Opt("verbose", choices=(0, 1, 2)),
)


@dataclass(frozen=True)
class Resume:
    """`mobman-train --resume DIR`: continue a run instead of starting one."""

    resume: str | None = None
    """Continue the run in this folder from its latest checkpoint; its config.json gives every setting but
    --timesteps (the new total) and --quiet."""


RESUME = (Opt("resume", metavar="DIR"),)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="mobman-train",
        description="Train a Stable-Baselines3 agent on a mobman env; the run folder holds model.zip, "
        "vecnormalize.pkl and config.json, which `mobman-eval run --policy sb3:DIR/model.zip` loads. "
        "`mobman-train report RUN_DIR...` evaluates several runs into one report.",
        epilog=RESUME_TRUST_NOTE,
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    add_options(p, TrainConfig, OPTIONS)
    add_options(p, Resume, RESUME)
    sub = p.add_subparsers(title="commands", dest="command", metavar="{report,speed,families,ship}")
    report_cli.add_parser(sub)
    speed = sub.add_parser(
        "speed",
        help="time the default PPO recipe's training (learner included) beside the same settings on Reacher-v5",
        description="Time model.learn of mobman-train's default PPO recipe on the native vector env and on "
        "MobMan-DevTrack-v0, interleaved with the same SB3 settings on Gymnasium's MuJoCo Reacher-v5 (the [bench] "
        "extra); writes train-speed.json and train-speed.md (see train.speed).",
    )
    speed.add_argument("--steps", type=int, default=81_920, metavar="N", help="env steps per timed learn (81920)")
    speed.add_argument("--repeats", type=int, default=3, metavar="N", help="timed repeats per env (3)")
    speed.add_argument("--out", default="runs/train-speed", metavar="DIR", help="output folder (runs/train-speed)")
    fam = sub.add_parser(
        "families",
        help="score agents trained with several seeds as families over one bench folder's episodes",
        description="Read a mobman-eval bench folder's results.json in which every seed of each family ran the "
        "same cells and seeds; write families.json and families.md (IQM and success with intervals over training "
        "seeds, the median-seed member to ship; see train.families).",
    )
    fam.add_argument("bench_dirs", nargs="+", metavar="BENCH_DIR", help="mobman-eval bench output folders")
    fam.add_argument(
        "--family", action="append", required=True, metavar="NAME=SPEC,...", help="a family and its seeds' specs"
    )
    fam.add_argument("--out", required=True, metavar="DIR", help="output folder")
    ship = sub.add_parser(
        "ship",
        help="ship a trained run as sb3:NAME with its model card",
        description="Copy a finished run's model.zip, vecnormalize.pkl and config.json into MODELS_DIR/NAME and "
        "write its model card from committed results (see train.model_card).",
    )
    ship.add_argument("run_dir", metavar="RUN_DIR", help="a finished mobman-train run folder")
    ship.add_argument("--name", required=True, help="the shipped name (sb3:NAME)")
    ship.add_argument("--train-commit", required=True, metavar="SHA", help="the commit of the training code")
    ship.add_argument("--families", metavar="DIR", help="a mobman-train families folder of its family")
    ship.add_argument("--scorecard", action="append", default=[], metavar="DIR", help="a bench folder it is on")
    ship.add_argument("--models-dir", default="policies/models", metavar="DIR", help="(policies/models)")
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
    """The TrainConfig of a parsed command line: what it gives over the hyperparameter file over the defaults;
    --env-kwargs merged over `LEARNING_ENV_KWARGS`; a progress bar only on a terminal."""
    fields = given(args, OPTIONS)
    fields.pop("hyperparams", None)
    fields["progress_bar"] = _progress(args)
    text = fields.pop("env_kwargs", None)
    if text is not None:
        try:
            extra = json_object(text)
        except argparse.ArgumentTypeError as exc:
            raise ValueError(str(exc)) from None
        merged = {**json.loads(json.dumps(LEARNING_ENV_KWARGS)), **extra}
        fields["env_kwargs"] = {k: v for k, v in merged.items() if v is not None}
    hyperparams = getattr(args, "hyperparams", None)
    if hyperparams is not None:  # what the command line sets wins over the file
        algo = fields.get("algo", field_default(TrainConfig, "algo"))
        fields = {**load_hyperparams(hyperparams, algo, fields.get("env_id")), **fields}
    return TrainConfig(**fields)


def _progress(args: argparse.Namespace) -> bool:
    """A progress bar unless --quiet, and only on a terminal (a CI log would get one line per update)."""
    return getattr(args, "progress_bar", True) and hasattr(sys.stderr, "isatty") and sys.stderr.isatty()


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


def _speed(args: Any) -> int:
    from train import speed

    if args.steps < 1 or args.repeats < 1:
        print(
            f"mobman-train speed: error: --steps and --repeats must be >= 1, got {args.steps}, {args.repeats}",
            file=sys.stderr,
        )
        return 2
    try:
        require_rl()
    except ValueError as exc:
        print(f"mobman-train: error: {exc}", file=sys.stderr)
        return 2
    res = speed.measure(speed.SpeedConfig(steps=args.steps, repeats=args.repeats, out=args.out))
    folder = speed.write(res, args.out)
    print(speed.markdown(res) + f"written to {folder}")
    return 0


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "command", None) == "speed":
        return _speed(args)
    if getattr(args, "command", None) == "ship":
        from train import model_card

        try:
            folder = model_card.ship(
                args.run_dir, args.name, args.models_dir, args.families, args.scorecard, args.train_commit
            )
        except (ValueError, OSError) as exc:
            print(f"mobman-train ship: error: {exc}", file=sys.stderr)
            return 2
        print(f"shipped {args.run_dir} as sb3:{args.name} in {folder}")
        return 0
    if getattr(args, "command", None) == "families":
        from train import families

        try:
            return families.main(args.bench_dirs, args.family, args.out)
        except (ValueError, OSError) as exc:
            print(f"mobman-train families: error: {exc}", file=sys.stderr)
            return 2
    if getattr(args, "command", None) == "report":
        if argv[:1] != ["report"]:
            parser.error("report takes no training options: mobman-train report RUN_DIR... [report options]")
        return report_cli.run(args)
    try:
        require_rl()
    except ValueError as exc:
        print(f"mobman-train: error: {exc}", file=sys.stderr)
        return 2
    from train.run import TrainingInterrupted, resume, run

    try:
        folder = build(Resume, args, RESUME).resume
        if folder:
            extra = [flags(OPTIONS)[f] for f in given(args, OPTIONS) if f not in RESUME_OPTIONS]
            if extra:
                raise ValueError(
                    f"--resume takes its settings from the run's config.json; only --timesteps and --quiet may be "
                    f"given with it, not {', '.join(extra)}"
                )
            summary = resume(folder, timesteps=getattr(args, "timesteps", None), progress_bar=_progress(args))
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

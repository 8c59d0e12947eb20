"""`mobman-eval run`: benchmark policies on identical episodes (parses into `EvalConfig`, calls `eval.runner.run`)."""

from __future__ import annotations

import sys

from eval.cli.common import EXECUTION, add_execution, policy_option
from eval.cli.options import Opt, add_options, build
from eval.config import DYNAMICS_CHOICES, SAVE_ARRAYS_CHOICES, STDOUT_FORMATS, EvalConfig
from eval.runner import run

#: what is run: envs, policies, seeds, conditions (`EvalConfig`'s fields)
EPISODES = (
    Opt("envs", flag="--env", metavar="ID"),
    policy_option(),
    Opt("episodes", flag="--seeds", metavar="N", old=("--episodes",)),
    Opt("seed", metavar="S"),
    Opt("dynamics", choices=DYNAMICS_CHOICES, metavar="MODE"),
    Opt("model_error", metavar="X"),
    Opt("obs_noise", metavar="M"),
    Opt("env_kwargs", metavar="JSON"),
    Opt("tolerance", metavar="M"),
    Opt("settle_time", metavar="S"),
)
#: what is written and shown
OUTPUT = (
    Opt("out", metavar="DIR"),
    "overwrite",
    "resume",
    "rerun_changed",
    "video",
    Opt("plots", flag="--no-plots"),
    Opt("save_arrays", choices=SAVE_ARRAYS_CHOICES),
    Opt("stdout_format", flag="--format", choices=STDOUT_FORMATS),
    Opt("progress", flag="--quiet"),
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "run",
        help="benchmark policies on identical episodes",
        description="Run every policy on the same episodes (episode k of every env/dynamics/policy uses "
        "seed S + k) and write results.json, results.csv, summary.md, plots and config.json.",
    )
    add_options(p, EvalConfig, EPISODES)
    add_execution(p)
    add_options(p.add_argument_group("output"), EvalConfig, OUTPUT)


def main(args) -> int:
    result = run(build(EvalConfig, args, EPISODES + EXECUTION + OUTPUT))
    n_failed = sum(r["status"] != "ok" for r in result.episodes)
    if n_failed:
        print(f"warning: {n_failed} episode(s) failed; tracebacks in {result.out / 'results.json'}", file=sys.stderr)
    return 0

"""`mobman-eval sweep --config sweep.yaml`: a resumable grid (parses the options, calls `eval.sweep.run.run_sweep`)."""

from __future__ import annotations

import sys
from dataclasses import asdict, dataclass
from pathlib import Path

from eval.cli.common import EXECUTION, RESUMABLE, add_execution
from eval.cli.options import Opt, add_options, build, values
from eval.config import EvalConfig
from eval.errors import EvalError
from eval.output.journal import JOURNAL
from eval.sweep import __doc__ as sweep_doc
from eval.sweep.config import SweepRun, example_path, load_sweep
from eval.sweep.report import print_summary
from eval.sweep.run import default_out, run_sweep


@dataclass(frozen=True)
class SweepCommand:
    """What `mobman-eval sweep` does besides running: which file, or print the example."""

    config: str | None = None
    """The sweep file (YAML: the grid, `eval.sweep.config.SweepConfig`); `--example` prints one to start from."""
    example: bool = False
    """Print the example sweep file and exit."""


COMMAND = (Opt("config", metavar="YAML"), "example")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sweep",
        help="run a grid of policies x envs x seeds x model errors x noise levels from a YAML file (resumable)",
        description=sweep_doc.split("\n\n")[0] + " Run the same command again to resume.",
    )
    add_options(p, SweepCommand, COMMAND)
    add_options(p, SweepRun, RESUMABLE)
    add_execution(p)


def main(args) -> int:
    command = build(SweepCommand, args, COMMAND)
    if command.example:
        sys.stdout.write(example_path().read_text())
        return 0
    if not command.config:
        raise EvalError("--config YAML is required (`mobman-eval sweep --example > sweep.yaml` writes an example)")
    sweep = load_sweep(command.config)
    how = build(SweepRun, args, RESUMABLE)
    try:
        result = run_sweep(sweep, **asdict(how), source=command.config, **values(args, EvalConfig, EXECUTION))
    except KeyboardInterrupt:
        out = Path(how.out) if how.out else default_out(command.config)
        print(
            f"\nsweep interrupted; the episodes that ended are in {out / JOURNAL} and the table; run the same "
            f"command again to go on",
            file=sys.stderr,
        )
        return 130
    if how.progress:
        print_summary(result)
        n_failed = sum(r["status"] != "ok" for r in result.episodes)
        n_grid = result.results["config"]["n_episodes"]
        print(
            f"{len(result.episodes)} of {n_grid} episodes in {result.out / 'results.csv'} "
            f"({result.n_run} run now, {result.n_skipped} from earlier runs, {n_failed} failed)"
        )
        if result.n_left:
            print(f"{result.n_left} episodes left: run the same command again to go on")
    return 0

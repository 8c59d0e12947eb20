"""`mobman-eval plots DIR...`: draw the plots of results folders again from the results they hold, running no
episode (`eval.redraw`: a bench's from its scorecard, a run's and the paper's from results.json and
episodes.npz); prints a line per folder."""

from __future__ import annotations

from dataclasses import dataclass

from eval.cli.options import Opt, add_options, build
from eval.redraw import redraw


@dataclass(frozen=True)
class PlotsCommand:
    """The folders `mobman-eval plots` draws again."""

    folders: tuple[str, ...]
    """Output folders of `mobman-eval bench`, `run` or `paper` (e.g. docs/results/bench-v3-dev)."""


OPTIONS = (Opt("folders", positional=True, metavar="DIR"),)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "plots",
        help="draw the plots of results folders again from their results files, running no episode",
        description=(__doc__ or "").split("\n\n")[0],
    )
    add_options(p, PlotsCommand, OPTIONS)


def main(args) -> int:
    command = build(PlotsCommand, args, OPTIONS)
    for folder in command.folders:
        written = redraw(folder)
        print(f"{folder}: {len(written)} plot(s) drawn again: {', '.join(str(p.relative_to(folder)) for p in written)}")
    return 0

"""`mobman-eval readme FILE...`: regenerate the generated blocks of Markdown files (the README, docs pages) from
the committed results they name: bench blocks from scorecards (`eval.bench.scorecard`), generated blocks from
Markdown files mobman wrote (`eval.output.readme`), layout blocks from the source tree (`eval.output.layout`)."""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass
from pathlib import Path

from eval.bench.scorecard import render_readme as render_bench
from eval.cli.options import Opt, add_options, build
from eval.errors import EvalError
from eval.output.files import atomic_rewrite_text
from eval.output.layout import render_layout
from eval.output.readme import read_text, render_generated

#: a line that begins a bench block (a search anchored at line starts: linear in the page)
BENCH_BEGIN = re.compile(r"^<!-- bench:begin ", re.M)


@dataclass(frozen=True)
class ReadmeCommand:
    """The files `mobman-eval readme` regenerates, or checks."""

    files: tuple[str, ...]
    """Markdown files holding generated blocks."""
    check: bool = False
    """Write nothing; exit 1 if a file is not up to date."""


OPTIONS = (Opt("files", positional=True, metavar="FILE"), "check")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "readme",
        help="regenerate the README's (or a docs page's) result blocks from the committed results they name",
        description=(__doc__ or "").split("\n\n")[0],
    )
    add_options(p, ReadmeCommand, OPTIONS)


def render(text: str, root: Path) -> tuple[str, list[str]]:
    """`text` with every bench, generated and layout block regenerated, and what they were made from (results
    files, package folders)."""
    used: list[str] = []
    if BENCH_BEGIN.search(text):
        text, bench = render_bench(text, root)
        used += bench
    text, generated = render_generated(text, root)
    used += generated
    text, packages = render_layout(text, root)
    used += packages
    if not used:
        raise EvalError("no generated block found (see eval.output.readme for the block syntax)")
    return text, used


def main(args) -> int:
    command = build(ReadmeCommand, args, OPTIONS)
    stale = []
    for name in command.files:
        path = Path(name)
        if not path.exists():
            raise EvalError(f"{name}: no such file")
        text = read_text(path, "page")
        new, used = render(text, path.resolve().parent)
        state = "up to date" if new == text else ("stale" if command.check else "updated")
        if new != text:
            stale.append(name)
            if not command.check:
                atomic_rewrite_text(path, new)
        print(f"{name}: {state} ({len(used)} source(s): {', '.join(used)})")
    if command.check and stale:
        print(f"not up to date: {', '.join(stale)}; run `mobman-eval readme {' '.join(stale)}`", file=sys.stderr)
        return 1
    return 0

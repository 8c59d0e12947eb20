"""`mobman-eval readme FILE...`: regenerate the generated blocks of Markdown files (the README, docs pages) from
the committed results they name: bench blocks from scorecards (`eval.bench.scorecard`), generated blocks from
Markdown files mobman wrote (`eval.output.readme`)."""

from __future__ import annotations

import sys
from pathlib import Path

from eval.bench.scorecard import README_BLOCK as BENCH_BLOCK
from eval.bench.scorecard import render_readme as render_bench
from eval.cli.common import HelpFormatter
from eval.errors import EvalError
from eval.output.files import atomic_write_text
from eval.output.readme import render_generated


def add_parser(sub) -> None:
    p = sub.add_parser(
        "readme",
        help="regenerate the README's (or a docs page's) result blocks from the committed results they name",
        description=__doc__.split("\n\n")[0],
        formatter_class=HelpFormatter,
    )
    p.add_argument("files", nargs="+", metavar="FILE", help="Markdown files holding generated blocks")
    p.add_argument("--check", action="store_true", help="write nothing; exit 1 if a file is not up to date")


def render(text: str, root: Path) -> tuple[str, list[str]]:
    """`text` with every bench block and generated block regenerated, and the results files used."""
    used: list[str] = []
    if BENCH_BLOCK.search(text):
        text, bench = render_bench(text, root)
        used += bench
    text, generated = render_generated(text, root)
    used += generated
    if not used:
        raise EvalError("no generated block found (see eval.output.readme for the block syntax)")
    return text, used


def main(args) -> int:
    stale = []
    for name in args.files:
        path = Path(name)
        if not path.is_file():
            raise EvalError(f"{name}: no such file")
        text = path.read_text(encoding="utf-8")
        new, used = render(text, path.resolve().parent)
        state = "up to date" if new == text else ("stale" if args.check else "updated")
        if new != text:
            stale.append(name)
            if not args.check:
                atomic_write_text(path, new)
        print(f"{name}: {state} ({len(used)} results file(s): {', '.join(used)})")
    if args.check and stale:
        print(f"not up to date: {', '.join(stale)}; run `mobman-eval readme {' '.join(stale)}`", file=sys.stderr)
        return 1
    return 0

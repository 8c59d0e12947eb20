"""`mobman-eval sweep --config sweep.yaml`: a resumable grid (parses the options, calls `eval.sweep.run.run_sweep`)."""

from __future__ import annotations

import sys
from pathlib import Path

from eval.cli.common import HelpFormatter, add_backend_arguments
from eval.config import BACKEND_CHOICES
from eval.errors import EvalError
from eval.sweep import __doc__ as sweep_doc
from eval.sweep.config import example_path, load_sweep
from eval.sweep.journal import JOURNAL
from eval.sweep.report import print_summary
from eval.sweep.run import default_out, run_sweep


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sweep",
        help="run a grid of policies x envs x seeds x model errors x noise levels from a YAML file (resumable)",
        description=sweep_doc.split("\n\n")[0] + " Run the same command again to resume.",
        formatter_class=HelpFormatter,
    )
    p.add_argument("--config", metavar="YAML", help="the sweep file (`--example` prints one to start from)")
    p.add_argument(
        "--out",
        default=None,
        help="output directory (default: runs/sweep-<config file stem>); an existing sweep there is resumed",
    )
    add_backend_arguments(p)
    p.add_argument(
        "--max-episodes",
        type=int,
        default=None,
        metavar="N",
        help="run at most N episodes not yet done, then write the table and stop (run again to go on)",
    )
    p.add_argument("--retry-failed", action="store_true", help="run again the episodes recorded as failed")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no table")
    p.add_argument("--example", action="store_true", help="print the example sweep file and exit")


def main(args) -> int:
    if args.example:
        sys.stdout.write(example_path().read_text())
        return 0
    if not args.config:
        raise EvalError("--config YAML is required (`mobman-eval sweep --example > sweep.yaml` writes an example)")
    if args.backend not in BACKEND_CHOICES:  # pragma: no cover - argparse checks it
        raise EvalError(f"unknown backend {args.backend!r}")
    sweep = load_sweep(args.config)
    try:
        result = run_sweep(
            sweep,
            args.out,
            backend=args.backend,
            address=args.address,
            workers=args.workers,
            batch_size=args.batch_size,
            max_episodes=args.max_episodes,
            retry_failed=args.retry_failed,
            plots=not args.no_plots,
            progress=not args.quiet,
            source=args.config,
        )
    except KeyboardInterrupt:
        out = Path(args.out) if args.out else default_out(args.config)
        print(
            f"\nsweep interrupted; the episodes that ended are in {out / JOURNAL} and the table; run the same "
            f"command again to go on",
            file=sys.stderr,
        )
        return 130
    if not args.quiet:
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

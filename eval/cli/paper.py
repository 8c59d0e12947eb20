"""`mobman-eval paper`: the paper's section IV in one command (calls `eval.paper.reproduce`)."""

from __future__ import annotations

from eval import paper
from eval.cli.common import HelpFormatter, add_batch_size_argument, param_default


def add_parser(sub) -> None:
    p = sub.add_parser(
        "paper",
        help="reproduce the paper's section IV (NNBC vs JMPI on the circle) and write paper.md",
        description=paper.__doc__.split("\n\n")[0],
        formatter_class=HelpFormatter,
    )
    p.add_argument("--out", default=None, help="output directory (default: runs/paper-<UTC timestamp>)")
    p.add_argument(
        "--seeds",
        type=int,
        default=param_default(paper.reproduce, "seeds"),
        help=f"reported seeds ({paper.PAPER_SEED}, {paper.PAPER_SEED + 1}, ...)",
    )
    p.add_argument(
        "--dynamics",
        choices=tuple(paper.DYNAMICS_ARG),
        default=param_default(paper.reproduce, "dynamics"),
        help="dynamics mode(s)",
    )
    p.add_argument("--workers", type=int, default=param_default(paper.reproduce, "workers"), help="worker processes")
    add_batch_size_argument(p)
    p.add_argument("--overwrite", action="store_true", help="write into an existing non-empty --out")
    p.add_argument("--video", action="store_true", help="also write videos of seed 10000 (slow)")
    p.add_argument("--quiet", action="store_true", help="no progress bar and no table")


def main(args) -> int:
    out = paper.reproduce(
        out=args.out,
        seeds=args.seeds,
        dynamics=args.dynamics,
        workers=args.workers,
        batch_size=args.batch_size,
        overwrite=args.overwrite,
        video=args.video,
        progress=not args.quiet,
    )
    if not args.quiet:
        print(f"paper reproduction: {out / 'paper.md'}")
    return 0

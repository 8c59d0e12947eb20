"""`mobman-eval paper`: the paper's section IV in one command (parses into `PaperConfig`, calls
`eval.paper.reproduce`)."""

from __future__ import annotations

from eval import paper
from eval.cli.options import Opt, add_options, build, commas, deprecated
from eval.paper import PAPER_DYNAMICS, PaperConfig


def dynamics_list(text: str) -> list[str]:
    """`--dynamics kinematic,physics`; the old value `both` (release 0.1) is both modes, with a deprecation
    message."""
    if text.strip() == "both":
        deprecated("mobman-eval paper", "--dynamics both is now --dynamics kinematic,physics (the default)")
        return list(PAPER_DYNAMICS)
    return commas(text)


OPTIONS = (
    Opt("out", metavar="DIR"),
    "overwrite",
    Opt("seeds", metavar="N"),
    Opt("dynamics", choices=PAPER_DYNAMICS, split=dynamics_list),
    Opt("workers", metavar="N"),
    Opt("batch_size", metavar="N"),
    "video",
    Opt("progress", flag="--quiet"),
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "paper",
        help="reproduce the paper's section IV (NNBC vs JMPI on the circle) and write paper.md",
        description=(paper.__doc__ or "").split("\n\n")[0],
    )
    add_options(p, PaperConfig, OPTIONS)


def main(args) -> int:
    config = build(PaperConfig, args, OPTIONS)
    out = paper.reproduce(config)
    if config.progress:
        print(f"paper reproduction: {out / 'paper.md'}")
    return 0

"""`mobman-eval speed`: the speed benchmark (parses into `SpeedConfig`, calls `eval.speed.measure`, writes
speed.json and speed.md)."""

from __future__ import annotations

import sys

from eval import speed
from eval.cli.common import policy_option
from eval.cli.options import Opt, add_options, build
from eval.output.files import atomic_write_json, check_out, make_out, resolve_out
from eval.speed import SpeedConfig

OPTIONS = (
    Opt("steps", metavar="N"),
    Opt("repeats", metavar="N"),
    Opt("episodes", metavar="N"),
    policy_option(),
    Opt("batch_size", metavar="N", old=("--batch",)),
    "peers",
    "paper",
    Opt("out", metavar="DIR"),
    "overwrite",
    Opt("progress", flag="--quiet"),
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "speed",
        help="the speed benchmark (env steps/s, predict µs, episodes/s)",
        description=(speed.__doc__ or "").split("\n\n")[0],
    )
    add_options(p, SpeedConfig, OPTIONS)


def main(args) -> int:
    config = build(SpeedConfig, args, OPTIONS)
    config.validate()
    out = resolve_out(config.out, "speed")
    check_out(out, config.overwrite)
    speed.check_policies(list(config.policies) if config.policies else None)
    out = make_out(out, exclusive=not config.out)
    say = (lambda msg: print(msg, file=sys.stderr)) if config.progress else (lambda msg: None)
    res = speed.measure(config, progress=say)
    atomic_write_json(out / "speed.json", res)
    (out / "speed.md").write_text(speed.markdown(res), encoding="utf-8")
    if config.progress:
        speed.print_table(res)
        print(f"speed.json in {out}")
    return 0

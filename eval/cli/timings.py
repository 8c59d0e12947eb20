"""`mobman-eval timings`: time the README's steps (parses into `TimingsConfig`, calls `eval.timings.measure`, writes
timings.json and timings.md)."""

from __future__ import annotations

import sys

from eval import timings
from eval.cli.options import Opt, add_options, build
from eval.output.files import atomic_write_json, atomic_write_text, check_out, make_out, resolve_out
from eval.output.provenance import provenance
from eval.timings import TimingsConfig

OPTIONS = (
    Opt("steps", metavar="STEP", choices=tuple(timings.STEPS)),
    Opt("out", metavar="DIR"),
    "overwrite",
    Opt("progress", flag="--quiet"),
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "timings",
        help="time the README's steps: first compile, the main job, the tests (wall and CPU, with the load)",
        description=(timings.__doc__ or "").split("\n\n")[0],
    )
    add_options(p, TimingsConfig, OPTIONS)


def main(args) -> int:
    config = build(TimingsConfig, args, OPTIONS)
    config.validate()
    out = resolve_out(config.out, "timings")
    check_out(out, config.overwrite)
    if "tests" in config.steps:
        timings.repository_root()  # refused before any step runs
    out = make_out(out, exclusive=not config.out)
    say = (lambda msg: print(msg, file=sys.stderr)) if config.progress else (lambda msg: None)
    result = timings.measure(config.steps, progress=say)
    result["provenance"] = provenance()
    atomic_write_json(out / "timings.json", result)
    atomic_write_text(out / "timings.md", timings.markdown(result))
    if config.progress:
        print(f"timings.json and timings.md in {out}")
    return 0 if all(s["returncode"] == 0 for s in result["steps"]) else 1

"""`mobman-eval speed`: the speed benchmark (calls `eval.speed.measure`, writes speed.json)."""

from __future__ import annotations

import argparse
import sys

from eval import speed
from eval.cli.common import TRUST_NOTE, HelpFormatter, param_default
from eval.errors import EvalError
from eval.output.files import atomic_write_json, check_out, make_out, resolve_out
from mobman_env.validation import integer


def add_arguments(p: argparse.ArgumentParser) -> None:
    d = lambda name: param_default(speed.measure, name)
    p.add_argument("--steps", type=int, default=d("steps"), help="control steps per timed block")
    p.add_argument("--repeats", type=int, default=d("repeats"), help="repeats per timed block (the best is reported)")
    p.add_argument("--episodes", type=int, default=d("episodes"), help="20 s episodes per workers setting")
    p.add_argument(
        "--policy",
        action="append",
        dest="policies",
        metavar="SPEC",
        help=f"policies whose predict is timed (default: every built-in name); each is built first, an unknown "
        f"one stops the benchmark before it starts. {TRUST_NOTE}",
    )
    p.add_argument("--batch", type=int, default=d("batch"), help="episodes of the batched-eval block (one vector env)")
    p.add_argument(
        "--peers",
        action="store_true",
        help="also race the installed peers (panda-gym PandaReach-v3, MuJoCo Reacher-v5; pip install 'mobman[bench]')",
    )
    p.add_argument(
        "--paper",
        action="store_true",
        help="also time the kinematic half of `mobman-eval paper` with 1 worker (about 20 s)",
    )
    p.add_argument("--out", default=None, help="output directory (default: runs/speed-<UTC timestamp>)")
    p.add_argument("--overwrite", action="store_true", help="write into an existing non-empty --out")
    p.add_argument("--quiet", action="store_true", help="no table")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "speed",
        help="the speed benchmark (env steps/s, predict µs, episodes/s)",
        description=speed.__doc__.split("\n\n")[0],
        formatter_class=HelpFormatter,
    )
    add_arguments(p)


def main(args) -> int:
    for name in ("steps", "repeats", "episodes", "batch"):
        integer(f"--{name}", getattr(args, name), low=1, error=EvalError)
    out = resolve_out(args.out, "speed")
    check_out(out, args.overwrite)
    speed.check_policies(args.policies)
    out = make_out(out, exclusive=not args.out)
    say = (lambda *a: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    res = speed.measure(
        args.steps,
        args.repeats,
        args.episodes,
        args.policies,
        progress=say,
        batch=args.batch,
        peers=args.peers,
        paper=args.paper,
    )
    atomic_write_json(out / "speed.json", res)
    (out / "speed.md").write_text(speed.markdown(res), encoding="utf-8")
    if not args.quiet:
        speed.print_table(res)
        print(f"speed.json in {out}")
    return 0

"""`mobman-eval`: benchmark policies side by side (`run`), sweep a grid (`sweep`), run the benchmark protocol
(`bench`), reproduce the paper (`paper`), measure speed (`speed`), render the README's picture (`picture`), time
the README's steps (`timings`).

```
mobman-eval run --env WheeledPuma-Circle-v0 --policy nnbc,jmpi --seeds 20 --dynamics kinematic
mobman-eval run ... --backend ray --address auto    # the same episodes as Ray tasks on a cluster
mobman-eval sweep --config sweep.yaml --workers 2   # a resumable grid (`--example` prints one)
mobman-eval bench --workers 2    # the benchmark protocol v2: one scorecard (resumable)
mobman-eval paper                # the paper's section IV, both dynamics modes, 20 reported seeds
mobman-eval speed                # env steps/s, predict microseconds, episodes/s
mobman-eval picture              # docs/assets/robot.png: nnbc-plus tracking the Line, physics mode
mobman-eval timings              # how long the README's steps take here (wall and CPU, with the load)
mobman-eval compact scorecard.json  # store a large result as scorecard.json.xz (every reader takes it)
mobman-eval plots docs/results/bench-v3-dev  # draw a folder's plots again from its results, no episode run
```

One module per subcommand (`run`, `sweep`, `bench`, `paper`, `speed`, `picture`, `readme`, `timings`, `compact`,
`plots`) builds its parser from the fields of the library's frozen config dataclasses (`eval.cli.options`: one
option per field, its help the field's docstring, its default the field's default) and calls one function; `main(argv=None)`, so tests call it
in-process. The same concept has the same option everywhere: `--policy SPEC` (repeatable, comma lists; one spec
in `picture`, which renders one episode), `--env ID`, `--dynamics MODE`, `--seed S` (the first seed), `--seeds N`
(how many), `--out DIR`, `--workers N`, `--env-kwargs JSON`; earlier spellings (`--episodes`, `--policies`,
`--seed-start`, `--batch`) still work for one release and say so on stderr. Bad input (unknown env id or policy,
missing model file, existing non-empty --out, malformed --env-kwargs) stops before any rollout with exit code 2
and a message naming the bad value and what is accepted.
"""

from __future__ import annotations

import argparse
import sys

from eval.errors import EvalError, RunInterrupted
from mobman_env import __version__
from mobman_env.packages import shadowing_message

#: the subcommands, each a module of this package with add_parser(sub) and main(args)
SUBCOMMANDS = ("run", "sweep", "bench", "paper", "speed", "picture", "readme", "timings", "compact", "plots")


def _subcommands() -> dict:
    """The subcommand modules, imported only after the shadowing check (they import policies)."""
    from eval.cli import bench, compact, paper, picture, plots, readme, run, speed, sweep, timings

    modules = (run, sweep, bench, paper, speed, picture, readme, timings, compact, plots)
    return dict(zip(SUBCOMMANDS, modules, strict=True))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mobman-eval", description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="{" + ",".join(SUBCOMMANDS) + "}")
    sub.required = True
    for module in _subcommands().values():
        module.add_parser(sub)
    return parser


def resume_command(argv: list[str], resume: tuple[str, ...]) -> str:
    """The command line that continues `mobman-eval ARGV`: `argv` without `--overwrite` (it would start over)
    and without earlier values of the options in `resume` (e.g. `--out X`), followed by `resume`, quoted for a
    POSIX shell."""
    import shlex

    valued = {tok for tok, nxt in zip(resume, (*resume[1:], "--")) if tok.startswith("--") and not nxt.startswith("--")}
    drop = {tok for tok in resume if tok.startswith("--")} | {"--overwrite"}
    kept: list[str] = []
    skip = False
    for tok in argv:
        if skip:
            skip = False
            continue
        name = tok.split("=", 1)[0]
        if name in drop:
            skip = tok in valued  # `--out X`: drop X too (`--out=X` is one token)
            continue
        kept.append(tok)
    return shlex.join(["mobman-eval", *kept, *resume])


def main(argv: list[str] | None = None) -> int:
    """Parse `argv` and run the subcommand. Exit codes: 0 done, 2 bad input (before any rollout), 130
    interrupted by Ctrl-C or SIGTERM (what finished is written)."""
    message = shadowing_message(("mobman_env", "policies", "eval"))
    if message is not None:  # before anything imports the hidden package
        print(f"mobman-eval: error: {message}", file=sys.stderr)
        return 2
    from eval.cli.common import reserve_stdout
    from eval.output.files import sigterm_interrupts

    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = sys.argv[1:] if argv is None else list(argv)  # the command line, for the records that keep it
    if argv is None and getattr(args, "stdout_format", "table") != "table" and getattr(args, "progress", True):
        reserve_stdout()  # a command line piping data: native output (PyBullet, Ray) goes to stderr
    try:
        with sigterm_interrupts():  # SIGTERM (timeout, Slurm, docker stop) stops a command as Ctrl-C does
            return _subcommands()[args.command].main(args)
    except EvalError as exc:
        print(f"mobman-eval {args.command}: error: {exc}", file=sys.stderr)
        if exc.resume:
            line = resume_command(args.argv, exc.resume)
            print(f"mobman-eval {args.command}: the command that resumes: {line}", file=sys.stderr)
        return 2
    except RunInterrupted as exc:
        print(f"\nmobman-eval {args.command}: {exc}", file=sys.stderr)
        return 130
    except KeyboardInterrupt:
        print(f"\nmobman-eval {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

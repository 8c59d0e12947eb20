"""`mobman-eval bench`: the benchmark protocol v2 (parses the options, calls `eval.bench.run.run_bench`).

```
mobman-eval bench --workers 2                       # the dev track: every condition, robot, task and controller
mobman-eval bench --track heldout --out runs/heldout   # the held-out track (report it as it comes)
mobman-eval bench --seeds 5 --policy nnbc-plus,jmpi --conditions default,wear20 --out runs/quick
mobman-eval bench --list                            # the conditions, tasks and default controllers
mobman-eval bench --markdown runs/bench/scorecard.json   # the README block of a scorecard
mobman-eval bench --render-readme README.md         # regenerate the README's bench blocks in place
```
"""

from __future__ import annotations

import shlex
import sys
from dataclasses import asdict, dataclass
from pathlib import Path

from eval.bench.against import committed_settings
from eval.bench.config import CONDITIONS, DEFAULT_CONDITIONS, ROBOTS, TASKS, TRACKS, BenchConfig, default_policies
from eval.bench.run import DEFAULT_OUT, run_bench
from eval.bench.scorecard import load_scorecard, readme_markdown, render_readme
from eval.cli.common import EXECUTION, RESUMABLE, add_execution, policy_help, policy_option
from eval.cli.options import Opt, add_options, build, given, values
from eval.config import EvalConfig
from eval.errors import EvalError
from eval.output.files import atomic_rewrite_text
from eval.output.readme import read_text
from eval.sweep.config import SweepRun


@dataclass(frozen=True)
class BenchActions:
    """What `mobman-eval bench` does instead of (or besides) running the protocol."""

    list_conditions: bool = False
    """Print the conditions, tasks and default controllers and exit."""
    markdown: str | None = None
    """A scorecard.json: print its README block and exit."""
    render_readme: str | None = None
    """A Markdown file: regenerate every <!-- bench:begin PATH --> block of it from its scorecard, in place, and
    exit."""
    against: str | None = None
    """A committed bench (e.g. docs/results/bench-v2-dev): re-run a sample of its baselines bit for bit, reuse
    their rows, and run only the controllers given with --policy (yours), on the committed protocol (its track,
    seeds, first seed, tolerance, settle time and env arguments unless given)."""


#: what is run (`BenchConfig`'s fields)
PROTOCOL = (
    Opt("track", choices=TRACKS),
    Opt("robots", metavar="NAME", more=lambda: f"Accepted: {', '.join(ROBOTS)}, or all."),
    Opt("tasks", metavar="NAME", more=lambda: f"Accepted: {', '.join(TASKS)}."),
    Opt(
        "conditions",
        metavar="NAME",
        more=lambda: (
            f"Accepted: {', '.join(CONDITIONS)} (--list shows them; the dev track's default: "
            f"{', '.join(DEFAULT_CONDITIONS['dev'])})."
        ),
    ),
    policy_option(old=("--policies",), more=lambda: "--list shows the built-in controllers. " + policy_help()),
    Opt("seeds", metavar="N"),
    Opt("physics_seeds", metavar="N"),
    Opt("seed_start", flag="--seed", metavar="S", old=("--seed-start",)),
    Opt("tolerance", metavar="M"),
    Opt("settle_time", metavar="S"),
    Opt("env_kwargs", metavar="JSON"),
)
ACTIONS = (
    Opt("against", metavar="DIR"),
    Opt("list_conditions", flag="--list"),
    Opt("markdown", metavar="SCORECARD"),
    Opt("render_readme", metavar="README"),
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "bench",
        help="the benchmark protocol v2: conditions x robots x tasks x every controller x seeds, one scorecard "
        "(resumable)",
        description=(
            "Run the benchmark protocol v2 (eval.bench): for every condition of the track, its robots x tasks x "
            "built-in controllers x seeds, as one resumable sweep per condition, and write scorecard.md, "
            "scorecard.json and plots. Run the same command again to resume."
        ),
    )
    add_options(p, BenchConfig, PROTOCOL)
    add_options(p, SweepRun, RESUMABLE)
    add_execution(p)
    add_options(p.add_argument_group("instead of running"), BenchActions, ACTIONS)


def main(args) -> int:
    actions = build(BenchActions, args, ACTIONS)
    if actions.markdown:
        sys.stdout.write(readme_markdown(load_scorecard(actions.markdown)))
        return 0
    if actions.render_readme:
        path = Path(actions.render_readme)
        if not path.exists():
            raise EvalError(f"cannot read {str(path)!r}: no such file")
        text = read_text(path, "page")  # a regular UTF-8 file of at most MAX_PAGE_BYTES
        new, used = render_readme(text, path.parent)
        if new != text:
            atomic_rewrite_text(path, new)
        print(
            f"{path}: {len(used)} bench block(s) {'updated' if new != text else 'already up to date'} ({', '.join(used)})"
        )
        return 0
    if actions.list_conditions:
        for name, c in CONDITIONS.items():
            mark = "*" if name in DEFAULT_CONDITIONS.get(c.track, ()) else " "
            extra = ", ".join(f"{k}={v}" for k, v in c.extra_kwargs.items())
            print(
                f"{mark} {c.track:8s} {name:17s} {c.dynamics:9s} model_error={c.model_error:g} obs_noise={c.obs_noise:g} "
                f"robots={','.join(c.robots)} {extra}  {c.description}"
            )
        print("(* = in the track's default set)")
        print(f"tasks: {', '.join(TASKS)}; robots: {', '.join(ROBOTS)}")
        print(f"default controllers: {', '.join(default_policies())}")
        return 0
    fixed = committed_settings(actions.against, given(args, PROTOCOL)) if actions.against else {}
    config = build(BenchConfig, args, PROTOCOL, **fixed)
    how = build(SweepRun, args, RESUMABLE)
    try:
        result = run_bench(
            config,
            **asdict(how),
            against=actions.against,
            command_line=shlex.join(["mobman-eval", *getattr(args, "argv", [])]),
            **values(args, EvalConfig, EXECUTION),
        )
    except KeyboardInterrupt:
        print(
            f"\nbench interrupted; finished episodes are in {how.out or DEFAULT_OUT}/episodes.jsonl; run the same "
            f"command again to go on",
            file=sys.stderr,
        )
        return 130
    if how.progress:
        from eval.bench.scorecard import headline_tables

        print("\n".join(headline_tables(result.scorecard)))
        sc = result.scorecard
        print(
            f"{sc['n_episodes']} of {sc['n_expected']} episodes ({result.n_run} run now, {result.n_skipped} from "
            f"earlier runs, {sc['n_failed']} failed); scorecard in {result.out / 'scorecard.md'}"
        )
        if result.n_left:
            print(f"{result.n_left} episodes left: run the same command again to go on")
    return 0

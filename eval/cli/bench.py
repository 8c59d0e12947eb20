"""`mobman-eval bench`: the benchmark protocol v1 (parses the options, calls `eval.bench.run.run_bench`).

```
mobman-eval bench --workers 2                       # every task, condition and built-in controller, 20 seeds
mobman-eval bench --seeds 5 --policies nnbc-plus,jmpi --conditions default,wear20 --out runs/quick
mobman-eval bench --list                            # the conditions, tasks and default controllers
mobman-eval bench --markdown runs/bench/scorecard.json   # the README block of a scorecard
mobman-eval bench --render-readme README.md         # regenerate the README's bench blocks in place
```
"""

from __future__ import annotations

import sys
from pathlib import Path

from eval.bench.config import (
    CONDITIONS,
    DEFAULT_CONDITIONS,
    DEFAULT_SEEDS,
    REPORTED_SEED_START,
    ROBOTS,
    TASKS,
    BenchConfig,
    default_policies,
)
from eval.bench.run import DEFAULT_OUT, run_bench
from eval.bench.scorecard import load_scorecard, readme_markdown, render_readme
from eval.cli.common import HelpFormatter, add_backend_arguments, default, env_kwargs_arg
from eval.errors import EvalError


def _list(text: str) -> list[str]:
    return [v.strip() for v in text.split(",") if v.strip()]


def policy_list(text: str) -> list[str]:
    """Comma-separated policy specs; a piece `key=value` without a name continues the spec before it, so
    `nnbc:gamma=20,mu=20,jmpi` is two specs: `nnbc:gamma=20,mu=20` and `jmpi`."""
    specs: list[str] = []
    for piece in _list(text):
        if specs and "=" in piece and ":" not in piece and ":" in specs[-1]:
            specs[-1] += "," + piece
        else:
            specs.append(piece)
    return specs


def add_parser(sub) -> None:
    p = sub.add_parser(
        "bench",
        help="the benchmark protocol v1: tasks x conditions x every controller x seeds, one scorecard (resumable)",
        description=(
            "Run the benchmark protocol v1 (eval.bench): every task x condition x built-in controller x seed, "
            "as one resumable sweep per condition, and write scorecard.md, scorecard.json and plots. Run the "
            "same command again to resume."
        ),
        formatter_class=HelpFormatter,
    )
    p.add_argument(
        "--robots",
        type=_list,
        action="extend",
        metavar="A,B",
        help=f"robots ({', '.join(ROBOTS)}, or all); default: puma",
    )
    p.add_argument(
        "--tasks", type=_list, action="extend", metavar="A,B", help=f"tasks ({', '.join(TASKS)}); default: all"
    )
    p.add_argument(
        "--conditions",
        type=_list,
        action="extend",
        metavar="A,B",
        help=f"conditions ({', '.join(CONDITIONS)}); default: {', '.join(DEFAULT_CONDITIONS)} (those this "
        f"mobman_env can build)",
    )
    p.add_argument(
        "--policies",
        type=policy_list,
        action="extend",
        metavar="A,B",
        help="policy specs (nnbc:gamma=20,mu=20,jmpi is two); default: every built-in controller of the "
        "registry (`--list` shows them)",
    )
    p.add_argument("--seeds", type=int, default=DEFAULT_SEEDS, metavar="N", help="seeds per cell")
    p.add_argument(
        "--seed-start",
        type=int,
        default=REPORTED_SEED_START,
        metavar="S",
        help="first seed (reported results use seeds >= 10000; a development run may start at 0)",
    )
    p.add_argument(
        "--out",
        default=None,
        help=f"output directory (default: {DEFAULT_OUT}); an existing bench there is resumed",
    )
    add_backend_arguments(p)
    p.add_argument(
        "--max-episodes",
        type=int,
        default=None,
        metavar="N",
        help="run at most N new episodes, then write the scorecard",
    )
    p.add_argument("--retry-failed", action="store_true", help="run again the episodes recorded as failed")
    p.add_argument("--tolerance", type=float, default=default(BenchConfig, "tolerance"), help="success threshold, m")
    p.add_argument(
        "--settle-time", type=float, default=default(BenchConfig, "settle_time"), help="steady-state window start, s"
    )
    p.add_argument(
        "--env-kwargs",
        type=env_kwargs_arg,
        default={},
        metavar="JSON",
        help="env arguments added to every condition (e.g. a short path for a quick check)",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.add_argument("--quiet", action="store_true", help="no progress and no summary")
    p.add_argument("--list", action="store_true", help="print the conditions, tasks and default controllers and exit")
    p.add_argument("--markdown", metavar="SCORECARD", help="print the README block of a scorecard.json and exit")
    p.add_argument(
        "--render-readme",
        metavar="README",
        help="regenerate every <!-- bench:begin PATH --> block of README from its scorecard, in place, and exit",
    )


def main(args) -> int:
    if args.markdown:
        sys.stdout.write(readme_markdown(load_scorecard(args.markdown)))
        return 0
    if args.render_readme:
        path = Path(args.render_readme)
        try:
            text = path.read_text()
        except OSError as exc:
            raise EvalError(f"cannot read {str(path)!r}: {exc}") from None
        new, used = render_readme(text, path.parent)
        if new != text:
            path.write_text(new)
        print(
            f"{path}: {len(used)} bench block(s) {'updated' if new != text else 'already up to date'} ({', '.join(used)})"
        )
        return 0
    if args.list:
        for name, c in CONDITIONS.items():
            mark = "*" if name in DEFAULT_CONDITIONS else " "
            extra = ", ".join(f"{k}={v}" for k, v in c.env_kwargs.items())
            print(
                f"{mark} {name:9s} {c.dynamics:9s} model_error={c.model_error:g} obs_noise={c.obs_noise:g} {extra}  {c.description}"
            )
        print("(* = default set)")
        print(f"tasks: {', '.join(TASKS)}; robots: {', '.join(ROBOTS)}")
        print(f"default controllers: {', '.join(default_policies())}")
        return 0
    config = BenchConfig(
        robots=tuple(args.robots or ("puma",)),
        tasks=tuple(args.tasks or TASKS),
        conditions=tuple(args.conditions) if args.conditions else None,
        policies=tuple(args.policies) if args.policies else None,
        seeds=args.seeds,
        seed_start=args.seed_start,
        tolerance=args.tolerance,
        settle_time=args.settle_time,
        env_kwargs=args.env_kwargs,
    )
    try:
        result = run_bench(
            config,
            args.out,
            backend=args.backend,
            address=args.address,
            workers=args.workers,
            batch_size=args.batch_size,
            max_episodes=args.max_episodes,
            retry_failed=args.retry_failed,
            plots=not args.no_plots,
            progress=not args.quiet,
        )
    except KeyboardInterrupt:
        print(
            f"\nbench interrupted; finished episodes are in {args.out or DEFAULT_OUT}/conditions/*/; run the same "
            f"command again to go on",
            file=sys.stderr,
        )
        return 130
    if not args.quiet:
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

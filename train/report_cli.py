"""`mobman-train report RUN_DIR... --out DIR` (also `train.report_cli.main(argv)` in-process): the multi-seed
report of `train.report`. Exit codes: 0 written, 2 bad arguments or run folders."""

from __future__ import annotations

import argparse
import json
import sys

from train.report import DEFAULT_CONTROLLERS, ReportConfig


def build_parser() -> argparse.ArgumentParser:
    d = ReportConfig(runs=("x",))
    p = argparse.ArgumentParser(
        prog="mobman-train report",
        description="Evaluate several mobman-train runs (families of seeds) on the reported episodes beside the "
        "controllers and write learning curves with IQM and 95%% intervals over seeds, final tables and "
        "provenance into one results folder (see train.report).",
    )
    p.add_argument("runs", nargs="*", metavar="RUN_DIR", help="run folders of mobman-train")
    p.add_argument(
        "--include",
        action="append",
        default=[],
        metavar="REPORT_DIR",
        help="carry over the finished runs of an earlier report folder as they were measured (repeatable; see "
        "train.report_archive)",
    )
    p.add_argument("--out", default=d.out, metavar="DIR", help=f"results folder (default {d.out})")
    p.add_argument("--episodes", type=int, default=d.episodes, metavar="N", help=f"reported episodes ({d.episodes})")
    p.add_argument("--seed", type=int, default=d.seed, metavar="S", help=f"first reported seed ({d.seed})")
    p.add_argument(
        "--controllers",
        default=",".join(DEFAULT_CONTROLLERS),
        metavar="A,B",
        help=f"controller specs on the same episodes, comma-separated (default {','.join(DEFAULT_CONTROLLERS)}; "
        "'' for none)",
    )
    p.add_argument("--tolerance", type=float, default=d.tolerance, metavar="M", help="success threshold, m")
    p.add_argument(
        "--env-kwargs",
        default="{}",
        metavar="JSON",
        help="env arguments of every evaluation beyond the bench condition",
    )
    p.add_argument("--train-commit", metavar="SHA", help="git commit of the code that trained the runs (recorded)")
    p.add_argument("--workers", type=int, default=d.workers, metavar="K", help="parallel episodes per evaluation")
    p.add_argument(
        "--ship",
        action="append",
        default=[],
        metavar="ALIAS=FAMILY",
        help="copy FAMILY's median-seed model to MODELS_DIR/ALIAS with a generated README (repeatable)",
    )
    p.add_argument("--models-dir", default=d.models_dir, metavar="DIR", help=f"where --ship writes ({d.models_dir})")
    p.add_argument("--no-plots", action="store_true", help="do not draw curves.png")
    return p


def _pair(text: str) -> tuple[str, str]:
    alias, sep, family = text.partition("=")
    if not sep or not alias or not family:
        raise ValueError(f"--ship {text!r}: expected ALIAS=FAMILY, e.g. --ship ppo-circle=ppo-kinematic")
    return alias, family


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    from eval.errors import EvalError
    from train.report import build_report

    try:
        env_kwargs = json.loads(args.env_kwargs)
        if not isinstance(env_kwargs, dict):
            raise ValueError(f"--env-kwargs must be a JSON object, got {args.env_kwargs!r}")
        config = ReportConfig(
            runs=tuple(args.runs),
            out=args.out,
            episodes=args.episodes,
            seed=args.seed,
            controllers=tuple(c for c in args.controllers.split(",") if c),
            tolerance=args.tolerance,
            env_kwargs=env_kwargs,
            train_commit=args.train_commit,
            workers=args.workers,
            plots=not args.no_plots,
            ship=tuple(_pair(s) for s in args.ship),
            models_dir=args.models_dir,
            include=tuple(args.include),
        )
        results = build_report(config)
    except (ValueError, EvalError) as exc:
        print(f"mobman-train report: error: {exc}", file=sys.stderr)
        return 2
    done = sum(r["status"] == "done" for r in results["runs"])
    print(f"mobman-train report: {len(results['runs'])} runs ({done} finished) -> {config.out}/summary.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())

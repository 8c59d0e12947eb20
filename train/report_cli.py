"""`mobman-train report RUN_DIR... --out DIR` (also `train.report_cli.main(argv)` in-process): the multi-seed
report of `train.report` (parses into `ReportConfig`, calls `train.report.build_report`). Exit codes: 0 written,
2 bad arguments or run folders."""

from __future__ import annotations

import argparse
import sys

from eval.cli.common import TRUST_NOTE, policy_help, policy_option
from eval.cli.options import Opt, add_options, build
from train.report import ReportConfig

DESCRIPTION = (
    "Evaluate several mobman-train runs (families of seeds) on the reported episodes beside the controllers and "
    "write learning curves with IQM and 95%% intervals over seeds, final tables and provenance into one results "
    "folder (see train.report)."
)


def _pair(text: str) -> tuple[str, str]:
    alias, sep, family = text.partition("=")
    if not sep or not alias or not family:
        raise argparse.ArgumentTypeError(
            f"--ship {text!r}: expected ALIAS=FAMILY, e.g. --ship ppo-circle=ppo-kinematic"
        )
    return alias, family


#: the options of a report (`ReportConfig`'s fields)
OPTIONS = (
    Opt("runs", positional=True, metavar="RUN_DIR"),
    Opt("include", metavar="REPORT_DIR"),
    Opt("out", metavar="DIR"),
    Opt("episodes", flag="--seeds", metavar="N", old=("--episodes",)),
    Opt("seed", metavar="S"),
    policy_option("controllers", more=lambda: "--policy '' runs none. " + policy_help(), old=("--controllers",)),
    Opt("tolerance", metavar="M"),
    Opt("env_kwargs", metavar="JSON"),
    Opt("train_commit", metavar="SHA"),
    Opt("workers", metavar="K"),
    Opt("ship", metavar="ALIAS=FAMILY", parse=_pair),
    Opt("models_dir", metavar="DIR"),
    Opt("plots", flag="--no-plots"),
    "redraw",
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    add_options(p, ReportConfig, OPTIONS)


def add_parser(sub) -> None:
    """`report` as a subcommand of `mobman-train`."""
    p = sub.add_parser(
        "report",
        help="evaluate several training runs (families of seeds) into one results folder",
        description=DESCRIPTION,
        epilog=TRUST_NOTE,
    )
    add_arguments(p)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="mobman-train report", description=DESCRIPTION, epilog=TRUST_NOTE)
    add_arguments(p)
    return p


def run(args: argparse.Namespace) -> int:
    """Build the report the parsed command line asks for; 2 with the message on a bad argument or run folder."""
    from eval.errors import EvalError
    from train.report import build_report, redraw_curves

    try:
        config = build(ReportConfig, args, OPTIONS)
        if config.redraw:
            print(f"mobman-train report: {redraw_curves(config.out)} drawn again")
            return 0
        results = build_report(config)
    except (ValueError, EvalError) as exc:
        print(f"mobman-train report: error: {exc}", file=sys.stderr)
        return 2
    done = sum(r["status"] == "done" for r in results["runs"])
    print(f"mobman-train report: {len(results['runs'])} runs ({done} finished) -> {config.out}/summary.md")
    return 0


def main(argv: list[str] | None = None) -> int:
    return run(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())

"""What every `mobman-eval` subcommand's parser shares: the policy list in the help, the execution options (from
`EvalConfig`'s fields) and stdout reserved for piped data. The options themselves are generated from the config
dataclasses (`eval.cli.options`), so no default or help text is written twice."""

from __future__ import annotations

import argparse
import os
import sys

from eval.cli.options import Opt, add_options, policy_list
from eval.config import BACKEND_CHOICES, EvalConfig


def reserve_stdout() -> None:
    """Keep stdout for this process's results: Python's `sys.stdout` gets its own copy of file descriptor 1,
    and descriptor 1 itself is pointed at stderr, so whatever native code writes there (PyBullet's build-time
    banner, Ray) cannot end up inside piped JSON or CSV."""
    sys.stdout.flush()
    fd = os.dup(1)
    os.dup2(2, 1)
    sys.stdout = open(fd, "w", encoding=sys.stdout.encoding or "utf-8", closefd=True)  # noqa: SIM115


def policy_help() -> str:
    """Every policy spec the registry knows, with its one-line description (no list is written twice)."""
    from policies.registry import KNOWN_POLICIES, SPEC_FORMS

    known = "; ".join(f"{k}: {v}" for k, v in {**KNOWN_POLICIES, **SPEC_FORMS}.items())
    return f"{POLICY_LISTS} Known: {known}. {TRUST_NOTE}"


#: How --policy lists are read (the same in every command).
POLICY_LISTS = "A piece key=value continues the spec before it: nnbc:gamma=20,mu=20,jmpi is two specs."

#: The --help note on loading agents (model files hold pickles).
TRUST_NOTE = (
    "Load only agents you trust: sb3: model.zip and vecnormalize.pkl / vec_normalize.pkl (mobman-train, plain SB3 "
    "or rl-zoo run folders) hold pickles (mobman reads them with a "
    "restricted unpickler, which narrows but does not sandbox what a crafted file can do), and module:attr runs "
    "the module's code"
)


def policy_option(field: str = "policies", more=policy_help, old: tuple[str, ...] = ()) -> Opt:
    """`--policy SPEC`: repeatable, comma lists (`policy_list`), in every command that takes policies."""
    return Opt(field, flag="--policy", metavar="SPEC", split=policy_list, more=more, old=old)


#: Where and how many episodes run at once (run, sweep, bench): `EvalConfig`'s fields.
EXECUTION = (
    Opt("workers", metavar="N"),
    Opt("batch_size", metavar="N"),
    Opt("backend", choices=BACKEND_CHOICES),
    Opt("address", metavar="ADDRESS"),
)


#: How this run of a resumable grid goes (sweep, bench): `SweepRun`'s fields.
RESUMABLE = (
    Opt("out", metavar="DIR"),
    Opt("max_episodes", metavar="N"),
    "retry_failed",
    "rerun_changed",
    Opt("plots", flag="--no-plots"),
    Opt("progress", flag="--quiet"),
)


def add_execution(parser: argparse.ArgumentParser) -> None:
    """--workers, --batch-size, --backend, --address, documented by `EvalConfig`'s fields."""
    add_options(parser.add_argument_group("where episodes run"), EvalConfig, EXECUTION)

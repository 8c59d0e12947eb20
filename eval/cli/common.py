"""What every `mobman-eval` subcommand's parser shares: the help formatter, the policy list, --env-kwargs parsing,
the backend arguments, and defaults read from the config dataclasses (so no default is written twice)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from typing import Any

from eval.config import BACKEND_CHOICES, EvalConfig


def reserve_stdout() -> None:
    """Keep stdout for this process's results: Python's `sys.stdout` gets its own copy of file descriptor 1,
    and descriptor 1 itself is pointed at stderr, so whatever native code writes there (PyBullet's build-time
    banner, Ray) cannot end up inside piped JSON or CSV."""
    sys.stdout.flush()
    fd = os.dup(1)
    os.dup2(2, 1)
    sys.stdout = open(fd, "w", encoding=sys.stdout.encoding or "utf-8", closefd=True)  # noqa: SIM115


def working_directory_importable() -> None:
    """Put the working directory at the end of `sys.path`, so `--policy mymod:MyCtrl` imports the `mymod.py`
    of the folder the command runs in (console scripts do not put it on sys.path; `python -m eval` does). At the
    end, a file there never hides an installed package. Spawned workers inherit sys.path."""
    cwd = os.getcwd()
    if not any(os.path.realpath(p or os.curdir) == os.path.realpath(cwd) for p in sys.path):
        sys.path.append(cwd)


def default(cls: Any, name: str) -> Any:
    """The default of field `name` of the dataclass `cls` (the CLIs show and use the configs' own defaults)."""
    f = cls.__dataclass_fields__[name]
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    raise KeyError(f"{cls.__name__}.{name} has no default")


def param_default(func: Any, name: str) -> Any:
    """The default of parameter `name` of `func` (for subcommands whose library entry is a function)."""
    import inspect

    value = inspect.signature(func).parameters[name].default
    if value is inspect.Parameter.empty:
        raise KeyError(f"{func.__name__}({name}) has no default")
    return value


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows "(default: X)" only where X says something (not None/False) and the help does not already."""

    def _get_help_string(self, action):
        text = action.help or ""
        if action.default in (None, False, argparse.SUPPRESS) or "default:" in text:
            return text
        return super()._get_help_string(action)


def policy_help() -> str:
    """Every policy spec the registry knows, with its one-line description (no list is written twice)."""
    from policies.registry import KNOWN_POLICIES, SPEC_FORMS

    return "; ".join(f"{k}: {v}" for k, v in {**KNOWN_POLICIES, **SPEC_FORMS}.items()) + f". {TRUST_NOTE}"


#: The --help note on loading agents (model files hold pickles).
TRUST_NOTE = (
    "Load only agents you trust: sb3: model.zip and vecnormalize.pkl / vec_normalize.pkl (mobman-train, plain SB3 "
    "or rl-zoo run folders) hold pickles (mobman reads them with a "
    "restricted unpickler, which narrows but does not sandbox what a crafted file can do), and module:attr runs "
    "the module's code"
)


def env_kwargs_arg(text: str) -> dict:
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(
            f'--env-kwargs must be a JSON object such as \'{{"path": {{"type": "circle", "duration": 2.0}}}}\' ({exc})'
        ) from None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"--env-kwargs must be a JSON object, got {text!r}")
    return value


def add_batch_size_argument(p) -> None:
    """--batch-size (run, sweep, bench and paper)."""
    p.add_argument(
        "--batch-size",
        type=int,
        default=default(EvalConfig, "batch_size"),
        metavar="N",
        help="most kinematic episodes of one env, condition and built-in policy stepped together through one "
        "vector env (same results; 1: one episode at a time; physics, sb3: and module:attr always run singly)",
    )


def add_backend_arguments(p) -> None:
    """--workers, --batch-size, --backend and --address (run, sweep and bench)."""
    add_batch_size_argument(p)
    p.add_argument(
        "--workers",
        type=int,
        default=default(EvalConfig, "workers"),
        help="parallel episodes: worker processes (one PyBullet client each), or with --backend ray and "
        "no --address the CPUs of the local Ray instance started for the run",
    )
    p.add_argument(
        "--backend",
        choices=BACKEND_CHOICES,
        default=default(EvalConfig, "backend"),
        help='where episodes run: local processes, or one Ray task per batch or episode (pip install "mobman[ray]")',
    )
    p.add_argument(
        "--address",
        default=None,
        metavar="ADDRESS",
        help="with --backend ray: the cluster to join (auto, HOST:6379, ray://HOST:10001); default: a "
        "local Ray instance",
    )

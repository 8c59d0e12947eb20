"""What every `mobman-eval` subcommand's parser shares: the help formatter, the policy list, --env-kwargs parsing,
the backend arguments, and defaults read from the config dataclasses (so no default is written twice)."""

from __future__ import annotations

import argparse
import dataclasses
import json
from typing import Any

from eval.config import BACKEND_CHOICES, EvalConfig


def default(cls: Any, name: str) -> Any:
    """The default of field `name` of the dataclass `cls` (the CLIs show and use the configs' own defaults)."""
    f = cls.__dataclass_fields__[name]
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    raise KeyError(f"{cls.__name__}.{name} has no default")


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows "(default: X)" only where X says something (not None/False) and the help does not already."""

    def _get_help_string(self, action):
        text = action.help or ""
        if action.default in (None, False, argparse.SUPPRESS) or "default:" in text:
            return text
        return super()._get_help_string(action)


def policy_help() -> str:
    try:
        from policies.registry import KNOWN_POLICIES, SPEC_FORMS

        items = {**KNOWN_POLICIES, **SPEC_FORMS}
        return "; ".join(f"{k}: {v}" for k, v in items.items())
    except Exception:
        return "nnbc, nnbc-full, nnbc-plus, jmpi, jmpi-full, oracle, oracle-full, zero, random, sb3:PATH, module:attr"


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


def add_backend_arguments(p) -> None:
    """--workers, --backend and --address (run and sweep)."""
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
        help='where episodes run: local processes, or one Ray task per episode (pip install "mobman[ray]")',
    )
    p.add_argument(
        "--address",
        default=None,
        metavar="ADDRESS",
        help="with --backend ray: the cluster to join (auto, HOST:6379, ray://HOST:10001); default: a "
        "local Ray instance",
    )

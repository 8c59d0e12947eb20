"""mobman's top-level packages and the check that a user's file of the same name does not hide one of them.

mobman installs four top-level packages with generic names (`mobman_env`, `policies`, `eval`, `train`). A
file or folder of one of those names earlier on `sys.path` (a user's `eval.py` or `policies.py` beside their
script) would be imported instead, and the failure would read "'policies' is not a package". `eval`'s CLI and
`train` call `shadowing_message` before importing the others, so the user reads which file hides which package
and what to do. The check uses `importlib.util.find_spec` and imports nothing.

Imports nothing of mobman's (a leaf module).
"""

from __future__ import annotations

from importlib.util import find_spec
from pathlib import Path

#: mobman's top-level packages, all installed side by side in one folder
PACKAGES = ("mobman_env", "policies", "eval", "train")

#: the folder holding mobman's packages
ROOT = Path(__file__).resolve().parents[1]


def shadowing_message(names: tuple[str, ...] = PACKAGES) -> str | None:
    """None if every package in `names` resolves to mobman's own; else a message naming the file that hides the
    first one that does not, and the fix."""
    for name in names:
        try:
            spec = find_spec(name)
        except (ImportError, ValueError):
            spec = None
        origin = spec.origin if spec is not None else None
        if origin is None or Path(origin).resolve().parent.parent != ROOT:
            return (
                f"`import {name}` found {origin or 'a namespace package or nothing'}, not mobman's {name} package "
                f"in {ROOT}: a file or folder named {name!r} in the working directory or on sys.path hides it; "
                f"rename it (and delete its __pycache__)"
            )
    return None


def check_not_shadowed(names: tuple[str, ...] = PACKAGES) -> None:
    """Raise `ImportError` with `shadowing_message(names)` if one of mobman's packages is hidden."""
    message = shadowing_message(names)
    if message is not None:
        raise ImportError(message)

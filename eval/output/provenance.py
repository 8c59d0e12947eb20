"""Provenance: where a result comes from (package versions, the git revision of the source tree)."""

from __future__ import annotations

import platform
import subprocess
from importlib import metadata
from pathlib import Path

_VERSION_PACKAGES = ("mobman", "numpy", "gymnasium", "pybullet", "matplotlib", "stable-baselines3", "torch")


def versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in _VERSION_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def git_rev() -> str:
    """The commit of the source tree the eval package runs from (`"<sha>"` or `"<sha>-dirty"`), or `"unknown"`."""
    here = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5)
        if sha.returncode != 0:
            return "unknown"
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=5,
        )
        return sha.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"

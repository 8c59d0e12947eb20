"""Provenance: where a result comes from: package versions, the git revision of the source tree and, in
`provenance()` (results.json schema 2), the machine: CPU, numpy's BLAS build, the BLAS kernel loaded at run time
(threadpoolctl) and the environment variables that select it.

Since provenance schema 4 (`PROVENANCE_SCHEMA`) a provenance also names the code exactly: `code` (`code_hash`,
the SHA-256 of the four packages' source, which every episode record carries too) and, from a dirty tree,
`diff` (`tree_diff`: the SHA-256 of the uncommitted changes and the changed paths), so that "dirty" is never
anonymous; `provenance_class` sorts a provenance into clean, dirty with a named diff, or dirty and unnamed.

Imports: the standard library, numpy, (optional) threadpoolctl and `mobman_env.packages` (a leaf module: where
mobman's four packages are; it imports nothing of mobman's).
"""

from __future__ import annotations

import functools
import hashlib
import os
import platform
import re
import subprocess
from importlib import metadata
from pathlib import Path

import numpy as np

from mobman_env.packages import PACKAGES, ROOT

_VERSION_PACKAGES = (
    "mobman",
    "numpy",
    "numba",
    "gymnasium",
    "pybullet",
    "matplotlib",
    "stable-baselines3",
    "torch",
)
#: the modules whose compiled kernels define the numbers (`kernels()` hashes their source)
KERNEL_MODULES = ("mobman_env.engine", "policies.kernels.shared", "policies.laws.nnbc", "policies.kernels.model_free")


def kernels() -> dict[str, str | None]:
    """SHA-256 (first 16 hex digits) of the source of each module of `KERNEL_MODULES`: the env's step and the
    controllers' compiled laws. Two results whose kernel hashes (and versions) agree were computed by the same
    arithmetic, whatever the machine's BLAS."""
    import importlib.util

    out: dict[str, str | None] = {}
    for name in KERNEL_MODULES:
        spec = importlib.util.find_spec(name)
        origin = spec.origin if spec is not None else None
        try:
            out[name] = hashlib.sha256(Path(origin).read_bytes()).hexdigest()[:16] if origin else None
        except OSError:
            out[name] = None
    return out


def versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in _VERSION_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


@functools.cache
def code_hash() -> str:
    """SHA-256 (hex) over the source of mobman's four packages (`mobman_env`, `policies`, `eval`, `train`): every
    `*.py` file under them, in sorted order, each as its path relative to their folder and its bytes.

    The one name of "the code that ran": every episode record carries it (`code`, stamped by `eval.grid`), a
    resumed run, sweep or bench refuses a journal of other code (never one result from two code versions), and
    `mobman-train report` keys its controllers' cache on it. Decisions: the source, not the git revision, because
    it is the same with and without git (a pip install, a copied tree) and changes with any edit, committed or
    not; all four packages, because the metrics and the rollout loop (eval) make the numbers as much as the env
    and the controllers do; `.py` files only (compiled caches and data files are not code; a shipped agent's
    files are hashed in its record's `artefacts`). A user's own `module:attr` controller is outside it: its
    version is the user's to record. Computed once per process (cached): the code a process runs is the code it
    imported when it started."""
    h = hashlib.sha256()
    for name in PACKAGES:
        root = ROOT / name
        for path in sorted(root.rglob("*.py")):
            if "__pycache__" in path.parts:
                continue
            h.update(path.relative_to(ROOT).as_posix().encode())
            h.update(b"\0")
            h.update(path.read_bytes())
    return h.hexdigest()


def _git(*args: str, text: bool = True) -> subprocess.CompletedProcess | None:
    """`git ARGS` in mobman's source folder, or None where git is missing, fails or times out."""
    try:
        proc = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=text, timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return proc if proc.returncode == 0 else None


def _untracked() -> list[str]:
    """The untracked files (not ignored) under the four packages, relative to the tree's top."""
    proc = _git("ls-files", "--others", "--exclude-standard", "--full-name", "--", *PACKAGES)
    return sorted(proc.stdout.splitlines()) if proc is not None else []


def git_rev() -> str:
    """The commit of the source tree the eval package runs from (`"<sha>"` or `"<sha>-dirty"`), or `"unknown"`.
    Dirty: a tracked file differs from the commit, or an untracked file (not ignored) lies under one of the
    four packages (a new module changes what runs as much as an edit does)."""
    sha = _git("rev-parse", "HEAD")
    if sha is None:
        return "unknown"
    status = _git("status", "--porcelain", "--untracked-files=no")
    dirty = status is None or bool(status.stdout.strip()) or bool(_untracked())
    return sha.stdout.strip() + ("-dirty" if dirty else "")


def tree_diff() -> dict | None:
    """What makes the tree dirty, named: `{"sha256", "paths"}`, or None for a clean tree (or no git).

    `sha256` is over the bytes of `git diff HEAD --binary` (every tracked file's uncommitted change) followed,
    for each untracked file under the four packages, by its path and the SHA-256 of its bytes; `paths` lists the
    changed tracked files and those untracked files. With the commit (`git`) the hash names the exact tree that
    ran: whoever holds the same diff can check it (`git diff HEAD --binary | sha256sum` when nothing is
    untracked)."""
    names = _git("diff", "HEAD", "--name-only")
    diff = _git("diff", "HEAD", "--binary", text=False)
    if names is None or diff is None:
        return None
    untracked = _untracked()
    paths = sorted(set(names.stdout.splitlines()) | set(untracked))
    if not paths:
        return None
    top = _git("rev-parse", "--show-toplevel")
    base = Path(top.stdout.strip()) if top is not None else ROOT
    h = hashlib.sha256(diff.stdout)
    for name in untracked:
        try:
            digest = hashlib.sha256((base / name).read_bytes()).hexdigest()
        except OSError:
            digest = "unreadable"
        h.update(f"\0untracked {name} {digest}".encode())
    return {"sha256": h.hexdigest(), "paths": paths}


#: provenance schema 4: `schema`, `code` and `diff` (none before; schema 4 is the results schema of release 0.4)
PROVENANCE_SCHEMA = 4

#: the three answers of `provenance_class`
CLEAN, DIRTY_NAMED, DIRTY_UNNAMED = "clean", "dirty with named diff", "dirty, unnamed"

_SHA1 = re.compile(r"[0-9a-f]{40}")
_SHA256 = re.compile(r"[0-9a-f]{64}")


def provenance_class(prov: dict | str | None) -> str:
    """Whether a provenance names the code that made a result: `CLEAN` (a 40-digit commit, not "-dirty"),
    `DIRTY_NAMED` (a commit "-dirty" whose `diff` names the change: a 64-digit `sha256` and a non-empty list of
    `paths`), or `DIRTY_UNNAMED` (anything else: a dirty tree without its diff, "unknown", a short or missing
    revision). `prov` is a provenance dict (its `git` and `diff`) or a bare git string (the top-level `git` of
    files without a provenance). Pure: it checks the record's form, not the repository."""
    if isinstance(prov, str):
        prov = {"git": prov}
    if not isinstance(prov, dict) or not isinstance(prov.get("git"), str):
        return DIRTY_UNNAMED
    git = prov["git"]
    if _SHA1.fullmatch(git):
        return CLEAN
    diff = prov.get("diff")
    if (
        git.endswith("-dirty")
        and _SHA1.fullmatch(git[: -len("-dirty")])
        and isinstance(diff, dict)
        and isinstance(diff.get("sha256"), str)
        and _SHA256.fullmatch(diff["sha256"])
        and isinstance(diff.get("paths"), list)
        and diff["paths"]
        and all(isinstance(p, str) for p in diff["paths"])
    ):
        return DIRTY_NAMED
    return DIRTY_UNNAMED


#: Environment variables that change numerical results or their speed (BLAS kernel and thread pools).
PROVENANCE_ENV_VARS = ("OPENBLAS_CORETYPE", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "MKL_CBWR")


def cpu_model() -> str | None:
    """The CPU's model name (Linux: /proc/cpuinfo "model name"; elsewhere `platform.processor()`)."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.lower().startswith(("model name", "hardware")):
                    return line.split(":", 1)[1].strip() or None
    except OSError:
        pass
    return platform.processor() or None


def blas_runtime() -> list[dict] | None:
    """The BLAS/OpenMP libraries loaded in this process, from threadpoolctl's `threadpool_info()`: user_api,
    internal_api (openblas, mkl, blis, ...), version, architecture (OpenBLAS's core kernel, e.g. "Haswell",
    which `OPENBLAS_CORETYPE` selects), threading_layer and num_threads. None without threadpoolctl."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return None
    keys = ("user_api", "internal_api", "prefix", "version", "architecture", "threading_layer", "num_threads")
    return [{k: lib.get(k) for k in keys} for lib in threadpool_info()]


def numpy_build() -> dict | None:
    """numpy's build-time BLAS and LAPACK (name, version, OpenBLAS configuration), from `np.show_config`."""
    try:
        deps = np.show_config(mode="dicts").get("Build Dependencies", {})
    except Exception:  # numpy < 1.26 has no mode="dicts"
        return None
    keep = ("name", "version", "openblas configuration")
    return {lib: {k: info.get(k) for k in keep if k in info} for lib, info in deps.items() if isinstance(info, dict)}


def provenance() -> dict:
    """Where results were produced: everything known to change floating-point results or their speed.

    `{"schema", "cpu", "machine", "cpu_count", "platform", "python", "numpy", "numpy_build", "blas", "env",
    "versions", "git", "diff", "code", "kernels"}`: the provenance schema (`PROVENANCE_SCHEMA`), CPU model, architecture, core count, OS, Python, numpy's version and build-time BLAS, the
    BLAS loaded at run time and its kernel (`blas_runtime`), the environment variables of `PROVENANCE_ENV_VARS`
    (None when unset), the package versions, the git revision, what makes the tree dirty (`tree_diff`: None when
    clean), the hash of the four packages' source (`code_hash`) and the hashes of the compiled kernels' source
    (`kernels`). The env and the controllers whose laws are compiled kernels (`nnbc`, `jmpi`, `clik`, `oracle`,
    `qp`, and since the numba port of the model-free law `nnbc-plus`, `broyden`, `rls`) do not use BLAS: their
    figures do not depend on the `blas` entries; the SB3 agents (and the model-free controllers of earlier
    revisions, written in numpy) may."""
    git = git_rev()
    return {
        "schema": PROVENANCE_SCHEMA,
        "cpu": cpu_model(),
        "machine": platform.machine(),
        "cpu_count": os.cpu_count(),
        "platform": platform.platform(),
        "python": f"{platform.python_implementation()} {platform.python_version()}",
        "numpy": np.__version__,
        "numpy_build": numpy_build(),
        "blas": blas_runtime(),
        "env": {k: os.environ.get(k) for k in PROVENANCE_ENV_VARS},
        "versions": versions(),
        "git": git,
        "diff": tree_diff() if git.endswith("-dirty") else None,
        "code": code_hash(),
        "kernels": kernels(),
    }

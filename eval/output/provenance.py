"""Provenance: where a result comes from: package versions, the git revision of the source tree and, in
`provenance()` (results.json schema 2), the machine: CPU, numpy's BLAS build, the BLAS kernel loaded at run time
(threadpoolctl) and the environment variables that select it.

Imports: the standard library, numpy and (optional) threadpoolctl.
"""

from __future__ import annotations

import os
import platform
import subprocess
from importlib import metadata
from pathlib import Path

import numpy as np

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
KERNEL_MODULES = ("mobman_env.engine", "policies.kernels", "policies.nnbc", "policies.model_free_kernels")


def kernels() -> dict[str, str | None]:
    """SHA-256 (first 16 hex digits) of the source of each module of `KERNEL_MODULES`: the env's step and the
    controllers' compiled laws. Two results whose kernel hashes (and versions) agree were computed by the same
    arithmetic, whatever the machine's BLAS."""
    import hashlib
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

    `{"cpu", "machine", "cpu_count", "platform", "python", "numpy", "numpy_build", "blas", "env", "versions",
    "git", "kernels"}`: CPU model, architecture, core count, OS, Python, numpy's version and build-time BLAS, the
    BLAS loaded at run time and its kernel (`blas_runtime`), the environment variables of `PROVENANCE_ENV_VARS`
    (None when unset), the package versions, the git revision and the hashes of the compiled kernels' source
    (`kernels`). The env and the controllers whose laws are compiled kernels (`nnbc`, `jmpi`, `clik`, `oracle`,
    `qp`, and since the numba port of the model-free law `nnbc-plus`, `broyden`, `rls`) do not use BLAS: their
    figures do not depend on the `blas` entries; the SB3 agents (and the model-free controllers of earlier
    revisions, written in numpy) may."""
    return {
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
        "git": git_rev(),
        "kernels": kernels(),
    }

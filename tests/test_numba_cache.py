"""numba's on-disk cache of the kernels (`mobman_env.numba_cache`): a damaged index or data file is removed and
the kernel compiled again, with one line on stderr naming the file, instead of a numba traceback in every later
process. Each run uses its own `NUMBA_CACHE_DIR` (the package's real cache is never touched) and one tiny
kernel (compiled in about a second)."""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
KERNEL = """\
from mobman_env.numba_cache import njit


@njit(cache=True)
def add(a, b):
    return a + b


print(add(1, 2))
"""


def _run(folder: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(folder / "cache"), "PYTHONPATH": f"{ROOT}{os.pathsep}{folder}"}
    return subprocess.run(
        [sys.executable, str(folder / "tiny.py")], capture_output=True, text=True, env=env, timeout=120, cwd=folder
    )


def _said(err: str) -> list[str]:
    return [line for line in err.splitlines() if "numba's cache file" in line]


def test_a_corrupt_cache_file_is_recompiled_and_said_once(tmp_path):
    (tmp_path / "tiny.py").write_text(KERNEL)
    first = _run(tmp_path)
    assert first.returncode == 0 and first.stdout == "3\n", first.stderr
    index = next((tmp_path / "cache").rglob("tiny.add-*.nbi"))
    data = next((tmp_path / "cache").rglob("tiny.add-*.nbc"))
    for damaged, damage in ((index, b"garbage"), (data, b"garbage"), (data, data.read_bytes()[:300])):
        damaged.write_bytes(damage)
        again = _run(tmp_path)
        assert again.returncode == 0 and again.stdout == "3\n", again.stderr
        assert "Traceback" not in again.stderr, again.stderr
        said = _said(again.stderr)
        assert len(said) == 1 and str(damaged) in said[0], again.stderr
        assert "could not be loaded" in said[0] and f"add ({tmp_path / 'tiny.py'}) is compiled again" in said[0]
        assert damaged.read_bytes() != damage  # written again by the recompile
        quiet = _run(tmp_path)  # the next process loads the new file and says nothing
        assert quiet.returncode == 0 and quiet.stdout == "3\n" and not _said(quiet.stderr), quiet.stderr


@pytest.mark.parametrize(
    "module",
    [
        "mobman_env.engine",
        "policies.kernels.shared",
        "policies.kernels.model_free",
        "policies.laws.calib_qp",
        "policies.laws.nnbc",
    ],
)
def test_every_cached_kernel_recovers_from_a_corrupt_file(module):
    from numba.core.dispatcher import Dispatcher

    from mobman_env.numba_cache import CheckedFunctionCache

    kernels = [v for v in vars(importlib.import_module(module)).values() if isinstance(v, Dispatcher)]
    assert kernels
    for kernel in kernels:
        assert isinstance(kernel._cache, CheckedFunctionCache), kernel


def test_a_damaged_index_never_removes_a_file_outside_the_cache(tmp_path):
    """An index whose entry names `../FILE` (a damaged or crafted index) makes the load fail: the index itself is
    removed, never the file it names outside the kernel's cache folder."""
    import pickle

    (tmp_path / "tiny.py").write_text(KERNEL)
    assert _run(tmp_path).returncode == 0
    index = next((tmp_path / "cache").rglob("tiny.add-*.nbi"))
    data = next((tmp_path / "cache").rglob("tiny.add-*.nbc"))
    victim = index.parent.parent / data.name
    victim.write_bytes(b"not a cache file: someone's data")
    with open(index, "rb") as f:
        version = pickle.load(f)
        stamp, overloads = pickle.loads(f.read())
    overloads = {key: f"../{name}" for key, name in overloads.items()}
    index.write_bytes(pickle.dumps(version) + pickle.dumps((stamp, overloads)))
    again = _run(tmp_path)
    assert again.returncode == 0 and again.stdout == "3\n", again.stderr
    said = _said(again.stderr)
    assert len(said) == 1 and f"cache file {index} could not be loaded" in said[0], again.stderr
    assert victim.read_bytes() == b"not a cache file: someone's data"
    assert not _said(_run(tmp_path).stderr)


@pytest.mark.parametrize("package", ["mobman_env", "policies"])
def test_the_warm_up_commands_exit_cleanly(package):
    """`python -m mobman_env` and `python -m policies` (CI's and a fresh install's compile step) exit 0: their
    warm-up calls every kernel with arrays of the shapes the kernels write (numba does not check bounds: a state
    array one column short was written past its end and the process aborted at exit, "free(): invalid pointer")."""
    proc = subprocess.run([sys.executable, "-m", package], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "kernels ready" in proc.stdout

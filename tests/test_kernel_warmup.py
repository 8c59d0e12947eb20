"""A first run says it compiles numba's kernels, compiles them before the first episode, and keeps the compile
out of the progress bar's clock (`eval.execution.warmup`); a warm cache says nothing (`mobman_env.kernel_cache`)."""

from __future__ import annotations

import importlib
import os
import pkgutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

import policies
from eval import EvalConfig, grid, run
from eval.execution import warmup
from mobman_env import engine
from mobman_env.kernel_cache import cold_kernels
from policies.warm import KERNEL_MODULES
from policies.warm import warm as warm_controllers

ROOT = Path(__file__).resolve().parents[1]
_PARTS = "from eval.execution.warmup import cold_parts; print(','.join(cold_parts()))"


def _cold_parts_in(cache_dir: Path | None) -> str:
    """`cold_parts()` in a fresh process, with `NUMBA_CACHE_DIR` = `cache_dir` (None: the default cache)."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = str(ROOT)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = str(cache_dir)
    out = subprocess.run([sys.executable, "-c", _PARTS], env=env, capture_output=True, text=True, check=True)
    return out.stdout.strip()


def test_after_warm_no_kernel_would_compile():
    """Both packages' warm() reach every cached kernel, so a warm cache is reported warm (no false 'compiling')."""
    engine.warm()
    warm_controllers()
    assert cold_kernels(engine, *KERNEL_MODULES) == []
    assert warmup.cold_parts() == []


def test_policies_kernel_modules_are_all_listed():
    """Every policies module holding an @njit(cache=True) kernel is in KERNEL_MODULES (else it is never checked)."""
    from numba.core.dispatcher import Dispatcher

    with_kernels = set()
    for info in pkgutil.walk_packages(policies.__path__, "policies."):  # the sub-packages' modules too
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        if any(isinstance(v, Dispatcher) and v.__module__ == module.__name__ for v in vars(module).values()):
            with_kernels.add(module.__name__)
    assert with_kernels == {m.__name__ for m in KERNEL_MODULES}


def test_an_empty_numba_cache_is_cold_and_the_default_one_warm(tmp_path):
    """numba honours NUMBA_CACHE_DIR for cache=True kernels: an empty folder means both parts would compile."""
    engine.warm()
    warm_controllers()
    assert _cold_parts_in(tmp_path) == "engine,controllers"
    assert _cold_parts_in(None) == ""


def _tiny(tmp_path: Path) -> EvalConfig:
    return EvalConfig(
        policies=("zero",), episodes=1, dynamics=("kinematic",), out=str(tmp_path / "run"), plots=False, progress=True
    )


def test_a_cold_cache_is_announced_and_compiled_before_the_bar_starts(tmp_path, monkeypatch, capsys):
    """With a cold cache (simulated: the compile itself is stubbed), the line comes first, then the compile, then
    the bar: the bar's start time (tqdm's clock, `start_t`) is after the compile ended, so its ETA holds none."""
    ended: list[float] = []
    bars: list = []
    monkeypatch.setattr(warmup, "cold_parts", lambda: ["engine", "controllers"])
    monkeypatch.setattr(engine, "warm", lambda: ended.append(time.time()) or 0.0)
    monkeypatch.setattr("policies.warm.warm", lambda: ended.append(time.time()) or 0.0)
    real_bar = grid.progress_bar
    monkeypatch.setattr(grid, "progress_bar", lambda *a, **k: bars.append(real_bar(*a, **k)) or bars[-1])
    run(_tiny(tmp_path))
    err = capsys.readouterr().err
    about = warmup.COMPILE_S["engine"] + warmup.COMPILE_S["controllers"]
    assert f"compiling the kernels once (about {about:.0f} s;" in err
    assert err.index("compiling the kernels once") < err.index("kernels compiled in") < err.index("1/1")
    assert len(ended) == 2 and len(bars) == 1
    assert bars[0].start_t >= max(ended)


def test_a_warm_cache_says_nothing_and_compiles_nothing(tmp_path, monkeypatch, capsys):
    """The warm case: no line, and no warm() call (which would load every kernel in the parent for nothing)."""
    monkeypatch.setattr(warmup, "cold_parts", lambda: [])
    monkeypatch.setattr(engine, "warm", lambda: pytest.fail("warm() called with a warm cache"))
    run(_tiny(tmp_path))
    assert "compiling" not in capsys.readouterr().err


@pytest.mark.slow
def test_a_first_run_on_an_empty_cache_says_it_compiles_and_the_second_does_not(tmp_path):
    """End to end, real compile: `mobman-eval run` with NUMBA_CACHE_DIR empty announces it; the rerun does not."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    errs = []
    for i in range(2):
        argv = ["-m", "eval", "run", "--policy", "zero", "--episodes", "1", "--dynamics", "kinematic"]
        argv += ["--out", str(tmp_path / f"run{i}"), "--no-plots"]
        done = subprocess.run([sys.executable, *argv], env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        errs.append(done.stderr)
    assert "compiling the kernels once" in errs[0] and "kernels compiled in" in errs[0]
    assert "compiling" not in errs[1]


class _Stop(Exception):
    pass


def test_picture_and_speed_compile_and_say_so_before_their_work(tmp_path, monkeypatch, capsys):
    """The commands that run kernels outside a grid (picture's episode or gallery, speed's first timing) compile
    a cold cache first, announced, so that neither sits silent nor times the compile."""
    from eval.cli import main
    from eval.speed import SpeedConfig, measure

    events: list[str] = []
    monkeypatch.setattr(warmup, "cold_parts", lambda: ["engine"])
    monkeypatch.setattr(engine, "warm", lambda: events.append("compile") or 0.0)

    def gallery(config):
        events.append("render")
        return {"robots": {}}

    monkeypatch.setattr("eval.cli.picture.render_gallery", gallery)
    assert main(["picture", "--gallery", str(tmp_path / "g"), "--width", "64", "--height", "64"]) == 0
    assert events == ["compile", "render"]
    assert "compiling the kernels once" in capsys.readouterr().err

    def first_timing(*args, **kwargs):
        events.append("time")
        raise _Stop

    monkeypatch.setattr("eval.speed.env_vs_bare", first_timing)
    with pytest.raises(_Stop):
        measure(SpeedConfig(), progress=lambda message: None)
    assert events[2:] == ["compile", "time"]
    assert "compiling the kernels once" in capsys.readouterr().err

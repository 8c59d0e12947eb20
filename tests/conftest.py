"""Shared fixtures. Every env made here is closed by its fixture."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

import pytest

import mobman_env

#: a short task for fast tests: the paper's circle shape, 1 s
SHORT_CIRCLE = {"type": "circle", "radius": 0.1, "tilt": 0.5235987755982988, "yaw": 3.141592653589793, "duration": 1.0}


@pytest.fixture
def make_env():
    """Factory fixture: `make_env(**kwargs)` builds a WheeledPumaEnv and closes it after the test."""
    envs = []

    def _make(**kwargs):
        env = mobman_env.WheeledPumaEnv(**kwargs)
        envs.append(env)
        return env

    yield _make
    for env in envs:
        env.close()


# --- no silent skips in CI ---------------------------------------------------------------------------------
# `pytest.importorskip("stable_baselines3")` skips the [rl] tests when SB3 is missing: fine on a laptop, a
# hole in CI. With CI set (as CI services do) or MOBMAN_NO_SKIPS=1, any skipped test or module fails the
# session and the summary lists them; MOBMAN_NO_SKIPS=0 turns the check off even under CI. An xfail is not a
# skip. (pytest_plugins = ["pytester"] in tests/test_no_skips.py tests these hooks.)
_SKIPPED: list[tuple[str, str]] = []


def no_skips_required() -> bool:
    """True when skipped tests must fail the session: MOBMAN_NO_SKIPS=1, or CI set and MOBMAN_NO_SKIPS unset."""
    flag = os.environ.get("MOBMAN_NO_SKIPS")
    if flag is not None and flag != "":
        return flag.strip().lower() not in ("0", "false", "no")
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def _record_skip(report) -> None:
    if report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
        _SKIPPED.append((report.nodeid, reason))


def pytest_sessionstart(session) -> None:
    _SKIPPED.clear()


def pytest_collectreport(report) -> None:
    _record_skip(report)


def pytest_runtest_logreport(report) -> None:
    _record_skip(report)


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session, exitstatus) -> None:
    if hasattr(session.config, "workerinput"):  # an xdist worker: the controller decides
        return
    if _SKIPPED and no_skips_required() and exitstatus in (pytest.ExitCode.OK, pytest.ExitCode.NO_TESTS_COLLECTED):
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    if _SKIPPED and no_skips_required() and not hasattr(config, "workerinput"):
        terminalreporter.section("skipped tests fail this session (CI or MOBMAN_NO_SKIPS=1)", red=True)
        for nodeid, reason in _SKIPPED:
            terminalreporter.line(f"SKIPPED {nodeid}: {reason}", red=True)
        terminalreporter.line(
            "install what they need (pip install -e '.[test]' installs every extra the tests use) or set "
            "MOBMAN_NO_SKIPS=0 to allow skips"
        )

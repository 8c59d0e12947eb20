"""The no-silent-skips hooks of tests/conftest.py: under CI (or MOBMAN_NO_SKIPS=1) a skipped test or module fails
the session and the summary names it; an xfail is not a skip; without the flag skips stay skips.

Each case runs a small session in-process (pytester) with the hooks' section of this project's conftest.py.
"""

from __future__ import annotations

from pathlib import Path

import pytest

pytest_plugins = ["pytester"]

MARKER = "# --- no silent skips in CI"
#: the hooks alone (the rest of conftest.py imports the simulator, which these sessions do not need)
HOOKS = (
    "import os\n\nimport pytest\n\n" + MARKER + Path(__file__).with_name("conftest.py").read_text().split(MARKER, 1)[1]
)

SESSION = {
    "test_mixed": """
import pytest

def test_passes():
    assert 1 + 1 == 2

def test_skipped_inside():
    pytest.skip("no GPU here")

@pytest.mark.xfail(reason="known bug", strict=True)
def test_xfails():
    assert False
""",
    "test_whole_module": """
import pytest

pytest.importorskip("no_such_package_mobman")

def test_never_collected():
    pass
""",
}


@pytest.fixture(autouse=True)
def _clean_env(monkeypatch):
    for name in ("CI", "MOBMAN_NO_SKIPS"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")  # the inner sessions need no plugins: fast


@pytest.fixture
def session(pytester):
    pytester.makeconftest(HOOKS)
    pytester.makepyfile(**SESSION)
    return pytester


@pytest.mark.parametrize(
    "env, enforced",
    [
        ({"MOBMAN_NO_SKIPS": "1"}, True),
        ({"CI": "true"}, True),
        ({}, False),
        ({"CI": "true", "MOBMAN_NO_SKIPS": "0"}, False),
        ({"CI": "false"}, False),
    ],
)
def test_skips_fail_the_session_only_under_the_flag_and_are_listed(session, monkeypatch, env, enforced):
    for k, v in env.items():
        monkeypatch.setenv(k, v)
    result = session.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, skipped=2, xfailed=1)
    out = result.stdout.str()
    if not enforced:
        assert result.ret == pytest.ExitCode.OK and "skipped tests fail this session" not in out
        return
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    listed = out.split("skipped tests fail this session", 1)[1]
    assert "SKIPPED test_mixed.py::test_skipped_inside: Skipped: no GPU here" in listed
    assert "SKIPPED test_whole_module.py: Skipped: could not import 'no_such_package_mobman'" in listed
    assert "test_xfails" not in listed  # an xfail is no skip


def test_a_session_without_skips_passes_under_the_flag(pytester, monkeypatch):
    monkeypatch.setenv("MOBMAN_NO_SKIPS", "1")
    pytester.makeconftest(HOOKS)
    pytester.makepyfile(test_ok="def test_ok():\n    assert True\n")
    result = pytester.runpytest("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.OK
    result.assert_outcomes(passed=1)


def test_failures_keep_their_exit_status_under_the_flag(session, monkeypatch):
    monkeypatch.setenv("MOBMAN_NO_SKIPS", "1")
    session.makepyfile(test_fails="def test_fails():\n    assert False\n")
    result = session.runpytest("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.assert_outcomes(passed=1, failed=1, skipped=2, xfailed=1)

"""`mobman-eval timings` (`eval.timings`): the README's steps timed, wall and CPU, with the load; a failed step
is recorded as failed."""

from __future__ import annotations

import json
import sys

import pytest

from eval import timings
from eval.cli import main

BUSY = f'{sys.executable} -c "x = 0\nfor i in range(3_000_000): x += i"'
FAIL = f'{sys.executable} -c "import sys; sys.exit(3)"'


def test_a_step_records_its_childrens_cpu_time_and_the_load():
    res = timings.measure(["busy"], commands={"busy": ("a busy child", BUSY)})
    (s,) = res["steps"]
    assert s["returncode"] == 0 and s["step"] == "busy"
    assert s["cpu_s"] > 0.0  # the child's user time is counted (it ran a loop of 3 M additions)
    assert s["load_before"] >= 0.0 and s["load_after"] >= 0.0
    assert res["cores"] >= 1


def test_a_failed_step_is_recorded_as_failed_and_the_next_still_runs():
    res = timings.measure(["bad", "busy"], commands={"bad": ("fails", FAIL), "busy": ("a busy child", BUSY)})
    bad, busy = res["steps"]
    assert bad["returncode"] == 3 and busy["returncode"] == 0
    text = timings.markdown(res)
    assert "| fails |" in text and "failed (exit 3)" in text and "passed" in text
    assert "## Timings" in text


def test_the_compile_step_runs_with_an_empty_numba_cache(tmp_path):
    probe = f"{sys.executable} -c \"import os, sys; d = os.environ['NUMBA_CACHE_DIR']; sys.exit(1 if os.path.isdir(d) and os.listdir(d) else 0)\""
    res = timings.measure(["compile"], commands={"compile": ("probe", probe)})
    assert res["steps"][0]["returncode"] == 0


def test_unknown_steps_are_refused_before_anything_runs(tmp_path, capsys):
    out = tmp_path / "t"
    with pytest.raises(SystemExit) as exit_:
        main(["timings", "--steps", "compile,install", "--out", str(out)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "'install'" in err and "accepted: compile, main, tests" in err
    assert not out.exists()


def test_the_cli_writes_json_and_markdown(tmp_path, monkeypatch):
    monkeypatch.setattr(timings, "STEPS", {**timings.STEPS, "compile": ("a busy child", BUSY)})
    monkeypatch.setattr(timings.measure, "__defaults__", (timings.STEPS, timings.measure.__defaults__[1]))
    out = tmp_path / "t"
    assert main(["timings", "--steps", "compile", "--out", str(out), "--quiet"]) == 0
    data = json.loads((out / "timings.json").read_text())
    assert [s["step"] for s in data["steps"]] == ["compile"] and "provenance" in data
    assert (out / "timings.md").read_text() == timings.markdown(data)


@pytest.mark.parametrize("seconds, text", [(75.4, "75 s"), (119.6, "120 s"), (252.0, "4.2 min")])
def test_durations_are_printed_in_seconds_then_minutes(seconds, text):
    assert timings._duration(seconds) == text


def test_the_readme_quotes_the_committed_timings_through_a_generated_block():
    """One recorded source: docs/results/timings/timings.json holds every README step from a clean tree (the
    compile and the main job passed; the tests step's result is whatever the suite of that commit gave, this test
    included, so it is shown, not asserted), and the README's "How long" quotes its CPU and wall times through the
    generated block (no typed figure)."""
    from pathlib import Path

    from eval.output.provenance import CLEAN, provenance_class

    root = Path(__file__).resolve().parents[1]
    record = json.loads((root / "docs" / "results" / "timings" / "timings.json").read_text())
    assert [s["step"] for s in record["steps"]] == list(timings.STEPS)
    assert [s["returncode"] for s in record["steps"][:2]] == [0, 0], record["steps"][:2]
    assert provenance_class(record["provenance"]) == CLEAN
    readme = (root / "README.md").read_text()
    begin = "<!-- generated:begin docs/results/timings/timings.md Timings -->"
    assert readme.count(begin) == 1
    block = readme.split(begin)[1].split("<!-- generated:end -->")[0]
    for step in record["steps"]:
        result = "passed" if step["returncode"] == 0 else f"failed (exit {step['returncode']})"
        assert f"{timings._duration(step['wall_s'])} | {timings._duration(step['cpu_s'])} | {result}" in block
    assert "How long: on the project's" not in readme  # the hand-typed paragraph it replaced

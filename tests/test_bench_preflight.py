"""Every spec is checked against every cell before any episode runs (`eval.bench.preflight`, `eval.checks`): a
spec that cannot run some cells (the PUMA agent, 8 actions, on the 9-actuator Panda) is refused at once with the
cells, the reason and the option that leaves them out; no episode, no folder, no warning per env, no list of
unrelated policy names."""

from __future__ import annotations

import json

import pytest
from test_eval_helpers import SHORT

from eval.bench import config as BC
from eval.bench.preflight import describe, fix
from eval.bench.run import run_bench
from eval.cli import main

AGENT = "sb3:ppo-circle"  # trained on WheeledPuma-Circle-v0: 8 actions (the Panda takes 9)
ARGS = ["bench", "--tasks", "circle", "--conditions", "default,wear20", "--seeds", "1", "--no-plots"]
ARGS += ["--env-kwargs", json.dumps(SHORT)]


def _forbid_episodes(monkeypatch) -> None:
    """Any episode (a bench's grid, an --against sample) fails the test: the refusal must come before."""

    def episode(*args, **kwargs):
        raise AssertionError("an episode ran before the refusal")

    monkeypatch.setattr("eval.grid.execute", episode)
    monkeypatch.setattr("eval.bench.against.rerun_sample", episode)


@pytest.fixture
def no_episodes(monkeypatch):
    _forbid_episodes(monkeypatch)


def _refusal(capsys, argv: list[str]) -> str:
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "known:" not in err and "Warning" not in err and "Traceback" not in err, err
    lines = [x for x in err.strip().splitlines() if not x.startswith("bench: building ")]  # what it checks
    assert len(lines) == 1, err  # the refusal alone: no warning per env before it
    return err


def test_an_agent_that_cannot_drive_the_panda_is_refused_before_any_episode(tmp_path, capsys, no_episodes):
    out = tmp_path / "bench"
    err = _refusal(capsys, [*ARGS, "--policy", f"zero,{AGENT}", "--out", str(out)])
    assert (
        f"policy '{AGENT}' cannot run on 2 of the 8 cells (robot(s) panda x task(s) circle in condition(s) "
        "default, wear20): the agent " in err
    )
    assert "outputs 8 actions; the env takes 9. Leave those cells out with --robots puma,ur5,random-arm" in err
    assert not out.exists()  # no bench.json, no journal


def test_against_refuses_before_rerunning_the_committed_samples(tmp_path, capsys, monkeypatch):
    """With --against, the committed baselines' samples used to run first (and the refusal came after them)."""
    committed = BC.BenchConfig(
        robots=("puma", "panda"),
        tasks=("circle",),
        conditions=("default",),
        policies=("zero",),
        seeds=1,
        env_kwargs=SHORT,
    )
    run_bench(committed, tmp_path / "c", progress=False, plots=False)
    _forbid_episodes(monkeypatch)
    argv = ["bench", "--robots", "puma,panda", "--tasks", "circle", "--conditions", "default", "--no-plots"]
    err = _refusal(capsys, [*argv, "--against", str(tmp_path / "c"), "--policy", AGENT, "--out", str(tmp_path / "m")])
    assert "cannot run on 1 of the 2 cells (robot(s) panda x task(s) circle in condition(s) default)" in err
    assert "--robots puma," in err and not (tmp_path / "m").exists()


def test_a_spec_wrong_everywhere_keeps_its_own_message(tmp_path, capsys, no_episodes):
    err = _refusal(capsys, [*ARGS, "--robots", "panda", "--policy", AGENT, "--out", str(tmp_path / "b")])
    assert "outputs 8 actions; the env takes 9 (on every one of the 2 cells)" in err


def test_run_names_every_env_a_policy_cannot_run_on(tmp_path, capsys, no_episodes):
    envs = "WheeledPuma-Circle-v0,WheeledPanda-Circle-v0,WheeledPanda-Line-v0"
    argv = ["run", "--env", envs, "--policy", AGENT, "--seeds", "1", "--out", str(tmp_path / "r")]
    err = _refusal(capsys, argv)
    assert "cannot run on 2 of the 3 envs (WheeledPanda-Circle-v0, WheeledPanda-Line-v0)" in err
    assert "Run it on the other env(s) (WheeledPuma-Circle-v0) with --env" in err


def test_warnings_while_building_are_one_line_per_spec(tmp_path, capsys):
    """An agent on tasks it was not trained on warns once per env; the bench prints one line for all of them."""
    argv = ["bench", "--robots", "puma", "--tasks", "circle,line,lemniscate", "--conditions", "default,wear20"]
    argv += ["--policy", AGENT, "--max-episodes", "0", "--no-plots"]
    assert main([*argv, "--out", str(tmp_path / "b")]) == 0
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if "trained on" in x]
    assert len(lines) == 1 and lines[0].startswith(f"bench: policy '{AGENT}': the agent "), err
    assert lines[0].endswith("(and 1 more like it)"), err


C = [(c, r, t) for c in ("default", "wear20") for r in ("puma", "panda") for t in ("circle", "line")]


@pytest.mark.parametrize(
    ("failing", "text", "hint"),
    [
        (
            [x for x in C if x[1] == "panda"],
            "robot(s) panda x task(s) circle, line in condition(s) default, wear20",
            "--robots puma,",
        ),
        (
            [x for x in C if x[2] == "line"],
            "robot(s) puma, panda x task(s) line in condition(s) default, wear20",
            "--tasks circle,",
        ),
        (
            [x for x in C if x[0] == "wear20"],
            "robot(s) puma, panda x task(s) circle, line in condition(s) wear20",
            "--conditions default,",
        ),
        ([C[0], C[7]], "puma/circle (default), panda/line (wear20)", "with --robots, --tasks or --conditions,"),
    ],
)
def test_the_fix_names_the_axis_that_leaves_exactly_the_failing_cells_out(failing, text, hint):
    assert describe(failing) == text
    assert hint in fix(failing, C)

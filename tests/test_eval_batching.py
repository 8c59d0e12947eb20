"""Batched execution (`eval.execution.batches`): `run` with `batch_size` > 1 gives the results of
`batch_size=1` (timings and pid aside), for chaotic controllers too; a failing batch is re-run episode by
episode so only the failing episode is recorded failed; Ctrl-C keeps the finished batches.

Episodes are kinematic 1 s paths (100 steps)."""

from __future__ import annotations

import json

import gymnasium as gym
import pytest

import eval.execution.batches as B
import eval.execution.tasks as T
import policies
from eval import EvalConfig, run
from eval.errors import RunInterrupted
from eval.execution.batches import plan_units
from eval.execution.dispatch import execute
from eval.execution.tasks import Task
from mobman_env import TASKS
from policies.base import policy_seed

TIMING = ("wall_s", "pid", "predict_us_median", "predict_us_p99")
CIRCLE, LINE = "WheeledPuma-Circle-v0", "WheeledPuma-Line-v0"
SPECS = ("clik", "jmpi", "nnbc", "nnbc-plus", "zero")


def _config(tmp_path, name: str, **kw) -> EvalConfig:
    base = {
        "envs": (CIRCLE,),
        "policies": ("clik",),
        "episodes": 4,
        "seed": 10_000,
        "dynamics": ("kinematic",),
        "env_kwargs": {"path": dict(TASKS[CIRCLE], duration=1.0)},
        "out": str(tmp_path / name),
        "plots": False,
        "progress": False,
    }
    return EvalConfig(**{**base, **kw})


def _fields(results: dict) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in results["episodes"]]


def _drop_timing(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if not k.startswith("predict_us")} for r in rows]


@pytest.fixture
def small_batches(monkeypatch):
    """Batches of 2 and 3 (below the speed floor `MIN_BATCH`), so that short tests exercise the batched path."""
    monkeypatch.setattr(B, "MIN_BATCH", 2)


@pytest.mark.parametrize("env_id", [CIRCLE, LINE])
def test_batched_run_writes_the_results_of_single_episodes(tmp_path, env_id, small_batches):
    """results.json episode fields are equal with batch_size 64 and 1, for five controllers (nnbc chaotic)."""
    kw = {
        "envs": (env_id,),
        "policies": SPECS,
        "episodes": 3,
        "obs_noise": 0.001,
        "env_kwargs": {"path": dict(TASKS[env_id], duration=1.0)},
    }
    batched = run(_config(tmp_path, "batched", **kw))
    single = run(_config(tmp_path, "single", batch_size=1, **kw))
    on_disk = [json.loads((tmp_path / d / "results.json").read_text()) for d in ("batched", "single")]
    assert _fields(on_disk[0]) == _fields(on_disk[1])
    assert all(r["status"] == "ok" for r in batched.episodes)
    assert _drop_timing(on_disk[0]["aggregate"]) == _drop_timing(on_disk[1]["aggregate"])
    for spec in SPECS:  # a batch's episodes share its wall time / N: the batched path really ran
        walls = {r["wall_s"] for r in batched.episodes if r["policy"] == spec}
        assert len(walls) == 1, (spec, walls)
    assert len({r["wall_s"] for r in single.episodes}) > 1


def test_a_batch_of_several_controllers_equals_single_episodes(small_batches):
    """Episodes of several controllers share one vector env (one group, a StackedPolicy over their rows), and
    every record equals the one-at-a-time path's; a controller's predict_us is its own part's time."""
    from policies.stacked import StackedPolicy

    specs = ("clik", "nnbc", "nnbc-plus", "qp-oracle")
    runs = [(spec, k) for spec in specs for k in range(3)]
    tasks = [Task(i, CIRCLE, "kinematic", spec, k, 10_000 + k, 0.05, 0.001) for i, (spec, k) in enumerate(runs)]
    env_kwargs = {"path": dict(TASKS[CIRCLE], duration=1.0)}
    cfg = EvalConfig(env_kwargs=env_kwargs, save_arrays="none", plots=False)
    units = plan_units(cfg, {}, tasks)
    assert [len(u) for u in units] == [12]  # one batch: every controller's rows
    runner = B.UnitRunner(cfg, {})
    try:
        policy = runner._policy(runner._vector_env(B.batch_key(cfg, {}, tasks[0]), tasks[0], 12), units[0])
        assert isinstance(policy, StackedPolicy)
        assert [sl for _, sl in policy.parts] == [slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)]
    finally:
        runner.close()
    out = {}
    for name, batch_size in (("single", 1), ("batched", 64)):
        config = EvalConfig(env_kwargs=env_kwargs, save_arrays="none", plots=False, batch_size=batch_size)
        records, _ = execute(config, {}, tasks)
        out[name] = [records[i] for i in range(len(tasks))]
    assert _fields({"episodes": out["batched"]}) == _fields({"episodes": out["single"]})
    assert len({r["wall_s"] for r in out["batched"]}) == 1  # one batch
    us = {spec: {r["predict_us_median"] for r in out["batched"] if r["policy"] == spec} for spec in specs}
    assert us["nnbc-plus"] != us["clik"]  # each part timed on its own


def test_plan_units_batches_kinematic_builtin_and_agent_specs_only(monkeypatch):
    tasks = []
    for dyn in ("kinematic", "physics"):
        for pol in ("nnbc", "sb3:sac-circle", "mine", "test_eval_helpers:SlowMarked"):
            for k in range(9):
                tasks.append(Task(len(tasks), CIRCLE, dyn, pol, k, 10_000 + k, None, None))
    user = {"mine": object()}
    units = plan_units(EvalConfig(batch_size=5), user, tasks)
    # kinematic nnbc and sb3: the fewest batches of at most batch_size, balanced, in order; the rest single
    assert [[t.index for t in u] for u in units[:4]] == [
        [0, 1, 2, 3],
        [4, 5, 6, 7, 8],
        [9, 10, 11, 12],
        [13, 14, 15, 16, 17],
    ]
    assert all(len(u) == 1 for u in units[4:]) and len(units) == 4 + 54
    assert sorted(t.index for u in units for t in u) == list(range(72))
    # two workers: the 18 batchable episodes are cut so that both get a batch of each group
    assert [len(u) for u in plan_units(EvalConfig(batch_size=64, workers=2), user, tasks)[:2]] == [9, 9]
    assert all(len(u) == 1 for u in plan_units(EvalConfig(batch_size=1), user, tasks))
    # below the speed floor (4 episodes) a group runs as single episodes
    assert [len(u) for u in plan_units(EvalConfig(batch_size=64), user, tasks[:3])] == [1, 1, 1]
    assert [len(u) for u in plan_units(EvalConfig(batch_size=64), user, tasks[:4])] == [4]
    monkeypatch.setattr(B, "MIN_BATCH", 2)
    assert [len(u) for u in plan_units(EvalConfig(batch_size=64), user, tasks[:3])] == [3]


def test_a_batch_of_any_seeds_equals_single_episodes(small_batches):
    """Non-consecutive seeds in any order (a sweep's seed list) batch bit-identically, through every backend
    entry and with workers=2 dealing batches."""
    seeds = [10_007, 10_000, 10_003, 12_345]
    tasks = [Task(i, CIRCLE, "kinematic", "nnbc", i, s, 0.05, 0.001) for i, s in enumerate(seeds)]
    env_kwargs = {"path": dict(TASKS[CIRCLE], duration=1.0)}
    out = {}
    for name, kw in {"single": {"batch_size": 1}, "batched": {}, "two": {"workers": 2}}.items():
        cfg = EvalConfig(env_kwargs=env_kwargs, save_arrays="none", plots=False, **kw)
        records, _ = execute(cfg, {}, tasks)
        out[name] = [{k: v for k, v in records[i].items() if k not in TIMING} for i in range(len(tasks))]
        if name != "single":
            assert len({records[i]["wall_s"] for i in range(len(tasks))}) < len(tasks)  # batched
    assert out["batched"] == out["single"] == out["two"]
    assert [r["seed"] for r in out["batched"]] == seeds and [r["episode"] for r in out["batched"]] == [0, 1, 2, 3]


class _FailsOnSeed:
    """Wraps a policy (single or batched); `predict` raises at step 30 of the episode of seed BAD."""

    BAD = 10_002

    def __init__(self, inner):
        self.inner = inner
        self.armed = False
        self.k = 0
        self.knowledge = policies.knowledge_of(inner)  # the wrapped controller's class, as its records say

    def reset(self, obs, info=None, *, seed=None):
        self.armed = policy_seed(self.BAD) in (seed if isinstance(seed, list) else [seed])  # batched: a list
        self.k = 0
        self.inner.reset(obs, info, seed=seed)

    def predict(self, obs, state=None, episode_start=None, deterministic=True):
        self.k += 1
        if self.armed and self.k == 30:
            raise RuntimeError(f"planted failure on seed {self.BAD}")
        return self.inner.predict(obs, state, episode_start, deterministic)


def test_a_failing_batch_is_rerun_one_by_one(tmp_path, monkeypatch):
    batches = []

    def wrapped(make):
        def make_policy(spec, env, seed):
            return _FailsOnSeed(make(spec, env, seed))

        return make_policy

    real_batch = B.rollout_batch

    def counting(venv, policy, seeds, **kw):
        batches.append(list(seeds))
        return real_batch(venv, policy, seeds, **kw)

    monkeypatch.setattr(T, "make_policy", wrapped(T.make_policy))
    monkeypatch.setattr(B, "make_policy", wrapped(B.make_policy))
    monkeypatch.setattr(B, "rollout_batch", counting)
    result = run(_config(tmp_path, "failing"))
    assert batches == [[10_000, 10_001, 10_002, 10_003]]  # one batch ran, failed, and was re-run singly
    status = {r["seed"]: r["status"] for r in result.episodes}
    assert status == {10_000: "ok", 10_001: "ok", 10_002: "failed", 10_003: "ok"}
    bad = next(r for r in result.episodes if r["status"] == "failed")
    assert "planted failure on seed 10002" in bad["error"] and bad["n_steps"] == 29
    monkeypatch.undo()
    clean = run(_config(tmp_path, "clean", batch_size=1))
    ok = [r for r in _fields(result.results) if r["status"] == "ok"]
    assert ok == [r for r in _fields(clean.results) if r["seed"] != 10_002]


def test_ctrl_c_keeps_the_finished_batches(tmp_path, monkeypatch, small_batches):
    real_batch = B.rollout_batch
    calls = []

    def interrupted_second(venv, policy, seeds, **kw):
        calls.append(list(seeds))
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real_batch(venv, policy, seeds, **kw)

    monkeypatch.setattr(B, "rollout_batch", interrupted_second)
    cfg = _config(tmp_path, "stopped", policies=("clik", "jmpi"), batch_size=3)
    with pytest.raises(RunInterrupted):
        run(cfg)
    results = json.loads((tmp_path / "stopped" / "results.json").read_text())
    status = [(r["policy"], r["seed"], r["status"]) for r in results["episodes"]]
    # one group of 8 episodes (both controllers), at most 3 a batch: clik 10000-1; clik 10002-3 with jmpi
    # 10000 (stopped); jmpi 10001-3
    assert calls == [[10_000, 10_001], [10_002, 10_003, 10_000]]
    assert [s for s in status if s[2] == "ok"] == [("clik", 10_000, "ok"), ("clik", 10_001, "ok")]
    stopped = [("clik", 10_002), ("clik", 10_003)] + [("jmpi", 10_000 + k) for k in range(4)]
    assert [s for s in status if s[2] != "ok"] == [(*p, "interrupted") for p in stopped]
    assert [(a["policy"], a["n"]) for a in results["aggregate"]] == [("clik", 2)]


def test_an_env_without_a_native_vector_env_runs_one_episode_at_a_time(small_batches):
    """An id registered without mobman's vector entry point (here a user's registration of the env class): found
    out once per condition, then its episodes run singly."""
    env_id = "MyWheeledPuma-v0"
    if env_id not in gym.registry:
        gym.register(env_id, entry_point="mobman_env.env:WheeledPumaEnv")
    cfg = EvalConfig(envs=(env_id,), env_kwargs={"path": dict(TASKS[CIRCLE], duration=0.2)}, save_arrays="none")
    tasks = [Task(i, env_id, "kinematic", "zero", i, 10_000 + i, None, None) for i in range(4)]
    runner = B.UnitRunner(cfg, {})
    try:
        (unit,) = plan_units(cfg, {}, tasks)
        done = list(runner.run(unit))
    finally:
        runner.close()
    assert runner._unbatchable == {(env_id, "kinematic", None, None, "")}
    assert [(t.seed, rec["status"]) for t, rec, _ in done] == [(10_000 + i, "ok") for i in range(4)]


def test_random_arms_batch(small_batches):
    """robot="random" has a native vector env (each robot its own arm): its episodes batch, with the records of
    the single path."""
    env_id = "WheeledRandomArm-Circle-v0"
    cfg = EvalConfig(envs=(env_id,), env_kwargs={"path": dict(TASKS[CIRCLE], duration=0.2)}, save_arrays="none")
    tasks = [Task(i, env_id, "kinematic", "clik", i, 10_000 + i, None, None) for i in range(4)]
    runner = B.UnitRunner(cfg, {})
    try:
        (unit,) = plan_units(cfg, {}, tasks)
        batched = [rec for _, rec, _ in runner.run(unit)]
        single = [runner.single.run(t)[0] for t in tasks]
    finally:
        runner.close()
    assert runner._unbatchable == set()
    for b, s in zip(batched, single):
        assert b["status"] == s["status"] == "ok"
        assert b["max_error_m"] == s["max_error_m"] and b["true_params_hash"] == s["true_params_hash"]


@pytest.mark.parametrize("command", [["run"], ["paper", "--dynamics", "kinematic"]])
def test_a_bad_batch_size_is_refused_before_any_rollout(tmp_path, capsys, command):
    from eval.cli import main

    assert main([*command, "--batch-size", "0", "--out", str(tmp_path / "x"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "batch_size" in err and "0" in err and "--batch-size 64" in err, err
    assert not (tmp_path / "x").exists()


def test_sb3_agent_batches_with_the_single_paths_records():
    """A PPO agent (`sb3:ppo-circle`, acting through `policies.agents.sb3_actor`) runs as one batch of rows with the
    same records as one episode at a time, its knowledge class and artefacts included."""
    tasks = [Task(k, CIRCLE, "kinematic", "sb3:ppo-circle", k, 10_000 + k, None, None) for k in range(5)]
    out = {}
    for name, batch_size in (("single", 1), ("batched", 64)):
        config = EvalConfig(save_arrays="none", plots=False, batch_size=batch_size)
        records, _ = execute(config, {}, tasks)
        out[name] = [records[i] for i in range(len(tasks))]
    assert _fields({"episodes": out["batched"]}) == _fields({"episodes": out["single"]})
    assert len({r["wall_s"] for r in out["batched"]}) == 1  # one batch
    assert {r["knowledge"] for r in out["batched"]} == {"none"}
    assert out["batched"][0]["artefacts"] == out["single"][0]["artefacts"]

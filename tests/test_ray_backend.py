"""The Ray backend: same records as the local backend, task retries, picklability and install errors.

One local Ray instance (2 CPUs) serves the whole module; episodes are short kinematic circles (1 s = 100 steps).
"""

from __future__ import annotations

import json
import logging
import os
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from test_eval_helpers import ENV, SHORT, CrashOnOddSeed, HoldStill, episode_seed, short_config, stable

from eval import EvalConfig, EvalError, run
from eval.cli import main

#: reported seeds of this module (DESIGN "Seeds")
SEED = 10_000


@pytest.fixture(scope="module")
def ray_cluster():
    """A local Ray instance with 2 CPUs for the module; the runs use it as it is (and leave it running)."""
    import ray

    from eval.execution.ray_backend import local_runtime_env

    ray.init(
        address="local",
        num_cpus=2,
        include_dashboard=False,
        log_to_driver=False,
        logging_level=logging.ERROR,
        object_store_memory=100 * 2**20,
        runtime_env=local_runtime_env(),
    )  # tests/ importable in workers
    yield ray
    ray.shutdown()


def _config(tmp_path, name="out", **kw) -> EvalConfig:
    return short_config(tmp_path, name, **{"policies": ("zero", "nnbc"), **kw})


class ExitOnOddSeed(HoldStill):
    """Kills its worker process when an odd-seed episode starts, in at most `max_exits` attempts of it (None:
    every attempt); each exit is logged as a line of `log_dir/attempts-<seed>`."""

    def __init__(self, log_dir: str, max_exits: int | None = None):
        super().__init__()
        self.log_dir = log_dir
        self.max_exits = max_exits

    def reset(self, obs, info=None, *, seed=None):
        super().reset(obs, info, seed=seed)
        seed = episode_seed(seed)
        if seed % 2 == 0:
            return
        log = Path(self.log_dir) / f"attempts-{seed}"
        if self.max_exits is not None and log.exists() and len(log.read_text().split()) >= self.max_exits:
            return
        with open(log, "a") as f:
            f.write(f"{os.getpid()}\n")
        os._exit(3)


def _fail_to_unpickle(log_dir: str):
    with open(Path(log_dir) / "unpickle-attempts", "a") as f:
        f.write(f"{os.getpid()}\n")
    raise ImportError("deliberate: this policy's module is missing on the worker")


class UnpicklesBadly(HoldStill):
    """Pickles fine here; unpickling it (in the Ray task, outside the episode) raises."""

    def __init__(self, log_dir: str):
        super().__init__()
        self.log_dir = log_dir

    def __reduce__(self):
        return _fail_to_unpickle, (self.log_dir,)


class HoldsALock(HoldStill):
    def __init__(self):
        super().__init__()
        self.lock = threading.Lock()  # cannot be pickled


# --- same results as the local backend --------------------------------------------------------------------


def test_ray_backend_equals_local_backend(tmp_path, ray_cluster):
    """Spec policies, a user object and an in-episode crash: the records and arrays equal the local ones."""
    local = run(_config(tmp_path, "local", save_arrays="all"), policies={"crash": CrashOnOddSeed()})
    out = tmp_path / "ray"
    rc = main(
        [
            "run",
            "--env",
            ENV,
            "--dynamics",
            "kinematic",
            "--env-kwargs",
            json.dumps(SHORT),
            "--seed",
            str(SEED),
            "--seeds",
            "2",
            "--policy",
            "zero",
            "--policy",
            "nnbc",
            "--policy",
            "test_eval_helpers:CrashOnOddSeed",
            "--out",
            str(out),
            "--quiet",
            "--no-plots",
            "--save-arrays",
            "all",
            "--backend",
            "ray",
        ]
    )
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    assert res["config"]["backend"] == "ray"
    recs = res["episodes"]
    local_recs = json.loads((tmp_path / "local" / "results.json").read_text())["episodes"]
    rename = {"crash": "test_eval_helpers:CrashOnOddSeed"}
    for a, b in zip(local_recs, recs):
        a = {**stable(a), "policy": rename.get(a["policy"], a["policy"])}
        b = stable(b)
        if a["error"]:  # the in-episode crash: the same exception, raised from the same line
            assert b["error"].splitlines()[-3:] == a["error"].splitlines()[-3:]
            a["error"] = b["error"] = None
        assert a == b
    assert [r["status"] for r in recs] == ["ok"] * 4 + ["ok", "failed"]  # the crash is a result, not a retry
    assert "deliberate crash at step 5" in recs[-1]["error"]
    assert os.getpid() not in {r["pid"] for r in recs} and None not in {r["pid"] for r in recs}

    z = np.load(out / "episodes.npz")
    for rec in local.episodes:
        for name in ("r_d", "r_a", "p_c", "error", "action"):
            np.testing.assert_array_equal(
                np.asarray(local.arrays[rec["index"]][name], np.float32), z[f"{rec['arrays_key']}__{name}"]
            )


# --- failed tasks -------------------------------------------------------------------------------------------


def test_a_dead_worker_is_retried_once_then_recorded_failed(tmp_path, ray_cluster):
    once_log, log = tmp_path / "once", tmp_path / "always"
    once_log.mkdir()
    log.mkdir()
    result = run(
        _config(tmp_path, policies=("zero",), backend="ray"),
        policies={"once": ExitOnOddSeed(str(once_log), max_exits=1), "always": ExitOnOddSeed(str(log))},
    )
    status = {(r["policy"], r["seed"]): r["status"] for r in result.episodes}
    assert status == {
        ("zero", SEED): "ok",
        ("zero", SEED + 1): "ok",
        ("once", SEED): "ok",
        ("once", SEED + 1): "ok",  # its worker died once; the retry ran it to the end
        ("always", SEED): "ok",
        ("always", SEED + 1): "failed",
    }
    assert len((once_log / f"attempts-{SEED + 1}").read_text().split()) == 1  # it exited once, then ran
    assert len((log / f"attempts-{SEED + 1}").read_text().split()) == 2  # the first attempt and one retry
    dead = next(r for r in result.episodes if r["status"] == "failed")
    assert "retry failed too" in dead["error"] and "WorkerCrashedError" in dead["error"]
    assert dead["pid"] is None and dead["max_error_m"] is None and dead["success"] is False
    once = [r for r in result.episodes if r["policy"] == "once"]
    zero = [r for r in result.episodes if r["policy"] == "zero"]
    same = {"policy": "", "index": 0, "arrays_key": None, "knowledge": None}  # a user's class: 'unknown'
    assert [stable(r) | same for r in once] == [stable(r) | same for r in zero]
    agg = {a["policy"]: a for a in result.aggregate}
    assert agg["always"]["n_failed"] == 1 and agg["once"]["n_failed"] == 0


def test_a_task_that_raises_outside_the_episode_is_retried_once_then_recorded_failed(tmp_path, ray_cluster):
    result = run(
        _config(tmp_path, policies=(), episodes=1, backend="ray"), policies={"bad": UnpicklesBadly(str(tmp_path))}
    )
    (rec,) = result.episodes
    assert rec["status"] == "failed" and rec["pid"] is None
    assert "retry failed too" in rec["error"] and "deliberate: this policy's module is missing" in rec["error"]
    assert "\x1b[" not in rec["error"]  # no terminal colour codes in the record
    assert len((tmp_path / "unpickle-attempts").read_text().split()) == 2


# --- errors before any rollout --------------------------------------------------------------------------------


def test_an_unpicklable_policy_object_is_refused_naming_it(tmp_path):
    spy = HoldStill()
    with pytest.raises(EvalError, match="cannot be sent to Ray workers") as exc:
        run(_config(tmp_path, policies=("zero",), backend="ray"), policies={"spy": spy, "locked": HoldsALock()})
    assert "'locked' (HoldsALock)" in str(exc.value) and "picklable" in str(exc.value)
    assert "'spy'" not in str(exc.value)
    assert spy.n_reset == 0 and not (tmp_path / "out").exists()


def test_without_ray_the_ray_backend_says_how_to_install_it(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` now raises ImportError
    out = tmp_path / "noray"
    rc = main(
        [
            "run",
            "--env",
            ENV,
            "--dynamics",
            "kinematic",
            "--policy",
            "zero",
            "--out",
            str(out),
            "--quiet",
            "--backend",
            "ray",
        ]
    )
    assert rc == 2
    assert 'pip install "mobman[cluster]"' in capsys.readouterr().err
    assert not out.exists()
    spy = HoldStill()
    with pytest.raises(EvalError, match=r'pip install "mobman\[cluster\]"'):
        run(_config(tmp_path, policies=(), backend="ray"), policies={"spy": spy})
    assert spy.n_reset == 0 and spy.n_predict == 0
    sweep_yaml = tmp_path / "sweep.yaml"
    sweep_yaml.write_text("policies: [zero]\ndynamics: kinematic\n")
    assert (
        main(["sweep", "--config", str(sweep_yaml), "--out", str(tmp_path / "sweep"), "--quiet", "--backend", "ray"])
        == 2
    )
    assert 'pip install "mobman[cluster]"' in capsys.readouterr().err
    assert not (tmp_path / "sweep").exists()
    assert (
        main(
            [
                "run",
                "--env",
                ENV,
                "--dynamics",
                "kinematic",
                "--policy",
                "zero",
                "--seeds",
                "1",
                "--env-kwargs",
                json.dumps(SHORT),
                "--out",
                str(tmp_path / "local"),
                "--quiet",
                "--no-plots",
            ]
        )
        == 0
    )  # no Ray needed


@pytest.mark.parametrize(
    "extra, needle",
    [
        (["--address", "auto"], "--address 'auto' needs --backend ray"),
        (["--backend", "ray", "--address", "auto", "--workers", "2"], "drop --workers"),
    ],
)
def test_backend_arguments_that_do_not_fit_together(tmp_path, capsys, extra, needle):
    out = tmp_path / "bad"
    assert (
        main(["run", "--env", ENV, "--dynamics", "kinematic", "--policy", "zero", "--out", str(out), "--quiet", *extra])
        == 2
    )
    assert needle in capsys.readouterr().err
    assert not out.exists()


# --- sweeps -------------------------------------------------------------------------------------------------


def test_a_sweep_started_locally_and_finished_on_ray_equals_a_local_one(tmp_path, ray_cluster):
    from eval.sweep.config import SweepConfig
    from eval.sweep.run import run_sweep

    sweep = SweepConfig.from_dict(
        {
            "envs": [ENV],
            "policies": ["zero", "nnbc"],
            "seeds": [SEED, SEED + 1],
            "dynamics": ["kinematic"],
            "model_error": [0.0, 0.1],
            "env_kwargs": SHORT,
        }
    )
    whole = run_sweep(sweep, tmp_path / "local", progress=False, plots=False)
    run_sweep(sweep, tmp_path / "mixed", max_episodes=3, progress=False, plots=False)
    resumed = run_sweep(sweep, tmp_path / "mixed", backend="ray", progress=False, plots=False)
    assert (resumed.n_run, resumed.n_skipped, resumed.n_left) == (5, 3, 0)
    assert [stable(r) for r in resumed.episodes] == [stable(r) for r in whole.episodes]
    assert os.getpid() not in {r["pid"] for r in resumed.episodes[3:]}


def test_a_bench_on_ray_equals_a_local_one(tmp_path, ray_cluster):
    from eval.bench.config import BenchConfig
    from eval.bench.run import run_bench

    cfg = BenchConfig(
        tasks=("circle",), conditions=("default", "wear20"), policies=("zero", "jmpi"), seeds=2, env_kwargs=SHORT
    )
    local = run_bench(cfg, tmp_path / "local", progress=False, plots=False)
    on_ray = run_bench(cfg, tmp_path / "ray", backend="ray", progress=False, plots=False)
    a, b = (json.loads((tmp_path / d / "results.json").read_text()) for d in ("local", "ray"))
    assert [stable(r) for r in b["episodes"]] == [stable(r) for r in a["episodes"]]
    assert {r["condition"] for r in a["episodes"]} == {"default", "wear20"}
    n = len(a["episodes"])
    assert os.getpid() not in {r["pid"] for r in b["episodes"]}  # they ran in Ray workers
    assert on_ray.n_run == local.n_run == n >= 8  # 2 policies x 2 conditions x 2 seeds, and the references'
    assert [r["max_error_m"] for r in on_ray.scorecard["pooled"]] == [
        r["max_error_m"] for r in local.scorecard["pooled"]
    ]

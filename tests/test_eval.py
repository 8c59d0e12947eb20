"""mobman-eval run: in-process CLI runs, the results.json schema, identical tasks, workers, user policies, errors.

All runs are kinematic and short (a 1 s circle of radius 0.1 m = 100 steps) so the file stays fast.
"""

from __future__ import annotations

import csv
import json
import os

import numpy as np
import pytest
from matplotlib.figure import Figure
from test_eval_helpers import ENV, SHORT, CrashOnOddSeed, HoldStill, ProportionalBatched, short_config, stable

from eval import EvalConfig, EvalError, run
from eval.cli import main

SHORT_JSON = json.dumps(SHORT)
#: reported seeds of this module (DESIGN "Seeds")
SEED = 10_000

EPISODE_KEYS = {
    "env",
    "policy",
    "seed",
    "dynamics",
    "model_error",
    "obs_noise",
    "control_freq",
    "path",
    "true_params_hash",
    "status",
    "error",
    "max_error_m",
    "rms_error_m",
    "final_error_m",
    "steady_max_error_m",
    "steady_rms_error_m",
    "axis_max_error_m",
    "effort",
    "peak_joint_speed",
    "peak_wheel_speed",
    "joint_limit_hits",
    "n_clipped",
    "tipped_over",
    "success",
    "predict_us_median",
    "predict_us_p99",
    "wall_s",
    "pid",
}
AGGREGATE_KEYS = {
    "env",
    "policy",
    "dynamics",
    "model_error",
    "obs_noise",
    "n",
    "n_failed",
    "success_rate",
    "success_rate_ci95",
    "success_curve",
    "max_error_m",
    "rms_error_m",
    "final_error_m",
    "effort",
}


def _config(tmp_path, name="out", **kw) -> EvalConfig:
    return short_config(tmp_path, name, **{"policies": ("zero", "random"), **kw})


def _run_args(out, *extra):
    return [
        "run",
        "--env",
        ENV,
        "--dynamics",
        "kinematic",
        "--env-kwargs",
        SHORT_JSON,
        "--seed",
        str(SEED),
        "--out",
        str(out),
        "--quiet",
        *extra,
    ]


# --- the CLI end to end -----------------------------------------------------------------------------------


def test_main_run_writes_every_output_with_schema_4(tmp_path):
    out = tmp_path / "run"
    rc = main(_run_args(out, "--policy", "zero", "--policy", "random", "--seeds", "2"))
    assert rc == 0
    for name in ("results.json", "results.csv", "summary.md", "config.json", "episodes.npz"):
        assert (out / name).is_file(), name
    pngs = sorted(p.name for p in (out / "plots").glob("*.png"))
    assert pngs == [f"{ENV}_kinematic_{k}.png" for k in ("axis_errors", "error_norm", "paths3d")]
    assert not [p for p in out.rglob("*.tmp")]  # no temporary file left behind

    res = json.loads((out / "results.json").read_text())
    assert res["schema"] == 4 and {r["condition"] for r in res["episodes"]} == {
        'kinematic, model_error=0.05, obs_noise=0, path={"duration":1.0,"radius":0.1,"type":"circle"}'
    }
    # a 0.1 m circle in 1 s asks for speeds near the limits: the flag is each episode's own (peaks 0.86, 1.05)
    assert [r["feasible"] for r in res["episodes"] if r["policy"] == "zero"] == [True, False]
    assert all(r["feasible"] == (r["feasibility_peak"] <= 0.9) for r in res["episodes"])
    assert {"config", "versions", "git", "provenance", "statistics", "episodes", "aggregate"} <= set(res)
    prov = res["provenance"]
    assert prov["cpu"] and prov["numpy"] == np.__version__ and "OPENBLAS_CORETYPE" in prov["env"]
    assert prov["blas"] and {"internal_api", "version", "architecture", "num_threads"} <= set(prov["blas"][0])
    assert res["statistics"]["settle_time_s"] == 0.5 and len(res["statistics"]["success_curve_tolerances_m"]) == 31
    assert res["versions"]["gymnasium"] and res["versions"]["pybullet"] and isinstance(res["git"], str)
    assert len(res["episodes"]) == 4
    for rec in res["episodes"]:
        assert set(rec) >= EPISODE_KEYS, EPISODE_KEYS - set(rec)
        assert rec["status"] == "ok" and rec["error"] is None
        assert rec["dynamics"] == "kinematic" and rec["control_freq"] == 100.0
        assert rec["path"]["type"] == "circle" and rec["path"]["radius"] == 0.1
        assert len(rec["axis_max_error_m"]) == 3
        assert rec["pid"] == os.getpid()  # workers=1 runs in this process
    assert [r["seed"] for r in res["episodes"]] == [SEED, SEED + 1, SEED, SEED + 1]
    assert [(a["policy"], a["n"]) for a in res["aggregate"]] == [("zero", 2), ("random", 2)]
    for agg in res["aggregate"]:
        assert set(agg) >= AGGREGATE_KEYS
        assert set(agg["max_error_m"]) >= {"median", "mean", "std", "iqm", "iqm_ci95"}
        assert len(agg["success_rate_ci95"]) == 2 and len(agg["success_curve"]) == 31
        assert agg["steady_max_error_m"]["iqm"] is not None and agg["steady_rms_error_m"]["iqm_ci95"] is not None

    # the zero policy leaves the end-effector where it starts: its error is |r_d(t) - r_d(0)|, the whole path
    zero = res["episodes"][0]
    assert zero["effort"] == 0.0 and zero["peak_joint_speed"] == 0.0
    assert zero["max_error_m"] == pytest.approx(0.2, abs=1e-6)  # the circle's diameter, 2 x 0.1 m
    assert zero["success"] is False

    rows = list(csv.DictReader((out / "results.csv").open()))
    assert len(rows) == 4 and float(rows[0]["max_error_m"]) == pytest.approx(zero["max_error_m"])
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["policies"] == ["zero", "random"] and cfg["env_kwargs"] == SHORT and cfg["out"] == str(out)
    summary = (out / "summary.md").read_text()
    assert "| zero |" in summary and "200.00" in summary  # mm

    # the per-step arrays reproduce the recorded metrics
    z = np.load(out / "episodes.npz")
    key = zero["arrays_key"]
    assert z[f"{key}__error"].shape == (101,) and z[f"{key}__action"].shape == (100, 8)
    assert float(z[f"{key}__error"].max()) == pytest.approx(zero["max_error_m"], rel=1e-6)


def test_identical_tasks_across_policies(tmp_path):
    result = run(_config(tmp_path, policies=("zero", "random", "nnbc"), episodes=2, save_arrays="all"))
    by_k: dict[int, list[dict]] = {}
    for rec in result.episodes:
        assert rec["status"] == "ok", rec["error"]
        by_k.setdefault(rec["episode"], []).append(rec)
    assert sorted(by_k) == [0, 1]
    hashes = []
    for recs in by_k.values():
        assert len(recs) == 3
        assert len({r["true_params_hash"] for r in recs}) == 1
        assert len({json.dumps(r["start"]) for r in recs}) == 1
        first = result.arrays[recs[0]["index"]]["r_d"]
        for r in recs[1:]:
            np.testing.assert_array_equal(result.arrays[r["index"]]["r_d"], first)  # target_pos sequences
        hashes.append(recs[0]["true_params_hash"])
    assert hashes[0] != hashes[1]  # episode k draws its own robot (seed S + k)


def test_workers_2_equal_workers_1_and_use_2_processes(tmp_path):
    one = run(_config(tmp_path, "w1", workers=1, save_arrays="all"))
    two = run(_config(tmp_path, "w2", workers=2, save_arrays="all"))
    assert [stable(r) for r in one.episodes] == [stable(r) for r in two.episodes]
    pids = {r["pid"] for r in two.episodes}
    assert len(pids) == 2 and os.getpid() not in pids
    for rec in one.episodes:
        a, b = one.arrays[rec["index"]], two.arrays[rec["index"]]
        for name in ("r_d", "r_a", "p_c", "error", "action"):
            np.testing.assert_array_equal(a[name], b[name])
    assert [stable(a) for a in one.aggregate] != [] and one.aggregate[0]["max_error_m"] == two.aggregate[0][
        "max_error_m"
    ]


def test_user_policy_through_module_attr_matches_zero(tmp_path):
    out = tmp_path / "user"
    rc = main(
        _run_args(out, "--policy", "test_eval_helpers:HoldStill", "--policy", "zero", "--seeds", "1", "--no-plots")
    )
    assert rc == 0
    recs = json.loads((out / "results.json").read_text())["episodes"]
    assert [r["policy"] for r in recs] == ["test_eval_helpers:HoldStill", "zero"]
    assert recs[0]["status"] == "ok"
    # the user's class declares no knowledge class; the rest of the records is the zero policy's
    assert (recs[0]["knowledge"], recs[1]["knowledge"]) == ("unknown", "none")
    same = {"policy": "", "index": 0, "arrays_key": None, "knowledge": None}
    assert stable(recs[0]) | same == stable(recs[1]) | same


def test_user_policy_objects_through_run(tmp_path):
    mine = HoldStill()
    result = run(
        _config(tmp_path, policies=("zero",), episodes=2), policies={"mine": mine, "batched": ProportionalBatched()}
    )
    names = [r["policy"] for r in result.episodes]
    assert names == ["zero", "zero", "mine", "mine", "batched", "batched"]
    assert all(r["status"] == "ok" for r in result.episodes)
    assert mine.n_reset == 2 and mine.n_predict == 200  # reset once per episode, predict once per step
    batched = [r for r in result.episodes if r["policy"] == "batched"]
    assert batched[0]["peak_wheel_speed"] > 0.0  # its (1, 8) actions reached the env
    cfg = json.loads((tmp_path / "out" / "config.json").read_text())
    assert cfg["policy_objects"] == {"mine": "HoldStill", "batched": "ProportionalBatched"}


@pytest.mark.parametrize("workers", [1, 2])
def test_a_crashing_policy_is_recorded_and_the_others_finish(tmp_path, workers):
    result = run(
        _config(tmp_path, policies=("zero",), episodes=2, workers=workers), policies={"crash": CrashOnOddSeed()}
    )
    crash = [r for r in result.episodes if r["policy"] == "crash"]
    assert [r["status"] for r in crash] == ["ok", "failed"]  # seeds S (even) and S + 1 (odd)
    failed = crash[1]
    assert "RuntimeError: deliberate crash at step 5" in failed["error"] and "Traceback" in failed["error"]
    assert failed["success"] is False and failed["max_error_m"] is None and failed["n_steps"] == 4
    assert all(r["status"] == "ok" for r in result.episodes if r["policy"] == "zero")
    agg = {a["policy"]: a for a in result.aggregate}
    assert agg["crash"]["n"] == 2 and agg["crash"]["n_failed"] == 1
    assert "Failed episodes" in (tmp_path / "out" / "summary.md").read_text()


# --- errors before any rollout ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "extra, needles",
    [
        (["--env", "NoSuch-v0", "--policy", "zero"], ["unknown env id 'NoSuch-v0'", "WheeledPuma-Circle-v0"]),
        (["--policy", "nbc"], ["unknown policy", "nnbc", "jmpi", "sb3:PATH"]),
        (["--policy", "sb3:/no/such/dir/model.zip"], ["not found", "/no/such/dir/model.zip"]),
        (["--policy", "zero", "--env-kwargs", '{"dynamics": "physics"}'], ["--dynamics"]),
        (
            ["--policy", "zero", "--env-kwargs", '{"path": {"type": "spiral"}}'],
            ["unknown path type 'spiral'", "circle"],
        ),
        (["--policy", "zero", "--seeds", "0"], ["episodes must be an integer >= 1"]),
    ],
)
def test_bad_arguments_stop_before_any_rollout(tmp_path, capsys, extra, needles):
    out = tmp_path / "bad"
    argv = ["run", "--dynamics", "kinematic", "--out", str(out), "--quiet", *extra]
    if "--env" not in extra:
        argv += ["--env", ENV]
    assert main(argv) == 2
    err = capsys.readouterr().err
    for needle in needles:
        assert needle in err, (needle, err)
    assert not out.exists()  # nothing was run, nothing written


def test_malformed_env_kwargs_json_is_an_argparse_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--env-kwargs", "{not json", "--out", str(tmp_path / "x")])
    assert exc.value.code == 2
    assert "--env-kwargs must be a JSON object" in capsys.readouterr().err


def test_errors_come_before_the_first_predict(tmp_path):
    spy = HoldStill()
    with pytest.raises(EvalError, match="unknown policy"):
        run(_config(tmp_path, policies=("zero", "no-such-policy")), policies={"spy": spy})
    assert spy.n_predict == 0 and spy.n_reset == 0
    with pytest.raises(EvalError, match="no predict"):
        run(_config(tmp_path, policies=()), policies={"bad": object()})


def test_existing_out_is_refused_unless_overwrite(tmp_path, capsys):
    out = tmp_path / "taken"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert main(_run_args(out, "--policy", "zero", "--seeds", "1", "--no-plots")) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]
    assert main(_run_args(out, "--policy", "zero", "--seeds", "1", "--no-plots", "--overwrite")) == 0
    assert (out / "notes.txt").read_text() == "keep me"  # other files are kept
    assert (out / "results.json").is_file()


def test_atomic_write_keeps_the_old_file_when_the_write_fails(tmp_path, monkeypatch):
    from eval.output import files as report

    target = tmp_path / "results.json"
    report.atomic_write_json(target, {"a": 1})

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(report.os, "replace", boom)
    with pytest.raises(EvalError, match=r"cannot write .*results.json \(disk full\); fix that and run again"):
        report.atomic_write_json(target, {"a": 2})  # an EvalError: the CLIs exit 2 naming the file
    assert json.loads(target.read_text()) == {"a": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["results.json"]


def test_to_jsonable_turns_nan_and_numpy_into_plain_json():
    from eval.output.files import to_jsonable

    data = to_jsonable(
        {"x": np.float32(1.5), "n": np.int64(3), "bad": float("nan"), "v": np.arange(2), "t": (True, np.bool_(False))}
    )
    assert data == {"x": 1.5, "n": 3, "bad": None, "v": [0, 1], "t": [True, False]}
    json.dumps(data, allow_nan=False)


# --- plots and video ---------------------------------------------------------------------------------------


def test_plot_functions_take_records_and_return_figures(tmp_path):
    from eval.output import plots

    result = run(_config(tmp_path, policies=("zero", "nnbc"), episodes=1))
    records = [{**r, **result.arrays[r["index"]]} for r in result.episodes]
    fig = plots.plot_paths_3d(records)
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    assert len(fig.axes[0].lines) >= 3  # desired, actual, platform
    fig = plots.plot_axis_errors(records)
    assert isinstance(fig, Figure) and len(fig.axes[0].lines) >= 3  # E_x, E_y, E_z
    fig = plots.plot_error_norm(records, tolerance=0.006)
    assert isinstance(fig, Figure) and len(fig.axes[0].lines) == 3  # two policies + the tolerance


def test_video_of_episode_0(tmp_path):
    result = run(_config(tmp_path, policies=("zero",), episodes=1, video=True))
    videos = list((result.out / "videos").iterdir())
    assert len(videos) == 1 and videos[0].suffix in (".mp4", ".gif") and videos[0].stat().st_size > 1000


def test_both_dynamics_modes_are_separate_conditions_on_the_same_robots(tmp_path):
    result = run(_config(tmp_path, policies=("zero", "nnbc"), episodes=1, dynamics=("kinematic", "physics")))
    assert [(r["dynamics"], r["policy"]) for r in result.episodes] == [
        ("kinematic", "zero"),
        ("kinematic", "nnbc"),
        ("physics", "zero"),
        ("physics", "nnbc"),
    ]
    assert all(r["status"] == "ok" for r in result.episodes)
    assert len({r["true_params_hash"] for r in result.episodes}) == 1  # seed S draws the same robot in both modes
    assert [(a["dynamics"], a["policy"]) for a in result.aggregate] == [
        ("kinematic", "zero"),
        ("kinematic", "nnbc"),
        ("physics", "zero"),
        ("physics", "nnbc"),
    ]


def test_duplicate_policies_and_unpicklable_objects_with_workers_are_refused(tmp_path):
    with pytest.raises(EvalError, match="more than once"):
        run(_config(tmp_path, policies=("zero", "zero")))

    class Local(HoldStill):  # a class defined inside a function cannot be pickled
        pass

    with pytest.raises(EvalError, match="cannot be sent to worker processes"):
        run(_config(tmp_path, policies=(), workers=2), policies={"local": Local()})
    assert not (tmp_path / "out").exists()


def test_a_worker_process_that_dies_marks_its_unfinished_episodes_failed(tmp_path):
    from test_eval_helpers import ExitOnOddSeed

    result = run(_config(tmp_path, policies=("zero",), episodes=2, workers=2), policies={"exit": ExitOnOddSeed()})
    status = {(r["policy"], r["seed"]): r["status"] for r in result.episodes}
    # worker 1 ran zero/seed S+1, then died in exit/seed S+1; worker 0 ran the rest
    assert status == {
        ("zero", SEED): "ok",
        ("zero", SEED + 1): "ok",
        ("exit", SEED): "ok",
        ("exit", SEED + 1): "failed",
    }
    died = next(r for r in result.episodes if r["status"] == "failed")
    assert "died with exit code 3" in died["error"]


def test_every_registered_task_runs_and_shares_its_path_across_policies(tmp_path):
    import mobman_env

    result = run(_config(tmp_path, envs=mobman_env.ENV_IDS, policies=("zero", "jmpi"), episodes=1, env_kwargs={}))
    assert len(result.episodes) == 2 * len(mobman_env.ENV_IDS)
    for env_id in mobman_env.ENV_IDS:
        recs = [r for r in result.episodes if r["env"] == env_id]
        assert all(r["status"] == "ok" and r["n_steps"] == 2000 for r in recs), env_id
        assert recs[0]["path"] == recs[1]["path"]  # Random-v0 included: the same drawn path seed
        assert recs[0]["true_params_hash"] == recs[1]["true_params_hash"]
    random_path = next(r["path"] for r in result.episodes if r["env"] == "WheeledPuma-Random-v0")
    assert "seed" in random_path


def test_every_record_has_every_field_even_when_its_worker_died(tmp_path):
    from test_eval_helpers import ExitOnOddSeed

    from eval.rollout import RECORD_KEYS

    result = run(_config(tmp_path, policies=(), episodes=2, workers=2), policies={"exit": ExitOnOddSeed()})
    ok, died = result.episodes
    assert ok["status"] == "ok" and died["status"] == "failed"
    for rec in result.episodes:
        assert set(RECORD_KEYS) <= set(rec)
    assert set(ok) == set(died)

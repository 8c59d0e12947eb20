"""mobman-eval sweep: YAML validation, the tidy table and plots, resuming after an interruption or a kill.

Episodes are kinematic 1 s circles (100 steps); the Ray-backend sweep test is in test_ray_backend.py (it shares
that module's Ray instance).
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from matplotlib.figure import Figure
from test_eval_helpers import ENV, SHORT, VOLATILE, CrashOnOddSeed, stable

from eval import EvalConfig, EvalError, run
from eval.cli import main
from eval.output.journal import JOURNAL, Journal
from eval.rollout import RECORD_KEYS
from eval.sweep.config import KEYS, SweepConfig, example_path, load_sweep
from eval.sweep.run import run_sweep

#: reported seeds of this module (DESIGN "Seeds")
SEEDS = [10_000, 10_001]
#: a small grid: 2 policies x 2 model errors x 2 noise levels x 2 seeds = 16 episodes
GRID = {
    "envs": [ENV],
    "policies": ["zero", "jmpi"],
    "seeds": SEEDS,
    "dynamics": ["kinematic"],
    "model_error": [0.0, 0.1],
    "obs_noise": [0.0, 0.002],
    "env_kwargs": SHORT,
}


def _sweep(**kw) -> SweepConfig:
    return SweepConfig.from_dict({**GRID, **kw})


def _table(out: Path) -> tuple[list[dict], list[dict], list[dict]]:
    """(results.json episodes, results.csv rows, aggregate) without the timing and pid fields."""
    res = json.loads((out / "results.json").read_text())
    rows = list(csv.DictReader((out / "results.csv").open()))
    agg = [{k: v for k, v in a.items() if not k.startswith("predict_us")} for a in res["aggregate"]]
    return (
        [stable(r) for r in res["episodes"]],
        [{k: v for k, v in r.items() if k not in VOLATILE} for r in rows],
        agg,
    )


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> Path:
    """The reference: the whole grid in one run."""
    out = tmp_path_factory.mktemp("sweep") / "whole"
    result = run_sweep(_sweep(), out, progress=False)
    assert result.n_run == 16 and result.n_left == 0
    return out


# --- the YAML file -------------------------------------------------------------------------------------------


def test_the_example_sweep_is_valid_and_printed_by_example(capsys):
    sweep = load_sweep(example_path())
    assert sweep.policies == ("nnbc", "jmpi", "oracle") and sweep.seeds == tuple(range(10_000, 10_008))
    assert sweep.n_episodes == 3 * 4 * 3 * 8
    assert main(["sweep", "--example"]) == 0
    assert yaml.safe_load(capsys.readouterr().out) == yaml.safe_load(example_path().read_text())


def test_seed_forms_scalars_and_defaults(tmp_path):
    path = tmp_path / "s.yaml"
    path.write_text("seeds: {start: 5, count: 3}\ndynamics: kinematic\nmodel_error: 0.1\n")
    sweep = load_sweep(path)
    assert sweep.seeds == (5, 6, 7) and sweep.dynamics == ("kinematic",) and sweep.model_error == (0.1,)
    assert sweep.policies == SweepConfig().policies and sweep.obs_noise == (0.0,)
    assert SweepConfig.from_dict({"seeds": [3, 1, 2]}).seeds == (3, 1, 2)
    # every key is read: a config differing from the defaults in every key round-trips through its dict
    custom = SweepConfig(
        envs=("WheeledPuma-Line-v0",),
        policies=("zero",),
        seeds=(3,),
        dynamics=("kinematic",),
        model_error=(0.2,),
        obs_noise=(0.001,),
        env_kwargs={"control_freq": 50.0},
        tolerance=0.01,
        settle_time=1.0,
    )
    assert all(getattr(custom, k) != getattr(SweepConfig(), k) for k in KEYS)
    assert set(custom.to_dict()) == set(KEYS) and SweepConfig.from_dict(custom.to_dict()) == custom


@pytest.mark.parametrize(
    "text, needles",
    [
        ("polices: [nnbc]", ["unknown key(s) 'polices' (did you mean 'policies'?)", "accepted: envs, policies, seeds"]),
        ("- nnbc", ["top level must be a mapping"]),
        ("seeds: 10000", ["seeds must be a list of integers", "{start: 10000, count: 8}"]),
        ("seeds: {start: 10000, n: 3}", ["exactly 'start' and 'count'", "'n'"]),
        ("seeds: {start: 10000, count: 0}", ["seeds.count must be an integer >= 1, got 0"]),
        ("seeds: [1, 1]", ["seeds lists 1 more than once"]),
        ("seeds: [1, -2]", ["seeds[1] must be an integer >= 0, got -2"]),
        ("model_error: [0.0, -0.1]", ["model_error[1] must be a finite number >= 0, got -0.1"]),
        ("obs_noise: [0.0, abc]", ["obs_noise[1] must be a finite number >= 0, got 'abc'"]),
        ("dynamics: [kinematics]", ["unknown mode 'kinematics'", "physics, kinematic"]),
        ("policies: []", ["policies is empty"]),
        ("env_kwargs: {model_error: 0.1}", ["env_kwargs sets ['model_error']", "sweep keys"]),
        ("env_kwargs: [1, 2]", ["env_kwargs must be a mapping"]),
        ("tolerance: 0", ["tolerance must be a finite number > 0"]),
        ("envs: [WheeledPuma-Circle-v0\n", ["not valid YAML"]),
    ],
)
def test_bad_sweep_files_fail_naming_the_problem(tmp_path, capsys, text, needles):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(EvalError) as exc:
        load_sweep(path)
    for needle in needles:
        assert needle in str(exc.value), (needle, str(exc.value))
    out = tmp_path / "out"
    assert main(["sweep", "--config", str(path), "--out", str(out), "--quiet"]) == 2
    assert needles[0] in capsys.readouterr().err
    assert not out.exists()


def test_unknown_policy_or_env_or_no_config_stops_before_any_episode(tmp_path, capsys):
    for kw, needle in (({"policies": ["zero", "nbc"]}, "unknown policy"), ({"envs": ["Nope-v0"]}, "unknown env id")):
        with pytest.raises(EvalError, match=needle):
            run_sweep(_sweep(**kw), tmp_path / "out", progress=False)
        assert not (tmp_path / "out").exists()
    assert main(["sweep", "--quiet"]) == 2
    assert "--config YAML is required" in capsys.readouterr().err
    assert main(["sweep", "--config", str(tmp_path / "missing.yaml")]) == 2
    assert "--example > sweep.yaml" in capsys.readouterr().err


# --- the table -------------------------------------------------------------------------------------------------


def test_sweep_writes_one_tidy_table_in_grid_order_and_plots(uninterrupted):
    out = uninterrupted
    for name in ("results.json", "results.csv", "aggregate.csv", "summary.md", "config.json", JOURNAL):
        assert (out / name).is_file(), name
    assert sorted(p.name for p in (out / "plots").iterdir()) == [
        f"{ENV}_kinematic_vs_model_error.png",
        f"{ENV}_kinematic_vs_obs_noise.png",
    ]
    res = json.loads((out / "results.json").read_text())
    assert res["schema"] == 4 and res["config"]["command"] == "sweep" and res["config"]["n_episodes"] == 16
    eps = res["episodes"]
    assert [(r["model_error"], r["obs_noise"], r["policy"], r["seed"]) for r in eps] == [
        (me, on, p, s) for me in (0.0, 0.1) for on in (0.0, 0.002) for p in ("zero", "jmpi") for s in SEEDS
    ]
    assert [r["index"] for r in eps] == list(range(16))
    for r in eps:
        assert set(RECORD_KEYS) <= set(r) and r["status"] == "ok"
    assert [r["episode"] for r in eps[:2]] == [0, 1]
    # model error draws another robot; sensor noise leaves the robot alone
    hashes = {(r["model_error"], r["obs_noise"], r["seed"]): r["true_params_hash"] for r in eps}
    assert hashes[(0.1, 0.0, SEEDS[0])] == hashes[(0.1, 0.002, SEEDS[0])] != hashes[(0.0, 0.0, SEEDS[0])]
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert len(rows) == 16 and float(rows[0]["max_error_m"]) == pytest.approx(eps[0]["max_error_m"])
    agg = list(csv.DictReader((out / "aggregate.csv").open()))
    assert len(agg) == 8 and {"success_rate", "max_error_m_median", "rms_error_m_std"} <= set(agg[0])
    assert all(a["n"] == "2" for a in agg)
    assert "| jmpi | 0.1 | 2 |" in (out / "summary.md").read_text()  # model_error 0.1, noise 2 mm


def test_a_sweep_episode_equals_the_run_episode_of_the_same_settings(uninterrupted, tmp_path):
    res = run(
        EvalConfig(
            envs=(ENV,),
            policies=("jmpi",),
            episodes=2,
            seed=SEEDS[0],
            dynamics=("kinematic",),
            model_error=0.1,
            obs_noise=0.002,
            env_kwargs=SHORT,
            out=str(tmp_path / "run"),
            progress=False,
            plots=False,
        )
    )
    sweep = json.loads((uninterrupted / "results.json").read_text())["episodes"]
    mine = [r for r in sweep if r["policy"] == "jmpi" and r["model_error"] == 0.1 and r["obs_noise"] == 0.002]
    drop = VOLATILE | {"index", "arrays_key"}
    assert [{k: v for k, v in r.items() if k not in drop} for r in mine] == [
        {k: v for k, v in r.items() if k not in drop} for r in json.loads(json.dumps(res.episodes))
    ]


def test_sweep_plot_takes_aggregate_rows_and_returns_a_figure(uninterrupted):
    from eval.sweep.plots import plot_vs, sweep_figures

    agg = json.loads((uninterrupted / "results.json").read_text())["aggregate"]
    fig = plot_vs(agg, "model_error", tolerance=0.006)
    assert isinstance(fig, Figure) and len(fig.axes) == 4  # success and error rows x 2 noise levels
    assert len(fig.axes[0].lines) == 2 and len(fig.axes[2].lines) == 3  # two policies (+ the tolerance)
    assert [name for name, _ in sweep_figures([a for a in agg if a["obs_noise"] == 0.0])] == [
        f"{ENV}_kinematic_vs_model_error"
    ]  # a variable with one value gets no plot


# --- resuming ------------------------------------------------------------------------------------------------


def test_an_interrupted_sweep_resumed_gives_the_same_table(uninterrupted, tmp_path):
    out = tmp_path / "parts"
    first = run_sweep(_sweep(), out, max_episodes=5, progress=False)
    assert (first.n_run, first.n_skipped, first.n_left, len(first.episodes)) == (5, 0, 11, 5)
    second = run_sweep(_sweep(), out, workers=2, progress=False)  # resumed with other executors
    assert (second.n_run, second.n_skipped, second.n_left) == (11, 5, 0)
    assert _table(out) == _table(uninterrupted)
    again = run_sweep(_sweep(), out, progress=False)
    assert again.n_run == 0 and again.n_skipped == 16 and _table(out) == _table(uninterrupted)


def test_a_write_torn_by_an_interruption_is_dropped_and_rerun(uninterrupted, tmp_path, monkeypatch):
    out = tmp_path / "torn"
    calls = []
    real_append = Journal.append

    def append_then_die(self, rec):
        calls.append(rec["seed"])
        if len(calls) < 4:
            return real_append(self, rec)
        os.write(self._fd, json.dumps(rec).encode()[:50])  # killed in the middle of the 4th line
        raise KeyboardInterrupt

    monkeypatch.setattr(Journal, "append", append_then_die)
    with pytest.raises(KeyboardInterrupt):
        run_sweep(_sweep(), out, progress=False)
    monkeypatch.undo()
    assert not (out / JOURNAL).read_bytes().endswith(b"\n")
    assert len(json.loads((out / "results.json").read_text())["episodes"]) == 3  # the complete records
    result = run_sweep(_sweep(), out, progress=False)
    assert (result.n_run, result.n_skipped) == (13, 3)
    assert _table(out) == _table(uninterrupted)
    assert len((out / JOURNAL).read_text().splitlines()) == 16


def test_a_killed_sweep_process_resumes_to_the_same_table(uninterrupted, tmp_path):
    cfg = tmp_path / "grid.yaml"
    cfg.write_text(yaml.safe_dump({**GRID, "env_kwargs": {"path": {**SHORT["path"], "duration": 3.0}}}))
    whole = tmp_path / "whole"
    assert main(["sweep", "--config", str(cfg), "--out", str(whole), "--quiet", "--no-plots"]) == 0
    out = tmp_path / "killed"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen(
        [sys.executable, "-m", "eval", "sweep", "--config", str(cfg), "--out", str(out), "--quiet", "--no-plots"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    journal = out / JOURNAL
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        if journal.exists() and journal.read_bytes().count(b"\n") >= 3:
            break
        time.sleep(0.005)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    n_before = journal.read_bytes().count(b"\n")
    assert 3 <= n_before < 16, n_before  # killed in the middle of the sweep
    assert main(["sweep", "--config", str(cfg), "--out", str(out), "--quiet", "--no-plots"]) == 0
    assert _table(out) == _table(whole)


def test_failed_episodes_are_kept_and_rerun_only_on_request(tmp_path):
    out = tmp_path / "crash"
    sweep = _sweep(policies=["zero"], model_error=[0.05], obs_noise=[0.0])
    first = run_sweep(sweep, out, progress=False, policies={"crash": CrashOnOddSeed()})
    assert [(r["policy"], r["status"]) for r in first.episodes] == [
        ("zero", "ok"),
        ("zero", "ok"),
        ("crash", "ok"),
        ("crash", "failed"),
    ]
    assert "deliberate crash" in first.episodes[-1]["error"]
    assert "Failed episodes (1)" in (out / "summary.md").read_text()
    assert run_sweep(sweep, out, progress=False, policies={"crash": CrashOnOddSeed()}).n_run == 0
    retried = run_sweep(sweep, out, progress=False, policies={"crash": CrashOnOddSeed()}, retry_failed=True)
    assert retried.n_run == 1 and retried.episodes[-1]["status"] == "failed"
    assert len(retried.episodes) == 4 and len((out / JOURNAL).read_text().splitlines()) == 5  # later line wins


def test_a_grown_grid_runs_only_the_new_episodes(uninterrupted, tmp_path):
    out = tmp_path / "grow"
    run_sweep(_sweep(obs_noise=[0.0]), out, progress=False)
    grown = run_sweep(_sweep(), out, progress=False)
    assert (grown.n_run, grown.n_skipped) == (8, 8)
    assert _table(out) == _table(uninterrupted)


def test_resuming_with_other_env_kwargs_or_into_a_foreign_directory_is_refused(uninterrupted, tmp_path):
    with pytest.raises(EvalError, match="holds a sweep with other settings .*env_kwargs"):
        run_sweep(
            _sweep(env_kwargs={"path": {"type": "circle", "radius": 0.1, "duration": 2.0}}),
            uninterrupted,
            progress=False,
        )
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(EvalError, match="does not hold a sweep"):
        run_sweep(_sweep(), foreign, progress=False)
    assert sorted(p.name for p in foreign.iterdir()) == ["notes.txt"]

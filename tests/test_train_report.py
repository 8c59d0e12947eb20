"""`mobman-train report` (train.report, train.report_stats, train.report_text): the statistics on known values,
the report on tiny synthetic run folders (evaluation replaced by known episode records, so these are fast), and
one real end-to-end report of two tiny trained agents on a 1 s path (evaluations cached on the second call)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from eval import metrics as M
from train import report as R
from train.report_stats import curve_rows, family_row, median_run, success_ci95

SHORT_PATH = {"type": "circle", "radius": 0.1, "tilt": 0.5236, "yaw": 3.1416, "duration": 1.0}


def _episodes(errors, tol=0.006, first=10_000):
    return [
        {"seed": first + k, "status": "ok", "max_error_m": e, "success": e <= tol, "tipped_over": False}
        for k, e in enumerate(errors)
    ]


# --- statistics -----------------------------------------------------------------------------------------------
def test_family_row_pools_seeds_x_episodes_and_resamples_seeds_within_episodes():
    errs = np.array([[0.001, 0.002, 0.010, 0.004], [0.003, 0.001, 0.020, 0.005], [0.002, 0.008, 0.004, 0.030]])
    runs = [{"name": f"r{i}", "seed": i, "episodes": _episodes(row)} for i, row in enumerate(errs)]
    row = family_row("ppo-kinematic", runs)
    assert row["n_seeds"] == 3 and row["n_episodes"] == 12 and row["n_failed"] == 0
    assert row["max_error_m"]["iqm"] == pytest.approx(M.iqm(errs.ravel()))
    # the interval is eval's stratified bootstrap with the episodes (columns) as strata
    assert row["max_error_m"]["iqm_ci95"] == M.iqm_ci95([list(errs[:, j]) for j in range(4)])
    low, high = row["max_error_m"]["iqm_ci95"]
    assert low <= row["max_error_m"]["iqm"] <= high
    assert row["max_error_m"]["per_seed_iqm"] == pytest.approx([M.iqm(r) for r in errs])
    assert row["success_rate"] == pytest.approx(np.mean(errs <= 0.006))
    assert row["per_seed_success_rate"] == pytest.approx([0.75, 0.75, 0.5])
    with pytest.raises(ValueError, match="evaluate every run on the same episodes"):
        family_row("f", [runs[0], {"name": "x", "seed": 9, "episodes": _episodes(errs[1], first=20_000)}])


def test_a_failed_episode_is_a_failure_and_not_an_error_value():
    eps = _episodes([0.001, 0.002, 0.003])
    eps[1] = {**eps[1], "status": "error", "max_error_m": None, "success": False}
    row = family_row("f", [{"name": "a", "seed": 0, "episodes": eps}])
    assert row["n_failed"] == 1 and row["success_rate"] == pytest.approx(2 / 3)
    assert row["max_error_m"]["median"] == pytest.approx(0.002)


def test_success_interval_is_a_seed_bootstrap():
    assert success_ci95(np.ones((5, 20))) == [1.0, 1.0]
    mixed = np.array([[1.0] * 10, [0.0] * 10, [1.0] * 10])  # one seed of three fails everything
    low, high = success_ci95(mixed)
    assert 0.0 < low < 2 / 3 < high <= 1.0
    assert success_ci95(mixed) == [low, high]  # fixed generator: same values, same interval
    # the spread between seeds widens it beyond the pooled-episode Wilson interval
    wilson = M.wilson_interval(20, 30)
    assert high - low > wilson[1] - wilson[0]


def test_median_run_lower_median_ties_by_seed():
    runs = [{"seed": s, "v": v} for s, v in [(0, 5.0), (1, 1.0), (2, 3.0), (3, 9.0), (4, 2.0)]]
    assert median_run(runs, key=lambda r: r["v"])["seed"] == 2
    assert median_run(runs[:4], key=lambda r: r["v"])["seed"] == 2  # 1, 3, 5, 9: the lower middle one
    tied = [{"seed": 7, "v": 1.0}, {"seed": 3, "v": 1.0}, {"seed": 5, "v": 1.0}]
    assert median_run(tied, key=lambda r: r["v"])["seed"] == 5
    with pytest.raises(ValueError, match="no finished run"):
        median_run([], key=lambda r: 0.0)


def test_curve_rows_iqm_over_the_seeds_evaluated_at_each_step():
    def run(values):
        return {
            "curve": [
                {"timesteps": 1000 * i, "wall_s": 10.0 * i, "median_max_error_m": v} for i, v in enumerate(values)
            ]
        }

    rows = curve_rows("f", [run([1.0, 0.5, 0.2]), run([2.0, 0.4]), run([3.0, 0.3, 0.1]), run([4.0, 0.6])])
    assert [r["timesteps"] for r in rows] == [0, 1000, 2000]
    assert [r["n_seeds"] for r in rows] == [4, 4, 2]
    assert rows[0]["median_max_error_m_iqm"] == pytest.approx(2.5)  # middle two of 1, 2, 3, 4
    assert rows[0]["median_max_error_m_ci95_low"] <= 2.5 <= rows[0]["median_max_error_m_ci95_high"]
    assert rows[1]["wall_s_median"] == 10.0
    one = curve_rows("f", [run([1.0])])
    assert one[0]["median_max_error_m_ci95_low"] is None  # no interval from one seed


# --- the report on synthetic run folders ----------------------------------------------------------------------
def _run_folder(root: Path, name: str, algo: str, seed: int, *, done=True, dynamics="kinematic", **cfg_changes):
    d = root / name
    d.mkdir(parents=True)
    cfg = {
        "algo": algo,
        "seed": seed,
        "dynamics": dynamics,
        "env_id": "WheeledPuma-Circle-v0",
        "timesteps": 2000,
        "env_kwargs": {"error_bound": 0.1},
        "eval_env_kwargs": {"dynamics": dynamics},
        "alive_bonus": 2.0,
        "obs_keys": ["pos_error"],
        "wrappers": ["pos_error"],
        "hyperparams_resolved": {"gamma": 0.98},
        "n_envs": 1,
        "torch_threads": 1,
        **cfg_changes,
    }
    (d / "config.json").write_text(json.dumps(cfg))
    steps = [0, 1000, 2000] if done else [0, 1000]
    lines = ["timesteps,wall_s,median_max_error_m"] + [f"{s},{s / 100},{0.5 / (1 + s / 500 + seed)}" for s in steps]
    (d / "learning_curve.csv").write_text("\n".join(lines) + "\n")
    if done:
        (d / "summary.json").write_text(json.dumps({"status": "done", "timesteps": 2000, "wall_s": 20.0 + seed}))
        (d / "model.zip").write_bytes(f"model {name}".encode())
    return d


def _fake_evaluation(calls):
    """Replaces eval.run behind the cache: known errors per model (seed-dependent) and per controller."""

    def fake(cfg, extra):
        calls.append(cfg.policies)
        out = []
        for p in cfg.policies:
            for k in range(cfg.episodes):
                if p.startswith("sb3:"):
                    seed = int(Path(p[4:]).parent.name.rsplit("s", 1)[1])
                    err = 0.002 * (1 + seed) + 0.001 * k
                else:
                    err = {"zero": 0.8, "jmpi": 0.07}.get(p, 0.0004)
                out.append({**_episodes([err], first=cfg.seed + k)[0], "policy": p, "dynamics": cfg.dynamics[0]})
        return out

    return fake


def test_report_on_synthetic_runs(tmp_path, monkeypatch):
    calls: list = []
    monkeypatch.setattr(R, "cached_evaluation", _fake_evaluation(calls))
    runs = [_run_folder(tmp_path, f"ppo-kin-s{s}", "ppo", s) for s in range(3)]
    runs.append(_run_folder(tmp_path, "ppo-phys-s0", "ppo", 0, dynamics="physics"))
    runs.append(_run_folder(tmp_path, "ppo-phys-s1", "ppo", 1, dynamics="physics", done=False))
    out = tmp_path / "report"
    cfg = R.ReportConfig(
        runs=tuple(map(str, runs)),
        out=str(out),
        episodes=4,
        controllers=("jmpi", "zero"),
        ship=(("my-ppo", "ppo-kinematic"),),
        models_dir=str(tmp_path / "models"),
    )
    results = R.build_report(cfg)
    assert {f for f in R.REPORT_FILES} <= {p.name for p in out.iterdir()}
    # only finished runs are evaluated; controllers once per mode
    assert sum(1 for c in calls if c[0].startswith("sb3:")) == 4
    assert [c for c in calls if not c[0].startswith("sb3:")] == [("jmpi", "zero"), ("jmpi", "zero")]
    fam = {f["family"]: f for f in results["families"]}
    assert sorted(fam) == ["ppo-kinematic", "ppo-physics"]
    assert fam["ppo-kinematic"]["n_seeds"] == 3 and fam["ppo-kinematic"]["n_episodes"] == 12
    assert fam["ppo-physics"]["n_seeds"] == 1  # the unfinished seed is not in the final table
    assert fam["ppo-kinematic"]["wall_s_total"] == pytest.approx(20 + 21 + 22)
    assert results["median_seed_models"]["ppo-kinematic"] == {
        "run": "ppo-kin-s1",
        "seed": 1,
        "path": str(runs[1].resolve()),
    }
    status = {r["name"]: r["status"] for r in results["runs"]}
    assert status["ppo-phys-s1"] == "training"
    saved = json.loads((out / "results.json").read_text())
    assert min(e["seed"] for e in saved["episodes"]) == 10_000
    assert len(saved["episodes"]) == 4 * 4 + 2 * 2 * 4
    text = (out / "summary.md").read_text()
    for section in ("## Final evaluation: kinematic", "## Final evaluation: physics", "## Runs", "## Compute"):
        assert section in text
    assert "| PPO (kinematic-trained), 2,000 steps | 3 x 4 |" in text
    assert "`ppo-kin-s1` (median seed)" in text
    assert fam["ppo-physics"]["max_error_m"]["iqm_ci95"] is None  # one seed: no interval over seeds
    assert "| PPO (physics-trained), 2,000 steps | 1 x 4 | 0 | 0 | 100% | 3.50 | 3.50 | training seeds |" in text
    assert "training (target 2,000)" in text
    # summary.md is a function of results.json alone
    from train.report_text import summary_markdown

    assert summary_markdown(saved) == text
    # the shipped model is the median seed's, with a README generated from the results
    shipped = tmp_path / "models" / "my-ppo"
    assert (shipped / "model.zip").read_bytes() == b"model ppo-kin-s1"
    from train.report_text import model_readme

    readme = (shipped / "README.md").read_text()
    assert readme == model_readme(saved, "ppo-kinematic", "my-ppo", str(out / "results.json"))
    assert "**median-seed model** of the `ppo-kinematic` family: of its finished training seeds (0, 1, 2)" in readme
    assert "`ppo-kin-s1`, seed 1. A typical run, not the best one." in readme
    assert (
        "mobman-train --algo ppo --env WheeledPuma-Circle-v0 --dynamics kinematic --timesteps 2000 --seed 1" in readme
    )
    with pytest.raises(ValueError, match=r"no finished run of family 'sac-kinematic'; families: \['ppo-kinematic'"):
        R.build_report(cfg.__class__(**{**cfg.__dict__, "ship": (("x", "sac-kinematic"),)}))
    curves = (out / "curves_iqm.csv").read_text().splitlines()
    assert curves[0].startswith("family,timesteps,n_seeds,median_max_error_m_iqm")


@pytest.mark.parametrize(
    "changes, match",
    [
        ({"timesteps": 5000}, r"ppo-kin-s1 has timesteps 5000, ppo-kin-s0 2000; the runs of a family may differ only"),
        ({"hyperparams_resolved": {"gamma": 0.9}}, "has hyperparams"),
        ({"cfg_seed": 0}, r"training seeds repeat \(\[0, 0\]"),
        ({"eval_env_kwargs": {"model_error": 0.2}}, r"trained on env arguments \{'model_error': 0.2\}"),
    ],
)
def test_report_refuses_runs_that_are_not_one_setting(tmp_path, monkeypatch, changes, match):
    monkeypatch.setattr(R, "cached_evaluation", _fake_evaluation([]))
    a = _run_folder(tmp_path, "ppo-kin-s0", "ppo", 0)
    seed = changes.pop("cfg_seed", 1)
    b = _run_folder(tmp_path, "ppo-kin-s1", "ppo", seed, **changes)
    with pytest.raises(ValueError, match=match):
        R.build_report(R.ReportConfig(runs=(str(a), str(b)), out=str(tmp_path / "o"), episodes=2, controllers=()))


def test_report_cli_errors(tmp_path, capsys):
    from train.cli import main

    assert main(["report", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "is not a mobman-train run folder (no config.json)" in capsys.readouterr().err
    assert main(["report", str(tmp_path), "--seed", "5"]) == 2
    assert "reported seeds start at 10000" in capsys.readouterr().err


def test_redraw_draws_the_committed_curves_again_from_the_committed_report(tmp_path, capsys):
    """`mobman-train report --redraw --out DIR`: curves.png of docs/results/rl-v2 again from its results.json and
    curves.csv alone (nothing evaluated): the same palette PNG (up to 1% of pixels, for another FreeType); other
    report options and a folder that is not a report's are refused."""
    from PIL import Image

    from policies.agents.untrusted_json import stored_path
    from train.cli import main

    committed = Path(__file__).resolve().parents[1] / "docs" / "results" / "rl-v2"
    for name in ("results.json", "curves.csv"):  # results.json is stored compacted: results.json.xz
        stored = stored_path(committed / name)
        (tmp_path / stored.name).write_bytes(stored.read_bytes())
    assert main(["report", "--redraw", "--out", str(tmp_path)]) == 0
    assert "curves.png drawn again" in capsys.readouterr().out
    with Image.open(committed / "curves.png") as old, Image.open(tmp_path / "curves.png") as new:
        assert new.mode == old.mode == "P" and new.size == old.size
        a, b = (np.asarray(i.convert("RGB")) for i in (old, new))
    assert (a != b).any(axis=2).mean() <= 0.01
    assert main(["report", "--redraw", "--out", str(tmp_path), "--seeds", "3"]) == 2
    assert "--redraw takes only --out DIR, not episodes" in capsys.readouterr().err
    (tmp_path / "results.json").write_text(json.dumps({"schema": 4}))
    assert main(["report", "--redraw", "--out", str(tmp_path)]) == 2
    assert "not a report's" in capsys.readouterr().err


# --- end to end: two tiny trained agents, real evaluations, cache -------------------------------------------
@pytest.mark.slow
def test_report_end_to_end_with_cache(tmp_path, monkeypatch):
    pytest.importorskip("stable_baselines3")
    from train.config import TrainConfig
    from train.run import run

    tiny = {"n_steps": 64, "batch_size": 32, "n_epochs": 1, "policy_kwargs": {"net_arch": {"pi": [8], "vf": [8]}}}
    dirs = []
    for seed in (0, 1):
        d = tmp_path / f"ppo-s{seed}"
        run(
            TrainConfig(
                algo="ppo",
                timesteps=128,
                seed=seed,
                out=str(d),
                hyperparams=tiny,
                env_kwargs={"path": SHORT_PATH, "error_bound": 0.1},
                eval_freq=64,
                eval_episodes=1,
                final_eval_episodes=0,
                checkpoint_freq=0,
                progress_bar=False,
            )
        )
        dirs.append(str(d))
    cfg = R.ReportConfig(
        runs=tuple(dirs), out=str(tmp_path / "rep"), episodes=2, controllers=("zero",), env_kwargs={"path": SHORT_PATH}
    )
    first = R.build_report(cfg)
    eps = [e for e in first["episodes"] if e.get("run") == "ppo-s0"]
    assert [e["seed"] for e in eps] == [10_000, 10_001] and all(e["n_steps"] == 100 for e in eps)
    assert (tmp_path / "rep" / "evals" / "ppo-s0" / "results.json").is_file()

    import eval as eval_pkg

    def no_rerun(*a, **k):
        raise AssertionError("the evaluation should have been read from the cache")

    monkeypatch.setattr(eval_pkg, "run", no_rerun)
    second = R.build_report(cfg)
    assert second["episodes"] == first["episodes"]
    # a changed model is evaluated again
    with open(Path(dirs[0]) / "model.zip", "ab") as f:
        f.write(b"\0")
    with pytest.raises(AssertionError, match="from the cache"):
        R.build_report(cfg)


# --- runs carried over from an earlier report (train.report_archive) ----------------------------------------
def _caching_evaluation(calls):
    """The fake evaluation of `_fake_evaluation`, written to the cache files a real one leaves (inputs.json,
    results.json in cfg.out), which is what --include reads back."""
    fake = _fake_evaluation(calls)

    def run(cfg, extra):
        records = fake(cfg, extra)
        out = Path(cfg.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "inputs.json").write_text(json.dumps(R._inputs(cfg, extra)))
        (out / "results.json").write_text(json.dumps({"episodes": records}))
        return records

    return run


@pytest.mark.parametrize("compacted", [False, True], ids=["plain", "compacted"])
def test_report_carries_over_an_earlier_reports_runs(tmp_path, monkeypatch, compacted):
    """An earlier report's finished runs are carried over as measured, also from a report whose results files are
    stored compacted (`mobman-eval compact`, as docs/results/rl-v2 keeps them)."""
    import shutil

    calls: list = []
    monkeypatch.setattr(R, "cached_evaluation", _caching_evaluation(calls))
    common = dict(episodes=4, controllers=("zero",), models_dir=str(tmp_path / "models"), plots=False)
    old = [_run_folder(tmp_path / "machine1", f"ppo-kin-s{s}", "ppo", s) for s in range(3)]
    first = R.build_report(
        R.ReportConfig(
            runs=tuple(map(str, old)), out=str(tmp_path / "a"), ship=(("my-ppo", "ppo-kinematic"),), **common
        )
    )
    assert first["median_seed_models"]["ppo-kinematic"]["run"] == "ppo-kin-s1"
    shutil.rmtree(tmp_path / "machine1")  # the old machine is gone: only the committed report is left
    if compacted:
        from eval.output.compact import compact

        for path in sorted((tmp_path / "a").rglob("results.json")):
            compact(path)
    new = _run_folder(tmp_path / "machine2", "ppo-kin-s3", "ppo", 3)
    calls.clear()
    cfg = R.ReportConfig(
        runs=(str(new),),
        include=(str(tmp_path / "a"),),
        out=str(tmp_path / "b"),
        train_commit="abc1234",
        ship=(("my-ppo", "ppo-kinematic"),),
        **common,
    )
    second = R.build_report(cfg)
    # only the new run is evaluated; the carried runs keep their measured episodes, curves and budgets
    assert [c for c in calls if c[0].startswith("sb3:")] == [(f"sb3:{new}/model.zip",)]
    fam = second["families"][0]
    assert (
        fam["n_seeds"] == 4 and fam["seeds"] == [0, 1, 2, 3] and fam["wall_s_total"] == pytest.approx(20 + 21 + 22 + 23)
    )
    assert fam["max_error_m"]["per_seed_iqm"][:3] == first["families"][0]["max_error_m"]["per_seed_iqm"]
    carried = {r["name"]: r for r in second["runs"] if r.get("archived_from")}
    assert sorted(carried) == ["ppo-kin-s0", "ppo-kin-s1", "ppo-kin-s2"]
    assert carried["ppo-kin-s0"]["archived_from"] == str(tmp_path / "a")
    from train.report_archive import archived_curves

    assert archived_curves(tmp_path / "b") == archived_curves(tmp_path / "a") | {
        "ppo-kin-s3": archived_curves(tmp_path / "b")["ppo-kin-s3"]
    }
    assert [c["timesteps"] for c in archived_curves(tmp_path / "b")["ppo-kin-s0"]] == [0.0, 1000.0, 2000.0]
    assert (tmp_path / "b" / "evals" / "ppo-kin-s0" / "inputs.json").is_file()  # the evidence moves with them
    copied = tmp_path / "b" / "evals" / "ppo-kin-s0" / ("results.json.xz" if compacted else "results.json")
    assert copied.is_file()  # as it was stored
    assert second["train_commits"] == {
        "not recorded": ["ppo-kin-s0", "ppo-kin-s1", "ppo-kin-s2"],
        "abc1234": ["ppo-kin-s3"],
    }
    assert "runs carried over from" in (tmp_path / "b" / "summary.md").read_text()
    # the median of four seeds is still ppo-kin-s1, whose model is gone but already shipped: its README is redone
    assert second["median_seed_models"]["ppo-kinematic"]["run"] == "ppo-kin-s1"
    assert (tmp_path / "models" / "my-ppo" / "model.zip").read_bytes() == b"model ppo-kin-s1"
    assert "4 finished seed(s)" in (tmp_path / "models" / "my-ppo" / "README.md").read_text()
    # a carried run is never re-evaluated: a report with other episodes refuses it and names the difference
    with pytest.raises(ValueError, match=r"run ppo-kin-s0 was evaluated with other settings \(episodes differ"):
        R.build_report(R.ReportConfig(**{**cfg.__dict__, "episodes": 3, "out": str(tmp_path / "c")}))
    # a shipped model that is not the archived median's cannot be replaced without its run folder
    (tmp_path / "models" / "my-ppo" / "model.zip").write_bytes(b"another model")
    with pytest.raises(ValueError, match=r"median-seed run ppo-kin-s1 has no model at .*give its run folder"):
        R.build_report(cfg)


@pytest.mark.parametrize("name", ["../escaped", "../../escaped", "sub/escaped", "..", ""])
def test_include_refuses_a_run_name_that_is_not_a_plain_folder_name(tmp_path, monkeypatch, name):
    """An archived run's name becomes evals/<name>/ in the new report: `../x` must not write outside it."""
    import shutil

    monkeypatch.setattr(R, "cached_evaluation", _caching_evaluation([]))
    common = dict(episodes=2, controllers=(), plots=False)
    old = _run_folder(tmp_path / "m", "ppo-kin-s0", "ppo", 0)
    R.build_report(R.ReportConfig(runs=(str(old),), out=str(tmp_path / "a"), **common))
    results = json.loads((tmp_path / "a" / "results.json").read_text())
    results["runs"][0]["name"] = name
    (tmp_path / "a" / "results.json").write_text(json.dumps(results))
    cached = tmp_path / "a" / "evals" / name  # where the crafted name points, given what the old report had
    cached.mkdir(parents=True, exist_ok=True)
    for f in ("inputs.json", "results.json"):
        if not (cached / f).exists():  # ("..": the report's own results.json stays the crafted one)
            shutil.copyfile(tmp_path / "a" / "evals" / "ppo-kin-s0" / f, cached / f)
    out = tmp_path / "b" / "report"
    with pytest.raises(ValueError, match=rf"run name must be a plain name .*got '{name}'.*restore the file"):
        R.build_report(R.ReportConfig(include=(str(tmp_path / "a"),), out=str(out), **common))
    assert not (tmp_path / "b").exists()


def test_ship_alias_and_run_folder_names_must_be_plain(tmp_path, capsys):
    from train.cli import main

    run = _run_folder(tmp_path / "m", "ppo-kin-s0", "ppo", 0)
    models = tmp_path / "shipped" / "models"
    for alias in ("../x", "a/b", ".."):
        assert main(["report", str(run), "--ship", f"{alias}=ppo-kinematic", "--models-dir", str(models)]) == 2
        err = capsys.readouterr().err
        assert "--ship ALIAS must be a plain name" in err and repr(alias) in err and "Traceback" not in err
    assert not (tmp_path / "shipped").exists()
    (run / "sub").mkdir()
    assert R.read_run(f"{run}/sub/..")["name"] == "ppo-kin-s0"  # its real name, not "..", which is evals/..


def _damage(run: Path, damage: str) -> None:
    import os

    curve, cfg = run / "learning_curve.csv", run / "config.json"
    if damage == "curve_dev_zero":
        curve.unlink()
        curve.symlink_to("/dev/zero")
    elif damage == "curve_fifo":
        curve.unlink()
        os.mkfifo(curve)
    elif damage == "summary_fifo":
        (run / "summary.json").unlink()
        os.mkfifo(run / "summary.json")
    elif damage == "curve_huge":
        with open(curve, "ab") as f:
            f.truncate(65 * 2**20)  # sparse: 65 MiB of NULs after the rows
    elif damage == "config_no_algo":
        cfg.write_text(json.dumps({k: v for k, v in json.loads(cfg.read_text()).items() if k != "algo"}))
    elif damage == "summary_wall":
        (run / "summary.json").write_text(json.dumps({"status": "done", "timesteps": 2000, "wall_s": "long"}))
    elif damage == "curve_extra_column":
        curve.write_text(curve.read_text().replace("\n1000,", "\n1000,7,", 1))
    elif damage == "curve_not_a_number":
        curve.write_text(curve.read_text().replace("\n1000,10.0,", "\n1000,10.0,abc", 1))


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    "damage, match",
    [
        ("curve_dev_zero", r"learning_curve.csv is a device, not a regular file"),
        ("curve_fifo", r"learning_curve.csv is a FIFO, not a regular file"),
        ("summary_fifo", r"summary.json is a FIFO, not a regular file"),
        ("curve_huge", r"learning_curve.csv holds 68157440 bytes; a learning curve is at most 67108864 bytes"),
        ("config_no_algo", r"config.json: 'algo' must be a text, got missing"),
        ("summary_wall", r"summary.json: 'wall_s' must be a number, got 'long'"),
        ("curve_extra_column", r"learning_curve.csv, line 3: 4 fields where the header has 3"),
        ("curve_not_a_number", r"learning_curve.csv, line 3: median_max_error_m = 'abc[0-9.]+' is not a number"),
    ],
)
def test_report_refuses_run_files_it_cannot_read_safely(tmp_path, capsys, damage, match):
    """A run folder's files are read only as regular files under a size cap, and every malformed value is
    named with its file (exit 2, no traceback, nothing written)."""
    import re

    from train.cli import main

    run = _run_folder(tmp_path / "m", "ppo-kin-s0", "ppo", 0)
    _damage(run, damage)
    assert main(["report", str(run), "--out", str(tmp_path / "out"), "--policy", ""]) == 2
    err = capsys.readouterr().err
    assert re.search(match, err) and "Traceback" not in err, err
    assert not (tmp_path / "out").exists()


def test_a_model_zip_that_inflates_beyond_the_cap_is_refused_unread(tmp_path):
    import zipfile

    from policies.agents.sb3_files import read_zip_data
    from policies.agents.untrusted import MAX_MODEL_DATA_BYTES

    path = tmp_path / "model.zip"
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("data", b"{" + b" " * (MAX_MODEL_DATA_BYTES + 1) + b"}")
    assert path.stat().st_size < 2**20
    with pytest.raises(ValueError, match=rf"entry 'data' inflates to {MAX_MODEL_DATA_BYTES + 3} bytes; at most"):
        read_zip_data(path)


def test_the_controllers_are_evaluated_again_when_their_code_changes(tmp_path, monkeypatch):
    """The controllers' cached evaluation is keyed by the source of `mobman_env` and `policies` too: the same
    configuration with changed controller code runs again (a report once carried `nnbc-plus` v3's rows over
    after v4 had changed its actions), the same code reads the cache."""
    calls: list = []
    evaluate = _caching_evaluation(calls)

    def cached(cfg, extra):  # the cache rule of R.cached_evaluation over the fake evaluation
        out = Path(cfg.out)
        key = json.loads(json.dumps(R._inputs(cfg, extra)))
        if (out / "inputs.json").is_file() and json.loads((out / "inputs.json").read_text()) == key:
            return json.loads((out / "results.json").read_text())["episodes"]
        return evaluate(cfg, extra)

    monkeypatch.setattr(R, "cached_evaluation", cached)
    cfg = R.ReportConfig(
        runs=(str(_run_folder(tmp_path, "ppo-kin-s0", "ppo", 0)),),
        out=str(tmp_path / "report"),
        episodes=2,
        controllers=("zero",),
        models_dir=str(tmp_path / "models"),
        plots=False,
    )
    R.build_report(cfg)
    assert [c for c in calls if not c[0].startswith("sb3:")] == [("zero",)]
    calls.clear()
    R.build_report(cfg)
    assert calls == []  # nothing changed: everything from the cache
    monkeypatch.setattr(R, "code_hash", lambda: "another source")
    R.build_report(cfg)
    assert calls == [("zero",)]  # the controllers again, the agent's evaluation still from its cache

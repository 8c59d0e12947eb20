"""results.json schema 4 and the reading of older files: `load_results`, the tables, a sweep made by mobman 0.1
(tests/fixtures/schema1, written at commit 3d1df75) resumed by today's code, and a schema-2 run of mobman 0.2
(tests/fixtures/schema2: the kinematic nnbc and jmpi episodes 0-2 of docs/results/paper/results.json at e8a9c1d)."""

import json
import shutil
from pathlib import Path

import pytest

from eval.cli import main as main_run
from eval.errors import EvalError
from eval.output.results import SCHEMA, load_results, upgrade_results
from eval.output.tables import summary_markdown
from eval.sweep.config import SweepConfig
from eval.sweep.report import aggregate_csv_text
from eval.sweep.run import run_sweep

FIXTURES = Path(__file__).parent / "fixtures" / "schema1"


def test_a_schema_1_run_loads_in_schema_4_shape():
    res = load_results(FIXTURES / "run" / "results.json")
    assert res["schema"] == 1 and SCHEMA == 4  # the file's own number is kept
    assert all(r["feasible"] is None and r["feasibility_peak"] is None for r in res["episodes"])
    assert res["provenance"] is None and res["statistics"] is None
    assert all(r["steady_max_error_m"] is None for r in res["episodes"])
    for row in res["aggregate"]:
        assert row["success_rate_ci95"] is None and row["success_curve"] is None
        assert row["max_error_m"]["iqm"] is None and row["max_error_m"]["median"] is not None
        assert row["steady_max_error_m"] == dict.fromkeys(
            ("median", "mean", "std", "min", "max", "p90", "iqm", "iqm_ci95", "worst")
        )
    md = summary_markdown(res)  # today's tables render a schema-1 file
    assert "| nnbc-plus |" in md and "| jmpi |" in md
    assert aggregate_csv_text(res["aggregate"]).count("\n") == 3


def test_an_older_files_records_are_named_as_a_run_of_their_arguments_names_them_today(tmp_path):
    """Converted, not re-run: a schema-1 file's episodes get the condition name that a schema-4 run of the same
    env arguments records."""
    old = load_results(FIXTURES / "run" / "results.json")
    cfg = old["config"]
    out = tmp_path / "again"
    rec = old["episodes"][0]
    code = main_run(
        [
            "run", "--env", rec["env"], "--policy", str(rec["policy"]), "--seed", str(rec["seed"]), "--seeds", "1",
            "--dynamics", "kinematic", "--env-kwargs", json.dumps(cfg["env_kwargs"]), "--out", str(out), "--quiet",
        ]
    )  # fmt: skip
    assert code == 0
    new = load_results(out / "results.json")["episodes"][0]
    assert new["condition"] == rec["condition"] == {r["condition"] for r in old["aggregate"]}.pop()
    assert rec["condition"].startswith("kinematic, model_error=0.05, obs_noise=0, path=")


def test_a_schema_2_run_loads_in_schema_4_shape():
    res = load_results(Path(__file__).parent / "fixtures" / "schema2" / "results.json")
    assert res["schema"] == 2
    assert all(
        r["robot"] is None and r["cmd_accel_rms"] is None and r["clean_success"] is None for r in res["episodes"]
    )
    assert all(r["max_error_m"] is not None for r in res["episodes"])
    for row in res["aggregate"]:
        assert row["success_curve"] is not None and row["success_curve_ci95"] is None
        assert row["max_error_m"]["iqm"] is not None and row["max_error_m"]["p90"] is None
        assert row["max_error_m"]["worst"] == row["max_error_m"]["max"]
    assert "| nnbc |" in summary_markdown(res)


def test_unknown_schemas_and_files_are_refused(tmp_path):
    with pytest.raises(EvalError, match="schema 5.*reads schemas 1, 2, 3, 4"):
        upgrade_results({"schema": 5})
    with pytest.raises(EvalError, match="not a mobman results file"):
        upgrade_results({"episodes": []})
    with pytest.raises(EvalError, match="not found"):
        load_results(tmp_path / "missing.json")
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(EvalError, match="cannot read"):
        load_results(tmp_path / "bad.json")


def test_a_schema_1_sweep_is_read_and_refused_on_resume_as_unknown_code_until_rerun(tmp_path):
    """A sweep of mobman 0.1 still loads (its journal's records parse), but its episodes carry no `code`: the
    code that ran them is unknown, so resuming is refused (one result never mixes two code versions) and
    `rerun_changed` runs them again with this code beside the new seed."""
    from eval.output.provenance import code_hash

    out = tmp_path / "sweep"
    shutil.copytree(FIXTURES / "sweep", out)
    old = [json.loads(line) for line in (out / "episodes.jsonl").read_text().splitlines()]
    assert len(old) == 4 and "steady_max_error_m" not in old[0] and "code" not in old[0]  # before schema 2
    cfg = json.loads((out / "config.json").read_text())
    sweep = SweepConfig.from_dict(
        {
            **{k: cfg[k] for k in ("envs", "policies", "env_kwargs")},
            "dynamics": ["kinematic"],
            "seeds": [10000, 10001, 10002],
        }
    )
    with pytest.raises(EvalError, match="holds 4 episode\\(s\\) run by other code than this: code unknown there"):
        run_sweep(sweep, out, progress=False, plots=False)
    result = run_sweep(sweep, out, rerun_changed=True, progress=False, plots=False)
    assert (result.n_skipped, result.n_run, result.n_left) == (0, 6, 0)
    res = json.loads((out / "results.json").read_text())
    assert res["schema"] == 4 and len(res["episodes"]) == 6 and {r["code"] for r in res["episodes"]} == {code_hash()}
    assert all(r["steady_max_error_m"] is not None for r in res["episodes"])
    for row in res["aggregate"]:
        assert row["n"] == 3 and row["max_error_m"]["iqm"] is not None


def test_settle_time_flag_reaches_the_records(tmp_path):
    from eval.cli import main

    short = '{"path": {"type": "circle", "radius": 0.1, "tilt": 0.5236, "yaw": 3.1416, "duration": 1.0}}'
    args = ["run", "--env", "WheeledPuma-Circle-v0", "--policy", "zero", "--seeds", "1", "--dynamics"]
    args += ["kinematic", "--env-kwargs", short, "--quiet", "--no-plots"]
    for settle in ("0", "0.9"):
        assert main([*args, "--settle-time", settle, "--out", str(tmp_path / settle)]) == 0
    full, late = (json.loads((tmp_path / s / "results.json").read_text()) for s in ("0", "0.9"))
    assert full["statistics"]["settle_time_s"] == 0.0 and late["statistics"]["settle_time_s"] == 0.9
    a, b = full["episodes"][0], late["episodes"][0]
    # zero stays at the start: its error grows along the circle; from t = 0 the steady max is the whole max
    assert a["steady_max_error_m"] == a["max_error_m"]
    assert b["steady_max_error_m"] < a["max_error_m"]  # past 0.9 s the circle is coming back (rest-to-rest)
    assert main([*args, "--settle-time", "-1", "--out", str(tmp_path / "bad")]) == 2  # refused, named
    assert not (tmp_path / "bad").exists()

"""`eval.load_results` (`eval.output.analysis`): results.json files of schema 1, 2 and 3 load, from the file or
its folder, into one DataFrame row per episode with nested values flattened; pandas is optional and its absence
is an error naming the fix; `import eval` stays light."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

import eval
from eval.errors import EvalError
from eval.output.analysis import flatten

ROOT = Path(__file__).resolve().parents[1]
SCHEMA1 = ROOT / "tests/fixtures/schema1/run/results.json"
SCHEMA2 = ROOT / "tests/fixtures/schema2"  # a run folder (results.json inside) of release 0.2


def _schema3(tmp_path: Path) -> Path:
    """Schema 2's file plus the fields release 0.3 adds (DESIGN), as schema 3."""
    data = json.loads((SCHEMA2 / "results.json").read_text())
    data["schema"] = 3
    for r in data["episodes"]:
        r.update(
            cmd_accel_rms=1.5,
            cmd_jerk_rms=20.0,
            limit_margin_min=0.3,
            clean_success=r["success"],
            converge_time_s=None,
            knowledge="none",
            policy_artefacts={"files": ["model.zip"], "sha256": ["ab12"]},
        )
    for a in data["aggregate"]:
        a["max_error_m"] |= {"p90": 0.01, "worst": 0.02}
    path = tmp_path / "results.json"
    path.write_text(json.dumps(data))
    return path


def test_every_schema_loads_one_row_per_episode(tmp_path):
    pytest.importorskip("pandas")
    one, two, three = eval.load_results(SCHEMA1), eval.load_results(SCHEMA2), eval.load_results(_schema3(tmp_path))
    assert (one.schema, two.schema, three.schema) == (1, 2, 3)
    for res in (one, two, three):
        df = res.to_dataframe()
        assert len(df) == len(res.episodes) and list(df["seed"]) == [r["seed"] for r in res.episodes]
        assert {"path.type", "start.x", "axis_max_error_m.z", "max_error_m", "steady_max_error_m"} <= set(df.columns)
        agg = res.aggregate_dataframe()
        assert len(agg) == len(res.aggregate) and "max_error_m.median" in agg.columns
    assert one.to_dataframe()["steady_max_error_m"].isna().all()  # schema 1 lacks it: filled with None
    d3 = three.to_dataframe()
    assert (d3["knowledge"] == "none").all() and d3["cmd_jerk_rms"].eq(20.0).all()
    assert d3["converge_time_s"].isna().all() and list(d3["policy_artefacts.files"][0]) == ["model.zip"]
    assert (three.aggregate_dataframe()["max_error_m.worst"] == 0.02).all()
    two_df = two.to_dataframe()
    first = two.episodes[0]
    assert two_df.loc[0, "axis_max_error_m.y"] == first["axis_max_error_m"][1]
    assert two_df.loc[0, "path.radius"] == first["path"]["radius"]
    agg2 = two.aggregate_dataframe()
    assert agg2.loc[0, "max_error_m.iqm_ci95.high"] == two.aggregate[0]["max_error_m"]["iqm_ci95"][1]
    assert len(agg2.loc[0, "success_curve"]) == 31  # a curve stays one column of lists


def test_flattening_rules():
    rec = {"a": 1, "path": {"type": "circle", "p": {"q": 2}}, "start": [1, 2, 3], "success_rate_ci95": [0.1, 0.9]}
    rec |= {"success_curve": [0.0, 1.0], "start_odd": [1, 2], "axis_max_error_m": None}
    assert flatten(rec) == {
        "a": 1,
        "path.type": "circle",
        "path.p.q": 2,
        "start.x": 1,
        "start.y": 2,
        "start.z": 3,
        "success_rate_ci95.low": 0.1,
        "success_rate_ci95.high": 0.9,
        "success_curve": [0.0, 1.0],
        "start_odd": [1, 2],
        "axis_max_error_m": None,  # a failed episode has none
    }


def test_paths_and_bad_files_fail_naming_the_fix(tmp_path):
    with pytest.raises(EvalError, match="holds no results.json; give the folder of a `mobman-eval run`"):
        eval.load_results(tmp_path)
    (tmp_path / "conditions" / "default").mkdir(parents=True)
    (tmp_path / "conditions" / "default" / "results.json").write_text("{}")
    with pytest.raises(EvalError, match=r"it is a bench: load a condition's file, one of conditions/default/results"):
        eval.load_results(tmp_path)
    with pytest.raises(EvalError, match="not found"):
        eval.load_results(tmp_path / "nothing.json")
    (tmp_path / "new.json").write_text(json.dumps({"schema": 5, "episodes": []}))
    with pytest.raises(EvalError, match="schema 5; this mobman reads schemas 1, 2, 3, 4"):
        eval.load_results(tmp_path / "new.json")


def test_without_pandas_the_error_names_the_extra(monkeypatch):
    res = eval.load_results(SCHEMA1)  # loading needs no pandas
    monkeypatch.setitem(sys.modules, "pandas", None)  # `import pandas` now raises ImportError
    for method in (res.to_dataframe, res.aggregate_dataframe):
        with pytest.raises(ImportError, match=r'need pandas, which is not installed: pip install "mobman\[pandas\]"'):
            method()


def test_import_eval_stays_light():
    code = (
        "import sys, eval; print(sorted(m for m in ('pandas', 'numpy', 'policies', 'mobman_env') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"

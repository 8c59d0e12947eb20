"""One code version per result (issue 34): every episode record carries the hash of the code that ran it
(`code`), and a resumed run, sweep or bench refuses a journal of other code (exit 2, naming both hashes and both
fixes) or, with `--rerun-changed`, runs those episodes again so that the result holds one code hash.

"Other code" is simulated by stamping the first episodes with another hash (`eval.grid.code_hash`, the name the
grid engine stamps and checks with), as a run made before an edit of a controller would have; records written
before the field existed have no `code` key (code unknown). Episodes are kinematic 1 s circles."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml
from test_eval_helpers import ENV, SHORT

import eval.grid as G
from eval.bench import config as BC
from eval.bench.run import run_bench
from eval.cli import main
from eval.errors import EvalError
from eval.output.journal import JOURNAL
from eval.output.provenance import code_hash
from eval.sweep.config import SweepConfig
from eval.sweep.run import run_sweep

#: the hash of "the code before the edit"
OTHER = "0" * 64
GRID = {
    "envs": [ENV],
    "policies": ["zero"],
    "seeds": [10_000, 10_001, 10_002],
    "dynamics": ["kinematic"],
    "model_error": [0.0],
    "obs_noise": [0.0],
    "env_kwargs": SHORT,
}


def _lines(out: Path) -> list[dict]:
    return [json.loads(x) for x in (out / JOURNAL).read_text().splitlines()]


def _codes(results: Path) -> set:
    return {e.get("code") for e in json.loads(results.read_text())["episodes"]}


@pytest.fixture
def sweep_file(tmp_path) -> Path:
    path = tmp_path / "grid.yaml"
    path.write_text(yaml.safe_dump(GRID))
    return path


def _old_sweep(monkeypatch, out: Path, n: int) -> None:
    """`n` episodes of the grid journaled by "the code before the edit"."""
    with monkeypatch.context() as m:
        m.setattr(G, "code_hash", lambda: OTHER)
        run_sweep(SweepConfig.from_dict(GRID), out, max_episodes=n, progress=False, plots=False)
    assert [r["code"] for r in _lines(out)] == [OTHER] * n


def test_code_hash_is_a_sha256_computed_once_and_every_record_carries_it(tmp_path):
    h = code_hash()
    assert len(h) == 64 and int(h, 16) >= 0 and code_hash() is h  # cached: the same object
    res = run_sweep(SweepConfig.from_dict(GRID), tmp_path / "s", progress=False, plots=False)
    assert {e["code"] for e in res.episodes} == {h} and {r["code"] for r in _lines(tmp_path / "s")} == {h}


def test_train_report_keys_its_cache_on_the_same_code_hash():
    import train.report as R

    assert R.code_hash is code_hash and not hasattr(R, "controller_source")


def test_a_sweep_resumed_after_the_code_changed_is_refused_naming_both_hashes_and_both_fixes(
    tmp_path, monkeypatch, sweep_file, capsys
):
    out = tmp_path / "s"
    _old_sweep(monkeypatch, out, 2)
    before = (out / JOURNAL).read_bytes()
    assert main(["sweep", "--config", str(sweep_file), "--out", str(out), "--quiet", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert f"--out '{out}' holds 2 episode(s) run by other code than this: code {OTHER} there, {code_hash()} now" in err
    assert "Use another --out to start over, or pass --rerun-changed to run those 2 episode(s) again" in err
    assert "Traceback" not in err and (out / JOURNAL).read_bytes() == before  # nothing ran, nothing written

    args = ["sweep", "--config", str(sweep_file), "--out", str(out), "--quiet", "--no-plots", "--rerun-changed"]
    assert main(args) == 0
    assert _codes(out / "results.json") == {code_hash()}
    assert len(json.loads((out / "results.json").read_text())["episodes"]) == 3
    assert [r["code"] for r in _lines(out)] == [OTHER, OTHER] + [code_hash()] * 3  # the two ran again, later lines win


def test_records_without_a_code_are_unknown_code_and_refused_the_same_way(tmp_path, monkeypatch, sweep_file, capsys):
    out = tmp_path / "s"
    run_sweep(SweepConfig.from_dict(GRID), out, max_episodes=1, progress=False, plots=False)
    (out / JOURNAL).write_text(
        "".join(json.dumps({k: v for k, v in r.items() if k != "code"}) + "\n" for r in _lines(out))
    )
    assert main(["sweep", "--config", str(sweep_file), "--out", str(out), "--quiet", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert f"code unknown there, {code_hash()} now ('unknown': written before mobman recorded" in err
    assert "--rerun-changed" in err and "another --out" in err
    res = run_sweep(SweepConfig.from_dict(GRID), out, rerun_changed=True, progress=False, plots=False)
    assert res.n_run == 3 and {e["code"] for e in res.episodes} == {code_hash()}


def test_changed_episodes_not_yet_rerun_stay_out_of_the_result(tmp_path, monkeypatch):
    out = tmp_path / "s"
    _old_sweep(monkeypatch, out, 2)
    res = run_sweep(SweepConfig.from_dict(GRID), out, max_episodes=1, rerun_changed=True, progress=False, plots=False)
    assert res.n_run == 1 and res.n_left == 2
    assert [e["seed"] for e in res.episodes] == [10_000] and _codes(out / "results.json") == {code_hash()}


def test_a_bench_with_a_condition_of_other_code_is_refused_before_anything_runs(tmp_path, monkeypatch):
    cfg = BC.BenchConfig(
        robots=("puma",),
        tasks=("circle",),
        conditions=("default", "wear20"),
        policies=("zero",),
        seeds=2,
        env_kwargs=SHORT,
    )
    out = tmp_path / "b"
    with monkeypatch.context() as m:
        m.setattr(G, "code_hash", lambda: OTHER)
        run_bench(cfg, out, max_episodes=3, progress=False, plots=False)  # default whole, wear20 half
    journal = (out / JOURNAL).read_bytes()  # one journal for the whole bench
    bench_json = (out / "bench.json").read_bytes()
    with pytest.raises(EvalError, match=f"holds 3 episode\\(s\\) run by other code than this: code {OTHER} there"):
        run_bench(cfg, out, progress=False, plots=False)
    assert (out / JOURNAL).read_bytes() == journal
    assert (out / "bench.json").read_bytes() == bench_json
    res = run_bench(cfg, out, rerun_changed=True, progress=False, plots=False)
    assert res.n_run == 4 and res.n_left == 0
    assert _codes(out / "results.json") == {code_hash()}


def test_a_run_resumed_after_the_code_changed_is_refused_and_reruns_on_request(tmp_path, monkeypatch, capsys):
    out = tmp_path / "r"
    args = ["run", "--policy", "zero", "--seeds", "2", "--dynamics", "kinematic", "--env-kwargs", json.dumps(SHORT)]
    args += ["--no-plots", "--quiet", "--out", str(out)]
    with monkeypatch.context() as m:
        m.setattr(G, "code_hash", lambda: OTHER)
        assert main(args) == 0
    assert main([*args, "--resume"]) == 2
    err = capsys.readouterr().err
    assert f"holds 2 episode(s) run by other code than this: code {OTHER} there, {code_hash()} now" in err
    assert "another --out" in err and "--rerun-changed" in err
    assert main([*args, "--resume", "--rerun-changed"]) == 0
    assert _codes(out / "results.json") == {code_hash()} and len(_lines(out)) == 4

"""The one JSON reader (`policies.agents.untrusted_json.read_json`) on every entry point that reads a file someone else
may have written: `bench --against`'s scorecard, `eval.load_results`, `mobman-train --resume`'s config.json.
A FIFO must not hang, a symlink to /dev/zero must not grow memory, an oversize or 100,000-deep file must not
raise a traceback, a malformed file is refused naming the field before anything runs, and a scorecard that
names code runs none of it."""

from __future__ import annotations

import copy
import json
import os
import re

import pytest
from test_eval_helpers import SHORT

import eval
from eval.bench import config as BC
from eval.bench.run import run_bench
from eval.cli import main
from eval.errors import EvalError
from policies.agents.untrusted import FileRefused
from policies.agents.untrusted_json import MAX_DEPTH, Int, ListOf, MapOf, Obj, Str, read_json

DEEP = b"[" * 100_000 + b"]" * 100_000


def _damage(path, kind: str, monkeypatch=None, module=None, cap: str = "") -> None:
    """Make `path` a FIFO, a symlink to /dev/zero, an oversize file (the cap `module.cap` lowered to 64 bytes),
    100,000-deep JSON, or bytes that are not UTF-8."""
    if path.exists() or path.is_symlink():
        path.unlink()
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dev_zero":
        path.symlink_to("/dev/zero")
    elif kind == "oversize":
        path.write_text(json.dumps({"padding": "x" * 200}))
        if module is not None:
            monkeypatch.setattr(module, cap, 64)
    elif kind == "deep":
        path.write_bytes(DEEP)
    elif kind == "latin1":
        path.write_bytes('{"a": "\u00e9"}'.encode("latin-1"))


#: what the refusal of each damage says
SAYS = {
    "fifo": "is a FIFO, not a regular file",
    "dev_zero": "is a device, not a regular file",
    "oversize": "bytes; a",
    "deep": f"nested deeper than {MAX_DEPTH} levels",
    "latin1": "not UTF-8 text (byte 7 is 0xe9)",
}
KINDS = list(SAYS)


# --- the reader ---------------------------------------------------------------------------------------------


@pytest.mark.timeout(30)
@pytest.mark.parametrize("kind", KINDS)
def test_read_json_refuses_what_is_not_a_small_regular_json_file(tmp_path, kind):
    f = tmp_path / "x.json"
    _damage(f, kind)
    with pytest.raises(FileRefused, match=re.escape(SAYS[kind])):
        read_json(f, 64 if kind == "oversize" else 2**20, "test file")


def test_read_json_checks_the_shape_naming_the_field_found_and_expected(tmp_path):
    schema = Obj({"rows": ListOf(Obj({"n": Int, "policy": Str}))})
    f = tmp_path / "x.json"
    f.write_text(json.dumps({"rows": [{"n": 1, "policy": "qp"}, {"n": "abc", "policy": "qp"}]}))
    with pytest.raises(FileRefused, match=r"x.json: rows\[1\].n is the string 'abc'; expected an integer"):
        read_json(f, 2**20, "test file", schema)
    f.write_text(json.dumps({"rows": "qp"}))
    with pytest.raises(FileRefused, match=r"rows is the string 'qp'; expected a list \(of an object with the keys"):
        read_json(f, 2**20, "test file", schema)
    f.write_text(json.dumps({"rows": [{"n": True, "policy": "qp"}]}))  # a boolean is not an integer
    with pytest.raises(FileRefused, match=r"rows\[0\].n is the boolean true; expected an integer"):
        read_json(f, 2**20, "test file", schema)
    f.write_text(json.dumps({"row": []}))
    with pytest.raises(FileRefused, match=r"rows is missing; expected a list"):
        read_json(f, 2**20, "test file", schema)
    f.write_text(json.dumps({"rows": [], "by": {"\x1b[2J": 1}}))  # a key is quoted: no raw escape in a message
    with pytest.raises(FileRefused, match=re.escape("by['\\x1b[2J'] is the number 1; expected a list")):
        read_json(f, 2**20, "test file", Obj({"rows": ListOf(Int)}, {"by": MapOf(ListOf(Int))}))
    nested: list = []
    for _ in range(MAX_DEPTH):  # [] wrapped 32 times: 33 deep; parses, but deeper than any mobman file
        nested = [nested]
    f.write_text(json.dumps(nested))
    with pytest.raises(FileRefused, match=rf"nested {MAX_DEPTH + 1} levels deep; at most {MAX_DEPTH}"):
        read_json(f, 2**20, "test file")


# --- bench --against ----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def committed(tmp_path_factory):
    """A small committed bench (zero on the default condition's circle, 2 seeds) and its scorecard dict."""
    out = tmp_path_factory.mktemp("committed")
    cfg = BC.BenchConfig(
        robots=("puma",), tasks=("circle",), conditions=("default",), policies=("zero",), seeds=2, env_kwargs=SHORT
    )
    run_bench(cfg, out, progress=False, plots=False)
    return json.loads((out / "scorecard.json").read_text())


AGAINST = ["bench", "--robots", "puma", "--tasks", "circle", "--conditions", "default", "--quiet", "--no-plots"]


def _against(tmp_path, scorecard, *policy: str) -> list[str]:
    pol = [a for p in (policy or ("jmpi",)) for a in ("--policy", p)]
    return [*AGAINST, "--against", str(scorecard), *pol, "--out", str(tmp_path / "mine")]


@pytest.mark.timeout(60)
@pytest.mark.parametrize("kind", KINDS)
def test_bench_against_refuses_a_damaged_scorecard(tmp_path, monkeypatch, capsys, kind):
    import eval.schemas as S

    sc = tmp_path / "scorecard.json"
    sc.write_text("{}")
    _damage(sc, kind, monkeypatch, S, "MAX_SCORECARD_BYTES")
    assert main(_against(tmp_path, sc)) == 2
    err = capsys.readouterr().err
    assert SAYS[kind] in err and "Traceback" not in err
    assert not (tmp_path / "mine").exists()


def _write(tmp_path, data: dict):
    (tmp_path / "c").mkdir(exist_ok=True)
    (tmp_path / "c" / "scorecard.json").write_text(json.dumps(data))
    return tmp_path / "c"


@pytest.mark.timeout(120)
def test_bench_against_a_scorecard_naming_code_runs_none_of_it(tmp_path, committed, capsys):
    """A scorecard whose protocol.policies and one sample name `os:system:command=touch PWNED` ran the command
    (the baselines' samples are run again here); it is refused before anything runs, naming the entry."""
    pwned = tmp_path / "PWNED"
    spec = f"os:system:command=touch {pwned}"
    data = copy.deepcopy(committed)
    data["protocol"]["policies"].append(spec)
    data["samples"].append({**data["samples"][0], "policy": spec})
    assert main(_against(tmp_path, _write(tmp_path, data))) == 2
    err = capsys.readouterr().err
    assert f"protocol.policies[1] = {spec!r} names code; a scorecard may name only built-in controllers" in err
    assert "run your own controller with --policy on the command line" in err and "Traceback" not in err
    assert not pwned.exists() and not (tmp_path / "mine").exists()


@pytest.mark.timeout(120)
def test_bench_against_a_scorecard_naming_a_module_env_id_imports_nothing(tmp_path, committed, capsys, monkeypatch):
    """`gym.make("evilmod:Env-v0")` imports evilmod: a sample's env must be a registered id."""
    (tmp_path / "evilmod_sc.py").write_text(f"open({str(tmp_path / 'PWNED')!r}, 'w').close()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    data = copy.deepcopy(committed)
    data["samples"][0]["env"] = "evilmod_sc:Env-v0"
    assert main(_against(tmp_path, _write(tmp_path, data))) == 2
    err = capsys.readouterr().err
    assert "samples[0].env = 'evilmod_sc:Env-v0' is not a registered env id" in err and "Traceback" not in err
    assert not (tmp_path / "PWNED").exists()


def test_bench_against_accepts_the_users_own_controller_in_the_scorecard(tmp_path, committed):
    """A controller the command line names is the user's own: the committed file may name it too (it is run by
    the bench from the command line, never from the file)."""
    from eval.schemas import check_scorecard_names

    data = copy.deepcopy(committed)
    data["protocol"]["policies"].append("mymod:Ctrl")
    check_scorecard_names(data, "scorecard.json", typed=("mymod:Ctrl",))
    with pytest.raises(EvalError, match=r"protocol.policies\[1\] = 'mymod:Ctrl' names code"):
        check_scorecard_names(data, "scorecard.json")


def _del(d: dict, key: str) -> None:
    del d[key]


@pytest.mark.timeout(120)
@pytest.mark.parametrize(
    "edit, says",
    [
        (lambda d: _del(d, "samples"), "samples is missing; expected a list (of an object with the keys condition"),
        (lambda d: d["rows"][0].update(n="abc"), "rows[0].n is the string 'abc'; expected an integer"),
        (lambda d: d["protocol"].update(policies="zero"), "protocol.policies is the string 'zero'; expected a list"),
        (lambda d: d["samples"][0].update(seed=None), "samples[0].seed is null; expected an integer"),
        (lambda d: d.update(pooled={"a": 1}), "pooled is an object with 1 keys; expected a list"),
        (lambda d: d["rows"][0].pop("n_failed"), "rows[0].n_failed is missing; expected an integer"),
    ],
)
def test_bench_against_a_malformed_scorecard_is_refused_before_anything_runs(tmp_path, committed, capsys, edit, says):
    data = copy.deepcopy(committed)
    edit(data)
    assert main(_against(tmp_path, _write(tmp_path, data))) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err
    assert not (tmp_path / "mine").exists()  # nothing ran


# --- eval.load_results --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def results(tmp_path_factory) -> dict:
    out = tmp_path_factory.mktemp("run")
    args = ["run", "--policy", "zero", "--seeds", "1", "--dynamics", "kinematic", "--quiet", "--no-plots"]
    assert main([*args, "--env-kwargs", json.dumps(SHORT), "--out", str(out / "o"), "--overwrite"]) == 0
    return json.loads((out / "o" / "results.json").read_text())


@pytest.mark.timeout(30)
@pytest.mark.parametrize("kind", KINDS)
def test_load_results_refuses_a_damaged_file(tmp_path, monkeypatch, kind):
    import eval.schemas as S

    f = tmp_path / "results.json"
    _damage(f, kind, monkeypatch, S, "MAX_RESULTS_BYTES")
    with pytest.raises(EvalError, match=re.escape(SAYS[kind])):
        eval.load_results(tmp_path)  # the folder: analysis's reader
    with pytest.raises(EvalError, match=re.escape(SAYS[kind])):
        eval.load_results(f)


@pytest.mark.parametrize(
    "edit, says",
    [
        (lambda d: d.update(episodes="none"), "episodes is the string 'none'; expected a list"),
        (lambda d: d["episodes"][0].update(policy=3), "episodes[0].policy is the number 3; expected a string"),
        (lambda d: d["aggregate"][0].update(n="1"), "aggregate[0].n is the string '1'; expected an integer"),
        (lambda d: d.update(schema=1, episodes=[[1]]), "episodes[0] is a list of 1 items; expected an object"),
    ],
)
def test_load_results_refuses_a_malformed_file_naming_the_field(tmp_path, results, edit, says):
    data = copy.deepcopy(results)
    edit(data)
    (tmp_path / "results.json").write_text(json.dumps(data))
    with pytest.raises(EvalError, match=f"results.json: {says}".replace("[", r"\[").replace("]", r"\]")):
        eval.load_results(tmp_path)


# --- mobman-train --resume ------------------------------------------------------------------------------------


@pytest.mark.timeout(60)
@pytest.mark.parametrize("kind", KINDS)
def test_train_resume_refuses_a_damaged_config_json(tmp_path, monkeypatch, capsys, kind):
    pytest.importorskip("stable_baselines3")
    from test_train import _fake_run_folder

    import train.runfolder as R
    from train.cli import main as train_main

    out = _fake_run_folder(tmp_path)
    _damage(out / "config.json", kind, monkeypatch, R, "MAX_RUN_JSON_BYTES")
    assert train_main(["--resume", str(out)]) == 2
    err = capsys.readouterr().err
    assert "config.json is not a readable JSON file" in err and SAYS[kind] in err and "Traceback" not in err


# --- the other readers: a sweep's record and journal, an agent's config.json ---------------------------------


@pytest.mark.timeout(120)
@pytest.mark.parametrize("name", ["config.json", "episodes.jsonl"])
def test_a_sweep_folder_whose_record_or_journal_is_a_fifo_is_refused(tmp_path, capsys, name):
    """Resuming a sweep whose config.json or episodes.jsonl is a FIFO hung (reading it, or opening the journal
    for appending); both are refused, naming the file."""
    import yaml

    spec = {"envs": ["WheeledPuma-Circle-v0"], "policies": ["zero"], "seeds": {"start": 10_000, "count": 1}}
    (tmp_path / "s.yaml").write_text(yaml.safe_dump({**spec, "dynamics": ["kinematic"], "env_kwargs": SHORT}))
    args = ["sweep", "--config", str(tmp_path / "s.yaml"), "--out", str(tmp_path / "o"), "--quiet", "--no-plots"]
    assert main(args) == 0
    _damage(tmp_path / "o" / name, "fifo")
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert f"{name} is " in err and "not a regular file" in err and "Traceback" not in err


@pytest.mark.timeout(60)
@pytest.mark.parametrize("kind", ["fifo", "dev_zero", "deep"])
def test_an_agents_config_json_is_read_by_the_one_reader(tmp_path, kind):
    import shutil

    import gymnasium as gym

    import policies

    pytest.importorskip("stable_baselines3")
    d = tmp_path / "agent"
    shutil.copytree(policies.resolve_model_path("sac-circle").parent, d)
    _damage(d / "config.json", kind)
    env = gym.make("WheeledPuma-Circle-v0")
    try:
        with pytest.raises(ValueError, match=re.escape(SAYS[kind])):
            policies.make(f"sb3:{d}", env)
    finally:
        env.close()

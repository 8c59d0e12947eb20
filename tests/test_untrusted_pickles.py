"""The restricted unpickler (`policies.agents.untrusted`): a family of crafted pickles is refused on every path that
reads SB3 files (model.zip entries, VecNormalize statistics, training checkpoints), at protocols 2 to 5 and
with both GLOBAL and STACK_GLOBAL, and legitimate data pickled at the same protocols still loads.

The crafted pickles are written opcode by opcode (a few dozen bytes each): a tree of calls whose leaves are
strings and (module, name) globals. Each would run `touch MARKER` through a plain `pickle.loads`.
"""

from __future__ import annotations

import base64
import json
import pickle
import shutil
import struct
import subprocess
import sys
import zipfile
from collections import OrderedDict, deque

import numpy as np
import pytest

from policies.agents.sb3_files import load_vecnormalize_stats, safe_custom_objects
from policies.agents.untrusted import ALLOWED_CHECKPOINT, ALLOWED_MODEL, UnsafePickleError, load_pickle


def G(module: str, name: str) -> tuple:
    return ("global", module, name)


def C(fn, *args) -> tuple:
    return ("call", fn, *args)


def _emit(node, stack_global: bool) -> bytes:
    if isinstance(node, str):
        raw = node.encode()
        return b"X" + struct.pack("<I", len(raw)) + raw  # BINUNICODE
    if node[0] == "global":
        _, module, name = node
        if stack_global:
            return _emit(module, True) + _emit(name, True) + b"\x93"  # STACK_GLOBAL
        return b"c" + f"{module}\n{name}\n".encode()  # GLOBAL
    fn, *args = node[1:]
    return _emit(fn, stack_global) + b"(" + b"".join(_emit(a, stack_global) for a in args) + b"tR"  # MARK TUPLE REDUCE


def crafted(node, proto: int, stack_global: bool) -> bytes:
    return b"\x80" + bytes([proto]) + _emit(node, stack_global) + b"."


def payloads(cmd: str) -> dict[str, tuple]:
    code = f"__import__('os').system({cmd!r})"
    return {
        # the report's 120 bytes: a dotted name under an allowed numpy.random module reaches eval
        "dotted __builtins__.get": C(C(G("numpy.random", "__builtins__.get"), "eval"), code),
        "dotted, another numpy.random module": C(C(G("numpy.random._pickle", "__builtins__.get"), "exec"), code),
        "dotted on an allowed class": C(G("collections", "OrderedDict.fromkeys.__self__"), "ab"),
        "a module's __builtins__": C(G("numpy.random._pickle", "__builtins__"), "eval"),
        "builtins.eval": C(G("builtins", "eval"), code),
        "python 2 name of eval": C(G("__builtin__", "eval"), code),
        "getattr chain": C(C(G("builtins", "getattr"), C(G("builtins", "__import__"), "os"), "system"), cmd),
        "operator.attrgetter": C(
            C(C(G("operator", "attrgetter"), "system"), C(G("importlib", "import_module"), "os")), cmd
        ),
        "functools.partial": C(C(G("functools", "partial"), G("os", "system"), cmd)),
        "os.system": C(G("os", "system"), cmd),
        "posix.system": C(G("posix", "system"), cmd),
        "subprocess.getoutput": C(G("subprocess", "getoutput"), cmd),
    }


#: (protocol, STACK_GLOBAL?): GLOBAL at every protocol, STACK_GLOBAL from protocol 4 on
OPCODES = [(2, False), (3, False), (4, False), (4, True), (5, False), (5, True)]
PAYLOADS = list(payloads("true"))


def _model_entry(blob: bytes, tmp_path) -> None:
    safe_custom_objects({"observation_space": {":serialized:": base64.b64encode(blob).decode()}}, tmp_path / "m.zip")


def _stats_file(blob: bytes, tmp_path) -> None:
    (tmp_path / "vecnormalize.pkl").write_bytes(blob)
    load_vecnormalize_stats(tmp_path / "vecnormalize.pkl")


def _checkpoint(blob: bytes, tmp_path) -> None:
    try:
        load_pickle(blob, ALLOWED_CHECKPOINT, what="a checkpoint")
    except UnsafePickleError as exc:
        raise ValueError(str(exc)) from None


READERS = {"model.zip entry": _model_entry, "vecnormalize.pkl": _stats_file, "checkpoint": _checkpoint}


@pytest.mark.parametrize("reader", list(READERS))
@pytest.mark.parametrize("proto, stack_global", OPCODES)
@pytest.mark.parametrize("payload", PAYLOADS)
def test_crafted_pickle_is_refused_and_runs_nothing(tmp_path, payload, proto, stack_global, reader):
    marker = tmp_path / "pwned"
    blob = crafted(payloads(f"touch {marker}")[payload], proto, stack_global)
    with pytest.raises(ValueError, match=r"refused to load \S+"):
        READERS[reader](blob, tmp_path)
    assert not marker.exists()


def test_the_crafted_pickles_do_run_code_when_unpickled_plainly(tmp_path):
    """The family is real: plain pickle runs the command of each payload that calls one."""
    harmless = {"dotted on an allowed class", "a module's __builtins__"}
    for i, name in enumerate(PAYLOADS):
        if name in harmless:
            continue
        node = payloads(f"touch {tmp_path}/ran-{i}")[name]
        pickle.loads(crafted(node, 2, False) if name.startswith("python 2") else crafted(node, 4, True))
        assert (tmp_path / f"ran-{i}").exists(), name


def _legit_objects():
    import gymnasium as gym
    import torch
    from stable_baselines3.common.policies import MultiInputActorCriticPolicy
    from stable_baselines3.sac.policies import MultiInputPolicy

    space = gym.spaces.Dict(
        {"ee_pos": gym.spaces.Box(-2.0, 2.0, (3,), np.float32), "joint_pos": gym.spaces.Box(-1e5, 1e5, (8,))}
    )
    space.seed(7)
    space.sample()  # a used random state
    return {
        "observation_space": space,
        "policy_class": MultiInputPolicy,
        "policy_class_pg": MultiInputActorCriticPolicy,
        "policy_kwargs": {
            "net_arch": {"pi": [64, 64], "vf": [64, 64]},
            "activation_fn": torch.nn.ReLU,
            "optimizer_class": torch.optim.Adam,
            "optimizer_kwargs": {"eps": 1e-5},
        },
        "data": OrderedDict(a=np.arange(4, dtype=np.int64), b=np.float32(1.5), c=deque([1.0, 2.0], maxlen=3), d={1, 2}),
    }


@pytest.mark.parametrize("proto", [2, 3, 4, 5])
def test_legitimate_entries_load_at_every_protocol(proto):
    import cloudpickle

    for name, obj in _legit_objects().items():
        for dumps in (pickle.dumps, cloudpickle.dumps):
            got = load_pickle(dumps(obj, protocol=proto), ALLOWED_MODEL)
            if name == "observation_space":
                assert got == obj and got.sample()["ee_pos"].tolist() == obj.sample()["ee_pos"].tolist()
            elif name == "data":
                assert list(got) == list(obj) and got["a"].tolist() == [0, 1, 2, 3] and got["c"].maxlen == 3
                assert got["b"] == np.float32(1.5) and got["d"] == {1, 2}
            else:
                assert got == obj


@pytest.mark.filterwarnings("ignore:numpy.core.*is deprecated:DeprecationWarning")  # numpy 1.x names, still listed
def test_every_allowed_pair_exists_here():
    """The allow-list names real objects (a typo would refuse a legitimate file), and none is a builtin
    that runs code."""
    import importlib

    for module, name in sorted(ALLOWED_CHECKPOINT):
        assert "." not in name
        getattr(importlib.import_module(module), name)
    assert not {p for p in ALLOWED_CHECKPOINT if p[0] in ("builtins", "os", "posix", "operator", "functools")} - {
        ("builtins", n) for n in ("set", "frozenset", "slice", "complex")
    }


def _crafted_model_dir(tmp_path, marker):
    """The shipped SAC with the report's pickle in its observation_space entry."""
    import policies

    src = policies.agents.sb3.MODELS_DIR / "sac-circle"
    d = shutil.copytree(src, tmp_path / "crafted")
    with zipfile.ZipFile(src / "model.zip") as zf:
        entries = {n: zf.read(n) for n in zf.namelist()}
    data = json.loads(entries["data"])
    blob = crafted(payloads(f"touch {marker}")["dotted __builtins__.get"], 4, True)
    data["observation_space"][":serialized:"] = base64.b64encode(blob).decode()
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(d / "model.zip", "w") as zf:
        for name, raw in entries.items():
            zf.writestr(name, raw)
    return d


def test_crafted_model_zip_is_refused_by_mobman_eval_run(tmp_path):
    pytest.importorskip("stable_baselines3")
    marker = tmp_path / "pwned"
    d = _crafted_model_dir(tmp_path, marker)
    out = subprocess.run(
        [sys.executable, "-m", "eval", "run", "--policy", f"sb3:{d}", "--seeds", "1", "--out", str(tmp_path / "o")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 2, out.stderr
    assert "refused to load numpy.random.__builtins__.get (a dotted name" in out.stderr
    assert "trust" in out.stderr and "Traceback" not in out.stderr
    assert not marker.exists()


@pytest.mark.parametrize("part", ["vecnormalize", "replay_buffer", "model"])
def test_crafted_checkpoint_is_refused_by_resume_and_changes_nothing(tmp_path, capsys, part):
    pytest.importorskip("stable_baselines3")
    from test_train import _fake_run_folder

    from train.cli import main

    out = _fake_run_folder(tmp_path)
    marker = tmp_path / "pwned"
    blob = crafted(payloads(f"touch {marker}")["dotted __builtins__.get"], 5, True)
    entry = {"steps": 100, "model": "model_100_steps.zip", "vecnormalize": None, "replay_buffer": None}
    data: dict = {}
    if part == "model":
        data["lr_schedule"] = {":serialized:": base64.b64encode(blob).decode()}
    else:
        entry[part] = f"{part}_100_steps.pkl"
        (out / "checkpoints" / entry[part]).write_bytes(blob)
    with zipfile.ZipFile(out / "checkpoints" / entry["model"], "w") as zf:
        zf.writestr("data", json.dumps(data))
    (out / "checkpoints" / "latest.json").write_text(json.dumps(entry))
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert main(["--resume", str(out), "--timesteps", "200"]) == 2
    err = capsys.readouterr().err
    assert "refused to load numpy.random.__builtins__.get (a dotted name" in err and "trust" in err, err
    assert "Traceback" not in err and not marker.exists()
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_train_help_says_what_to_trust(capsys):
    from train.cli import main as train_main
    from train.report_cli import main as report_main

    for main, argv in ((train_main, ["--help"]), (report_main, ["--help"])):
        with pytest.raises(SystemExit):
            main(argv)
        text = " ".join(capsys.readouterr().out.split())
        assert "only" in text and "you trust" in text and "restricted unpickler" in text

"""Compact storage (`eval.output.compact`, `policies.agents.untrusted_json.read_json`): a JSON file stored as FILE.xz
reads back byte for byte, by every reader, with the same caps; the committed compacted scorecards hold the bytes
of the files they replaced (their git blob ids are those in the history)."""

from __future__ import annotations

import hashlib
import json
import lzma
import subprocess
from pathlib import Path

import pytest

import eval
from eval.bench.scorecard import READABLE_SCHEMAS as SCORECARD_SCHEMAS
from eval.bench.scorecard import load_scorecard
from eval.cli import main
from eval.errors import EvalError
from eval.output.compact import compact, git_blob_id, stored_bytes
from eval.output.results import READABLE_SCHEMAS, load_results
from policies.agents.untrusted import FileRefused
from policies.agents.untrusted_json import read_json

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
MANIFEST = json.loads((RESULTS / "compacted.json").read_text())


def _write(path: Path, value) -> bytes:
    data = (json.dumps(value, indent=2) + "\n").encode()
    path.write_bytes(data)
    return data


def test_a_compacted_file_reads_back_byte_for_byte_in_place_of_the_original(tmp_path):
    value = {"schema": 4, "rows": [{"x": 0.1 + 0.2, "y": 1e-17, "n": 3}] * 50}
    data = _write(tmp_path / "r.json", value)
    rec = compact(tmp_path / "r.json")
    assert not (tmp_path / "r.json").exists() and (tmp_path / "r.json.xz").is_file()
    assert rec == {
        "file": "r.json",
        "bytes": len(data),
        "xz_bytes": (tmp_path / "r.json.xz").stat().st_size,
        "sha256": hashlib.sha256(data).hexdigest(),
        "git_blob": git_blob_id(data),
    }
    assert rec["xz_bytes"] < len(data) / 5
    assert stored_bytes(tmp_path / "r.json") == data
    assert read_json(tmp_path / "r.json", 1 << 20, "results file") == value  # the name of the original
    assert read_json(tmp_path / "r.json.xz", 1 << 20, "results file") == value  # or of the twin
    again = tmp_path / "again"
    again.mkdir()
    _write(again / "r.json", value)
    compact(again / "r.json")
    assert (again / "r.json.xz").read_bytes() == (tmp_path / "r.json.xz").read_bytes()  # deterministic


def test_git_blob_id_is_gits(tmp_path):
    data = b'{"a": 1}\n'
    (tmp_path / "f").write_bytes(data)
    out = subprocess.run(["git", "hash-object", str(tmp_path / "f")], capture_output=True, text=True, check=True)
    assert git_blob_id(data) == out.stdout.strip()


def test_compact_refuses_and_keeps_what_is_there(tmp_path):
    _write(tmp_path / "a.json", {"a": 1})
    (tmp_path / "a.json.xz").write_bytes(b"mine")
    with pytest.raises(EvalError, match=r"a\.json\.xz exists already; remove it"):
        compact(tmp_path / "a.json")
    assert (tmp_path / "a.json").is_file() and (tmp_path / "a.json.xz").read_bytes() == b"mine"
    (tmp_path / "b.json").write_text("{not json")
    with pytest.raises(EvalError, match=r"cannot compact .*b\.json: .*not valid JSON"):
        compact(tmp_path / "b.json")
    assert (tmp_path / "b.json").read_text() == "{not json"
    with pytest.raises(EvalError, match="already compacted"):
        compact(tmp_path / "a.json.xz")
    with pytest.raises(EvalError, match="no such file"):
        compact(tmp_path / "c.json")


def test_an_xz_bomb_a_cut_stream_and_a_non_xz_file_are_refused_by_the_cap_not_after_it(tmp_path):
    bomb = tmp_path / "s.json.xz"
    bomb.write_bytes(lzma.compress(b" " * (8 << 20) + b"{}", format=lzma.FORMAT_XZ))
    assert bomb.stat().st_size < 4096
    with pytest.raises(FileRefused, match=r"unpacks to more than 1048576 bytes; a scorecard is at most that"):
        read_json(tmp_path / "s.json", 1 << 20, "scorecard")
    whole = lzma.compress(b'{"a": 1}', format=lzma.FORMAT_XZ)
    bomb.write_bytes(whole[: len(whole) - 8])
    with pytest.raises(FileRefused, match="cut short|not a valid xz file"):
        read_json(tmp_path / "s.json", 1 << 20, "scorecard")
    bomb.write_bytes(b"plain text, not an xz stream at all")
    with pytest.raises(FileRefused, match="not a valid xz file"):
        read_json(tmp_path / "s.json", 1 << 20, "scorecard")


def test_the_compact_command_writes_the_manifest_and_refuses_with_exit_2(tmp_path, capsys):
    data = _write(tmp_path / "scorecard.json", {"k": [1.5] * 100})
    assert main(["compact", str(tmp_path / "scorecard.json"), "--manifest", str(tmp_path / "m.json")]) == 0
    assert "scorecard.json -> scorecard.json.xz" in capsys.readouterr().out
    m = json.loads((tmp_path / "m.json").read_text())
    assert m["scorecard.json"]["sha256"] == hashlib.sha256(data).hexdigest()
    assert main(["compact", str(tmp_path / "missing.json")]) == 2
    assert "missing.json: no such file" in capsys.readouterr().err


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_each_committed_compacted_file_holds_the_bytes_it_replaced(name):
    rec = MANIFEST[name]
    assert not (RESULTS / name).exists(), f"{name} is committed twice (plain and compacted)"
    data = stored_bytes(RESULTS / name)
    assert len(data) == rec["bytes"] and (RESULTS / f"{name}.xz").stat().st_size == rec["xz_bytes"]
    assert hashlib.sha256(data).hexdigest() == rec["sha256"]
    assert git_blob_id(data) == rec["git_blob"]
    if name.startswith("bench-v2"):  # protocol v2 on (bench-v1 is a schema `load_scorecard` no longer reads)
        assert load_scorecard(RESULTS / name)["rows"]
        assert load_scorecard(RESULTS / name) == load_scorecard((RESULTS / name).parent / "scorecard.json.xz")


@pytest.mark.parametrize("name", sorted(MANIFEST))
def test_a_compacted_file_reads_as_its_original(name, tmp_path):
    """Every reader gives the same from the compacted file as from the original bytes (the old form, written back):
    the JSON reader for every file, `load_results` and `eval.load_results` (of the file and of its folder) for a
    results file, `load_scorecard` for a scorecard it reads (schema 3 or 4): no value moved in the conversion."""
    old = tmp_path / "old" / Path(name).name
    old.parent.mkdir()
    old.write_bytes(stored_bytes(RESULTS / name))
    assert hashlib.sha256(old.read_bytes()).hexdigest() == MANIFEST[name]["sha256"]
    new = RESULTS / name
    value = read_json(new, 1 << 30, "file")
    assert value == read_json(old, 1 << 30, "file") == read_json(RESULTS / f"{name}.xz", 1 << 30, "file")
    if old.name == "results.json" and value.get("schema") in READABLE_SCHEMAS:
        assert load_results(new) == load_results(old)
        folder, plain = eval.load_results(new.parent), eval.load_results(old.parent)
        assert folder.episodes == plain.episodes and folder.aggregate == plain.aggregate
    if old.name == "scorecard.json" and value.get("schema") in SCORECARD_SCHEMAS:
        assert load_scorecard(new) == load_scorecard(old)


def test_the_committed_originals_are_in_the_history():
    """A compacted file whose original was committed (bench-v1 and the three protocol-v2 scorecards) names that
    original's blob, which the history holds; one compacted before its first commit (bench-v3-dev) has only its
    SHA-256 check above. An unpacked sdist has no history: there the test checks that it is one (PKG-INFO)."""
    assert all(len(rec["git_blob"]) == 40 and int(rec["git_blob"], 16) >= 0 for rec in MANIFEST.values())
    if not (ROOT / ".git").exists():
        assert (ROOT / "PKG-INFO").is_file(), "neither a git checkout nor an unpacked sdist"
        return
    git = ["git", "-C", str(ROOT)]
    shallow = subprocess.run([*git, "rev-parse", "--is-shallow-repository"], capture_output=True, text=True)
    if shallow.stdout.strip() == "true":
        subprocess.run([*git, "fetch", "--unshallow", "--quiet"], check=True)
    committed = []
    for name, rec in MANIFEST.items():
        log = subprocess.run([*git, "log", "--format=%H", "--", f"docs/results/{name}"], capture_output=True, text=True)
        if log.stdout.strip():
            committed.append(name)
            assert subprocess.run([*git, "cat-file", "-e", rec["git_blob"]]).returncode == 0, f"{name}: not in history"
    assert {"bench-v1/scorecard.json", "bench-v2-dev/scorecard.json"} <= set(committed)

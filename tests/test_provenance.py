"""Provenance names the code (issue 39, item 5): a dirty tree's provenance carries the SHA-256 of its
uncommitted diff and the changed paths, and `provenance_class` tells clean, dirty with a named diff, and dirty
unnamed apart. The git functions run on a throwaway repository (`eval.output.provenance.ROOT` pointed at it)."""

from __future__ import annotations

import hashlib
import subprocess
from pathlib import Path

import pytest

import eval.output.provenance as P

SHA1 = "a" * 40
SHA256 = "b" * 64


@pytest.mark.parametrize(
    "prov, expected",
    [
        ({"git": SHA1}, P.CLEAN),
        (SHA1, P.CLEAN),  # the bare `git` string of a file without a provenance
        ({"git": SHA1, "diff": None}, P.CLEAN),
        ({"git": SHA1 + "-dirty", "diff": {"sha256": SHA256, "paths": ["eval/x.py"]}}, P.DIRTY_NAMED),
        ({"git": SHA1 + "-dirty"}, P.DIRTY_UNNAMED),  # every committed file before provenance schema 4
        ({"git": SHA1 + "-dirty", "diff": None}, P.DIRTY_UNNAMED),
        ({"git": SHA1 + "-dirty", "diff": {"sha256": SHA256, "paths": []}}, P.DIRTY_UNNAMED),
        ({"git": SHA1 + "-dirty", "diff": {"sha256": "b" * 63, "paths": ["eval/x.py"]}}, P.DIRTY_UNNAMED),
        ({"git": SHA1 + "-dirty", "diff": {"sha256": SHA256, "paths": [1]}}, P.DIRTY_UNNAMED),
        ({"git": SHA1 + "-dirty", "diff": {"paths": ["eval/x.py"]}}, P.DIRTY_UNNAMED),
        ({"git": "unknown"}, P.DIRTY_UNNAMED),
        ({"git": "6b8f08d608a8"}, P.DIRTY_UNNAMED),  # a short revision names no tree for sure
        ({"git": SHA1.upper()}, P.DIRTY_UNNAMED),
        ({}, P.DIRTY_UNNAMED),
        (None, P.DIRTY_UNNAMED),
        ([SHA1], P.DIRTY_UNNAMED),
    ],
)
def test_provenance_class_of_constructed_provenances(prov, expected):
    assert P.provenance_class(prov) == expected


def _git(repo: Path, *args: str) -> str:
    cmd = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false", *args]
    return subprocess.run(cmd, cwd=repo, check=True, capture_output=True, text=True).stdout


@pytest.fixture
def repo(tmp_path, monkeypatch) -> Path:
    """A git repository holding the four packages, one file committed; the provenance functions look at it."""
    for name in ("mobman_env", "policies", "eval", "train"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text(f"# {name}\n")
    (tmp_path / "notes.txt").write_text("outside the packages\n")
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "add", ".")
    _git(tmp_path, "commit", "-qm", "first")
    P.code_hash()  # cached from mobman's own tree before ROOT is pointed elsewhere
    monkeypatch.setattr(P, "ROOT", tmp_path)
    return tmp_path


def test_a_clean_tree_has_no_diff_and_its_provenance_is_clean(repo):
    assert P.git_rev() == _git(repo, "rev-parse", "HEAD").strip()
    assert P.tree_diff() is None
    assert P.provenance_class({"git": P.git_rev(), "diff": P.tree_diff()}) == P.CLEAN


def test_a_dirty_tree_names_its_diff_by_hash_and_its_changed_paths(repo):
    (repo / "eval" / "__init__.py").write_text("# eval, edited\n")
    (repo / "policies" / "mine.py").write_text("X = 1\n")  # untracked, under a package
    (repo / "scratch.txt").write_text("untracked, outside the packages\n")
    assert P.git_rev().endswith("-dirty")
    diff = P.tree_diff()
    assert diff is not None and diff["paths"] == ["eval/__init__.py", "policies/mine.py"]
    patch = subprocess.run(["git", "diff", "HEAD", "--binary"], cwd=repo, capture_output=True, check=True).stdout
    h = hashlib.sha256(patch)
    h.update(f"\0untracked policies/mine.py {hashlib.sha256(b'X = 1' + bytes([10])).hexdigest()}".encode())
    assert diff["sha256"] == h.hexdigest()  # reproducible by whoever holds the same tree
    assert P.provenance_class({"git": P.git_rev(), "diff": diff}) == P.DIRTY_NAMED

    (repo / "policies" / "mine.py").write_text("X = 2\n")  # another untracked content: another hash
    assert P.tree_diff()["sha256"] != diff["sha256"]


def test_an_untracked_module_alone_makes_the_tree_dirty(repo):
    (repo / "train" / "new.py").write_text("pass\n")
    assert P.git_rev().endswith("-dirty") and P.tree_diff()["paths"] == ["train/new.py"]


def test_provenance_of_a_dirty_tree_is_dirty_with_a_named_diff(repo):
    (repo / "mobman_env" / "__init__.py").write_text("# changed\n")
    prov = P.provenance()
    assert prov["schema"] == P.PROVENANCE_SCHEMA == 4
    assert prov["git"].endswith("-dirty") and prov["diff"]["paths"] == ["mobman_env/__init__.py"]
    assert prov["code"] == P.code_hash() and P.provenance_class(prov) == P.DIRTY_NAMED


def test_no_git_is_unknown_and_unnamed(tmp_path, monkeypatch):
    monkeypatch.setattr(P, "ROOT", tmp_path)  # not a repository
    assert P.git_rev() == "unknown" and P.tree_diff() is None
    assert P.provenance_class({"git": P.git_rev(), "diff": P.tree_diff()}) == P.DIRTY_UNNAMED

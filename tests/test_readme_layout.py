"""The Layout page (docs/layout.md, linked from the README) is generated from the source tree
(`eval.output.layout`): every module of the four packages is in it with the first sentence of its docstring (fix:
`mobman-eval readme docs/layout.md`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from eval.cli import main
from eval.errors import EvalError
from eval.output.layout import LAYOUT_BLOCK, first_sentence, render_layout

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "layout.md"
PACKAGES = ("mobman_env", "policies", "eval", "train")


def test_the_layout_page_equals_the_source_tree():
    text = PAGE.read_text(encoding="utf-8")
    rendered, used = render_layout(text, PAGE.parent)
    assert used == [f"../{p}" for p in PACKAGES]
    assert rendered == text, "docs/layout.md differs from the modules; run `mobman-eval readme docs/layout.md`"


@pytest.mark.parametrize("package", PACKAGES)
def test_every_module_is_in_the_layout(package):
    body = LAYOUT_BLOCK.search(PAGE.read_text(encoding="utf-8")).group("body")
    section = body.split(f"**`{package}/`**")[1].split("\n**`")[0]
    for path in (ROOT / package).rglob("*.py"):
        rel = path.relative_to(ROOT / package).with_suffix("")
        if rel.parts == ("__init__",):
            continue
        name = "/".join(rel.parts[:-1]) + "/" if rel.name == "__init__" else "/".join(rel.parts)
        assert f"| `{name}` |" in section, f"{package}/{name} is not in docs/layout.md"


def _repo(tmp_path: Path) -> Path:
    (tmp_path / ".git").mkdir(parents=True)
    pkg = tmp_path / "pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text('"""pkg: a package.\n\nMore."""\n')
    (pkg / "a.py").write_text('"""Module a, e.g. the first. It does x."""\n')
    (tmp_path / "doc.md").write_text("# Doc\n\n<!-- layout:begin pkg -->\nstale\n<!-- layout:end -->\n")
    return tmp_path


def test_the_layout_follows_the_modules(tmp_path, capsys):
    repo = _repo(tmp_path)
    doc = str(repo / "doc.md")
    assert main(["readme", doc]) == 0
    text = (repo / "doc.md").read_text()
    assert "**`pkg/`**: a package.\n" in text and "| `a` | Module a, e.g. the first. |" in text
    assert main(["readme", "--check", doc]) == 0
    (repo / "pkg" / "sub").mkdir()
    (repo / "pkg" / "sub" / "__init__.py").write_text('"""pkg.sub: a sub-package | with a pipe."""\n')
    (repo / "pkg" / "sub" / "b.py").write_text('"""Module b."""\n')
    assert main(["readme", "--check", doc]) == 1  # a new module: the page is stale
    assert main(["readme", doc]) == 0
    text = (repo / "doc.md").read_text()
    assert "| `sub/` | a sub-package \\| with a pipe. |\n| `sub/b` | Module b. |" in text
    (repo / "pkg" / "c.py").write_text("x = 1\n")
    assert main(["readme", doc]) == 2
    assert "has no module docstring" in capsys.readouterr().err


def test_a_layout_block_reads_only_its_own_repository(tmp_path):
    repo = _repo(tmp_path / "repo")
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "x.py").write_text('"""X."""\n')
    with pytest.raises(EvalError, match="outside the page's repository"):
        render_layout("<!-- layout:begin ../outside -->\n<!-- layout:end -->\n", repo)


def test_first_sentence(tmp_path):
    f = tmp_path / "m.py"
    f.write_text('"""`m`: does x (eqs. (7)-(15)), i.e. y. Then z.\n\nMore."""\n')
    assert first_sentence(f, "m") == "`m`: does x (eqs. (7)-(15)), i.e. y."
    f.write_text('"""pkg.m: a module. `Other` text."""\n')
    assert first_sentence(f, "pkg.m") == "a module."


def test_a_docstring_cannot_end_the_layout_block_or_inject_html(tmp_path):
    """A docstring's first sentence is copied into a table cell: a `<!-- layout:end -->` in it closed the block
    early and the page grew on every render; it is escaped, and a second render changes nothing."""
    repo = _repo(tmp_path)
    (repo / "pkg" / "evil.py").write_text('"""Evil <!-- layout:end --> <img src=x onerror=alert(1)> `<!-- x -->`."""\n')
    doc = repo / "doc.md"
    assert main(["readme", str(doc)]) == 0
    once = doc.read_text()
    assert main(["readme", str(doc)]) == 0 and doc.read_text() == once
    assert "| `evil` | Evil &lt;!-- layout:end --> &lt;img src=x onerror=alert(1)> `<!\u200b-- x -->`. |" in once
    assert once.count("<!-- layout:end -->") == 1


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b'"""Broken."""\ndef f(:\n', r"pkg/bad.py is not Python source \(SyntaxError"),
        (b'"""Caf\xe9."""\n', r"pkg/bad.py: the module is not UTF-8 text \(byte 0xe9 at offset 6\)"),
        (b'"""Nul."""\n\x00\n', r"pkg/bad.py is not Python source"),
    ],
    ids=["syntax", "latin-1", "nul"],
)
def test_a_malformed_module_is_named_not_a_traceback(tmp_path, capsys, content, match):
    import re

    repo = _repo(tmp_path)
    (repo / "pkg" / "bad.py").write_bytes(content)
    before = (repo / "doc.md").read_text()
    assert main(["readme", str(repo / "doc.md")]) == 2
    err = capsys.readouterr().err
    assert re.search(match, err) and "Traceback" not in err, err
    assert (repo / "doc.md").read_text() == before

"""The README's result text is generated from committed results: every `<!-- bench:begin -->` and
`<!-- generated:begin PATH SECTION -->` block equals what `mobman-eval readme README.md` renders from the files
it names (fix: run that command, or rerun the experiment and commit its output)."""

import json
import re
from pathlib import Path

import pytest

from eval.cli import main
from eval.cli.readme import render
from eval.errors import EvalError
from eval.output.readme import render_generated

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
#: any block `mobman-eval readme` regenerates
BLOCK = re.compile(r"<!-- (generated|bench|layout):begin ")


def test_readme_blocks_equal_the_committed_results():
    text = README
    assert BLOCK.search(text), "README.md lost its generated blocks (the paper's claims, the headline scorecard)"
    rendered, used = render(text, ROOT)
    for rel in used:
        results = (ROOT / rel).with_name("results.json")
        if results.is_file():  # a generated Markdown file beside the results.json it was written from
            seeds = [r["seed"] for r in json.loads(results.read_text())["episodes"]]
            assert min(seeds) >= 10_000, f"{rel}: README figures come from reported seeds only"
    assert rendered == text, (
        "README.md's result blocks differ from the committed results; run `mobman-eval readme README.md`"
    )


def test_render_generated_replaces_the_section_body(tmp_path):
    (tmp_path / "paper.md").write_text("# T\n\n## Claims\n\n| a |\n|---|\n| 1 |\n\n## Other\n\nx\n")
    text = "intro\n<!-- generated:begin paper.md Claims -->\nstale\n<!-- generated:end -->\nend\n"
    new, used = render_generated(text, tmp_path)
    assert used == ["paper.md"]
    assert new == "intro\n<!-- generated:begin paper.md Claims -->\n| a |\n|---|\n| 1 |\n<!-- generated:end -->\nend\n"
    with pytest.raises(EvalError, match=r"paper.md: no section '## Nope'; the file's sections: \['Claims', 'Other'\]"):
        render_generated(text.replace("Claims", "Nope"), tmp_path)
    with pytest.raises(EvalError, match="missing.md, which does not exist"):
        render_generated(text.replace("paper.md", "missing.md"), tmp_path)


def test_the_readme_command_writes_and_checks(tmp_path, capsys):
    (tmp_path / "summary.md").write_text("## Table\n\n| x |\n")
    doc = tmp_path / "doc.md"
    doc.write_text("<!-- generated:begin summary.md Table -->\nold\n<!-- generated:end -->\n")
    assert main(["readme", "--check", str(doc)]) == 1
    assert "old" in doc.read_text()
    assert main(["readme", str(doc)]) == 0
    assert doc.read_text() == "<!-- generated:begin summary.md Table -->\n| x |\n<!-- generated:end -->\n"
    assert main(["readme", "--check", str(doc)]) == 0
    (tmp_path / "plain.md").write_text("no blocks\n")
    assert main(["readme", str(tmp_path / "plain.md")]) == 2
    assert "no generated block found" in capsys.readouterr().err


def _page_with_outside_source(tmp_path, kind: str, source: str) -> tuple[Path, Path]:
    """A repository (tmp/repo with .git) whose docs/page.md has one block naming `source`; the file it would
    copy lies outside the repository (tmp/outside.*), reached by a relative path, an absolute one or a
    symlink inside the repository."""
    repo = tmp_path / "repo"
    (repo / ".git").mkdir(parents=True)
    (repo / "docs").mkdir()
    if kind == "bench":
        outside = tmp_path / "outside.json"
        outside.write_text((ROOT / "docs/results/bench-v2-dev/scorecard.json").read_text())
        block = "<!-- bench:begin {} -->\nold\n<!-- bench:end -->\n"
    else:
        outside = tmp_path / "outside.md"
        outside.write_text("## T\n\nsecret from outside\n")
        block = "<!-- generated:begin {} T -->\nold\n<!-- generated:end -->\n"
    (repo / "docs" / "link").symlink_to(outside)
    rel = {"relative": f"../../{outside.name}", "absolute": str(outside), "symlink": "link"}[source]
    page = repo / "docs" / "page.md"
    page.write_text("# page\n" + block.format(rel))
    return page, outside


@pytest.mark.parametrize("source", ["relative", "absolute", "symlink"])
@pytest.mark.parametrize("kind", ["generated", "bench"])
def test_readme_copies_only_from_the_pages_repository(tmp_path, capsys, kind, source):
    page, outside = _page_with_outside_source(tmp_path, kind, source)
    before = page.read_text()
    argv = ["readme", str(page)] if kind == "generated" else ["bench", "--render-readme", str(page)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"resolves to {outside}, outside the page's repository {tmp_path / 'repo'}" in err, err
    assert "Traceback" not in err and page.read_text() == before


def test_a_source_tree_without_git_is_its_pages_repository(tmp_path, capsys):
    """An unpacked sdist has no .git: its pyproject.toml marks the repository, so docs/rl/page.md may copy from
    ../results/ (CI runs the suite from the sdist), and a block naming a file above the tree is still refused."""
    tree = tmp_path / "mobman-0.3.0"
    (tree / "docs" / "results").mkdir(parents=True)
    (tree / "pyproject.toml").write_text("[project]\nname = 'x'\n")
    (tree / "docs" / "results" / "summary.md").write_text("## Table\n\n| x |\n")
    (tree / "docs" / "rl").mkdir()
    page = tree / "docs" / "rl" / "page.md"  # as docs/rl/index.md names ../results/rl-v2/summary.md
    page.write_text("<!-- generated:begin ../results/summary.md Table -->\nold\n<!-- generated:end -->\n")
    assert main(["readme", str(page)]) == 0 and "| x |" in page.read_text()
    (tmp_path / "outside.md").write_text("## Table\n\nsecret\n")
    page.write_text("<!-- generated:begin ../../../outside.md Table -->\nold\n<!-- generated:end -->\n")
    assert main(["readme", str(page)]) == 2
    assert f"outside the page's repository {tree}" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["readme"], ["bench", "--render-readme"]])
def test_readme_keeps_a_symlinked_page_and_its_mode(tmp_path, argv):
    (tmp_path / ".git").mkdir()
    (tmp_path / "summary.md").write_text("## Table\n\n| x |\n")
    (tmp_path / "scorecard.json").write_text((ROOT / "docs/results/bench-v2-dev/scorecard.json").read_text())
    real = tmp_path / "real.md"
    block = (
        "<!-- bench:begin scorecard.json -->\nold\n<!-- bench:end -->\n"
        if "bench" in argv
        else ("<!-- generated:begin summary.md Table -->\nold\n<!-- generated:end -->\n")
    )
    real.write_text(block)
    real.chmod(0o640)
    page = tmp_path / "page.md"
    page.symlink_to(real)
    assert main([*argv, str(page)]) == 0
    assert page.is_symlink() and "old" not in real.read_text()
    assert real.stat().st_mode & 0o777 == 0o640

"""The README's result text is generated from committed results: every `<!-- bench:begin -->` and
`<!-- generated:begin PATH SECTION -->` block equals what `mobman-eval readme README.md` renders from the files
it names (fix: run that command, or rerun the experiment and commit its output)."""

import json
from pathlib import Path

import pytest

from eval.cli import main
from eval.cli.readme import render
from eval.errors import EvalError
from eval.output.readme import render_generated

ROOT = Path(__file__).resolve().parents[1]


def test_readme_blocks_equal_the_committed_results():
    text = (ROOT / "README.md").read_text()
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


def test_eval_readme_blocks_equal_the_committed_results():
    path = ROOT / "eval" / "README.md"
    text = path.read_text()
    rendered, used = render_generated(text, path.parent)
    assert "../docs/results/speed/speed.md" in used
    assert rendered == text, "eval/README.md's generated blocks differ; run `mobman-eval readme eval/README.md`"

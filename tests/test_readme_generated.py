"""The README's result text is generated from committed results: every `<!-- bench:begin -->` and
`<!-- generated:begin PATH SECTION -->` block equals what `mobman-eval readme README.md` renders from the files
it names (fix: run that command, or rerun the experiment and commit its output)."""

import json
import os
import re
from pathlib import Path

import pytest

from eval.cli import main
from eval.cli.readme import render
from eval.errors import EvalError
from eval.output.blocks import escape_copied, replace_blocks
from eval.output.compact import stored_bytes
from eval.output.readme import render_generated
from policies.agents.untrusted_json import stored_path

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
        if stored_path(results).is_file():  # a generated Markdown file beside the results.json it was written from
            seeds = [r["seed"] for r in json.loads(stored_bytes(results))["episodes"]]
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
        outside.write_text(stored_bytes(ROOT / "docs/results/bench-v2-dev/scorecard.json").decode())
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
    (tmp_path / "scorecard.json").write_text(stored_bytes(ROOT / "docs/results/bench-v2-dev/scorecard.json").decode())
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


#: a section copied from a hostile (or careless) source: markers that would end or open a block, HTML, an entity,
#: and the same inside a code span and a fenced block
HOSTILE = (
    "## T\n\nbefore <!-- generated:end --> after <script>alert(1)</script> &amp; <img src=x onerror=alert(2)>\n"
    "<!-- generated:end -->\n<!-- generated:begin other.md T -->\n"
    "code: `<!-- generated:end --> <b>`, plain: a <= 6 mm, b -> c, R & D\n"
    "```\n<!-- generated:end -->\n<i>fenced</i>\n```\n"
)


def _hostile_page(tmp_path) -> Path:
    (tmp_path / ".git").mkdir()
    (tmp_path / "summary.md").write_text(HOSTILE)
    page = tmp_path / "page.md"
    page.write_text("top\n<!-- generated:begin summary.md T -->\nold\n<!-- generated:end -->\nbottom\n")
    return page


def test_copied_text_cannot_close_its_block_or_inject_html_and_renders_the_same_twice(tmp_path, capsys):
    """Pass 3's RD4: a section holding `<!-- generated:end -->` closed its block early and the rest of the body
    grew after it on every render. Copied text is escaped: no tag, comment or entity of the source reaches the
    page (outside code as entities, inside code a zero-width space after `<!`), and a second render changes
    nothing."""
    page = _hostile_page(tmp_path)
    assert main(["readme", str(page)]) == 0
    once = page.read_text()
    assert main(["readme", str(page)]) == 0 and page.read_text() == once  # idempotent
    assert main(["readme", "--check", str(page)]) == 0
    body = once.split("<!-- generated:begin summary.md T -->\n", 1)[1]
    body, rest = body.split("\n<!-- generated:end -->", 1)
    assert rest == "\nbottom\n" and once.startswith("top\n")
    for raw in ("<script", "<img", "<!-- generated", " &amp; "):
        assert raw not in body, raw
    assert "&lt;script>alert(1)&lt;/script>" in body and "&amp;amp;" in body
    assert "`<!\u200b-- generated:end --> <b>`" in body and "\n<!\u200b-- generated:end -->\n<i>fenced</i>\n" in body
    assert "a <= 6 mm, b -> c, R & D" in body  # plain text that starts no markup stays as written
    assert "Traceback" not in capsys.readouterr().err


def test_a_bench_block_escapes_what_the_scorecard_names(tmp_path, monkeypatch):
    from eval.bench import scorecard

    (tmp_path / ".git").mkdir()
    (tmp_path / "scorecard.json").write_text(stored_bytes(ROOT / "docs/results/bench-v2-dev/scorecard.json").decode())
    monkeypatch.setattr(
        scorecard, "readme_markdown", lambda sc, pooled_only=False: "| <img src=x> |\n<!-- bench:end -->\nx\n"
    )
    page = "<!-- bench:begin scorecard.json -->\nold\n<!-- bench:end -->\n"
    once = scorecard.render_readme(page, tmp_path)[0]
    assert (
        once
        == "<!-- bench:begin scorecard.json -->\n| &lt;img src=x> |\n&lt;!-- bench:end -->\nx\n<!-- bench:end -->\n"
    )
    assert scorecard.render_readme(once, tmp_path)[0] == once


@pytest.mark.parametrize(
    ("page", "match"),
    [
        ("<!-- generated:begin s.md T -->\nold\n", "line 1: the generated block begun there has no line"),
        ("a\n<!-- generated:end -->\n", "line 2: '<!-- generated:end -->' closes no block"),
        (
            "<!-- generated:begin s.md T -->\n<!-- generated:begin s.md T -->\n<!-- generated:end -->\n",
            "line 2: a generated block begins inside the one begun on line 1",
        ),
        ("<!-- generated:begin s.md T\n<!-- generated:end -->\n", "line 1: .* does not end with ' -->'"),
        ("<!-- generated:begin s.md -->\n<!-- generated:end -->\n", "write '<!-- generated:begin PATH SECTION -->'"),
    ],
    ids=["no-end", "no-begin", "nested", "open-marker", "no-section"],
)
def test_malformed_blocks_are_refused_naming_the_line(tmp_path, capsys, page, match):
    (tmp_path / ".git").mkdir()
    (tmp_path / "s.md").write_text("## T\n\nx\n")
    (tmp_path / "page.md").write_text(page)
    assert main(["readme", str(tmp_path / "page.md")]) == 2
    err = capsys.readouterr().err
    assert re.search(match, err) and "Traceback" not in err, err
    assert (tmp_path / "page.md").read_text() == page  # nothing written


@pytest.mark.parametrize("which", ["page", "source", "bench page"])
def test_a_page_or_source_that_is_not_utf8_is_refused(tmp_path, capsys, which):
    """Pass 3's RD5: a page in Latin-1 gave a UnicodeDecodeError traceback (`readme` and `bench --render-readme`)."""
    page = _hostile_page(tmp_path)
    target = tmp_path / "summary.md" if which == "source" else page
    target.write_bytes(target.read_bytes().replace(b"top", b"caf\xe9").replace(b"## T\n", b"## T\n\xff\n"))
    before = page.read_bytes()
    argv = ["bench", "--render-readme", str(page)] if which == "bench page" else ["readme", str(page)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"{target}: the {'source file' if which == 'source' else 'page'} is not UTF-8 text (byte 0x" in err, err
    assert "save it as UTF-8" in err and "Traceback" not in err
    assert page.read_bytes() == before


def test_a_page_that_is_a_fifo_is_refused_not_read(tmp_path, capsys):
    fifo = tmp_path / "page.md"
    os.mkfifo(fifo)
    assert main(["readme", str(fifo)]) == 2
    err = capsys.readouterr().err
    assert "is a FIFO, not a regular file" in err and "Traceback" not in err


@pytest.mark.timeout(120)
def test_a_hostile_megabyte_page_is_parsed_in_one_pass(tmp_path, capsys):
    """A 672 KB page of begin markers without an end took 284 s (the regular expression rescanned the rest of the
    page from every marker); the blocks are now found in one pass over the lines, so a 1 MB page is refused at
    its second line (the old code would not finish within the timeout)."""
    (tmp_path / ".git").mkdir()
    (tmp_path / "s.md").write_text("## T\n\nx\n")
    line = "<!-- generated:begin s.md T -->\n"
    page = tmp_path / "page.md"
    page.write_text(line * (2**20 // len(line)))
    assert main(["readme", str(page)]) == 2
    assert "line 2: a generated block begins inside the one begun on line 1" in capsys.readouterr().err
    text, count = replace_blocks("x<!-- generated:begin s.md T -->\n" * (2**20 // 33), "generated", str)
    assert count == 0 and len(text) > 2**20 - 64  # markers mid-line are text: nothing to rebuild


@pytest.mark.timeout(120)
def test_a_hostile_megabyte_of_backticks_is_escaped_in_one_pass():
    """Code spans are paired in one pass (each run of backticks with the next run of the same length): 1 MB of
    runs of every length is escaped, and no comment opener survives, in code or out."""
    runs = "".join("`" * (k % 500 + 1) + "<!--" for k in range(4000))
    text = (runs + "\n") * (2**20 // (len(runs) + 1) + 1)
    out = escape_copied(text)
    assert len(text) > 2**20 and "<!--" not in out
    assert escape_copied("`<!--` <!--") == "`<!\u200b--` &lt;!--"


def test_a_copied_section_keeps_its_images_and_links_pointing_at_their_files(tmp_path):
    """A generated block copies a section with its relative image and link targets rewritten from the source's
    folder to the page's (a scorecard.md shows plots/x.png beside itself); URLs and anchors stay."""
    (tmp_path / ".git").mkdir()
    (tmp_path / "results" / "b").mkdir(parents=True)
    (tmp_path / "results" / "b" / "scorecard.md").write_text(
        "## Ladder\n\n| x |\n\n![ladder](plots/ladder.png)\n\n[up](../a.md#top) [site](https://example.org/p) [here](#k)\n"
    )
    (tmp_path / "docs").mkdir()
    page = tmp_path / "docs" / "page.md"
    page.write_text("<!-- generated:begin ../results/b/scorecard.md Ladder -->\nold\n<!-- generated:end -->\n")
    assert main(["readme", str(page)]) == 0
    text = page.read_text()
    assert "![ladder](../results/b/plots/ladder.png)" in text
    assert "[up](../results/a.md#top) [site](https://example.org/p) [here](#k)" in text

"""Every page that holds generated blocks (the docs pages and the packages' READMEs, beside the top README which
tests/test_readme_generated.py and tests/test_readme_bench.py hold) equals what `mobman-eval readme PAGE`
renders from the committed results it names, and those results come from reported seeds (>= 10,000) only."""

import json
import re
from pathlib import Path

import pytest

from eval.bench.scorecard import load_scorecard
from eval.cli.readme import render
from eval.output.compact import stored_bytes
from policies.agents.untrusted_json import stored_path

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"<!-- (generated|bench):begin ")


def _pages() -> list[Path]:
    """The hand-written Markdown pages holding a block: docs/ outside docs/results/ (whose files mobman
    writes) and each package's README."""
    pages = [p for p in sorted((ROOT / "docs").rglob("*.md")) if "results" not in p.relative_to(ROOT / "docs").parts]
    pages += sorted(ROOT.glob("*/README.md"))
    return [p for p in pages if BLOCK.search(p.read_text(encoding="utf-8"))]


def test_some_docs_page_holds_generated_blocks():
    assert _pages(), "no docs page holds a generated block: the figures of the docs would be typed by hand"


@pytest.mark.parametrize("page", _pages(), ids=lambda p: str(p.relative_to(ROOT)))
def test_docs_page_blocks_equal_the_committed_results(page):
    text = page.read_text(encoding="utf-8")
    rendered, used = render(text, page.parent)
    for rel in used:
        src = (page.parent / rel).resolve()
        assert src.is_relative_to(ROOT), f"{page}: {rel} lies outside the repository"
        if src.suffix == ".json":
            seeds = load_scorecard(src)["protocol"]["seeds"]
        elif stored_path(src.with_name("results.json")).is_file():  # results.json or its compacted twin
            seeds = [r["seed"] for r in json.loads(stored_bytes(src.with_name("results.json")))["episodes"]]
        else:
            continue
        assert min(seeds) >= 10_000, f"{page}: {rel}: the figures of a page come from reported seeds only"
    assert rendered == text, f"{page.relative_to(ROOT)} differs from its results; run `mobman-eval readme {page}`"


def test_the_nnbc_plus_v5_goals_page_is_what_its_script_makes_of_the_committed_scorecard():
    """docs/results/nnbc-plus-v5/goals.md (quoted on the nnbc-plus page) equals goals.py's output on the
    committed v3 dev scorecard: no figure of it is typed."""
    import importlib.util

    folder = ROOT / "docs" / "results" / "nnbc-plus-v5"
    spec = importlib.util.spec_from_file_location("goals", folder / "goals.py")
    assert spec is not None and spec.loader is not None
    goals = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(goals)
    made = goals.main(
        str(ROOT / "docs" / "results" / "bench-v3-dev" / "scorecard.json.xz"),
        str(ROOT / "docs" / "results" / "bench-v3-heldout-0.4" / "scorecard.json.xz"),
    )
    assert made == (folder / "goals.md").read_text()
    assert "## Goals" in made and all(f"`{p}`" in made for p in goals.POLICIES)


def test_the_nnbc_plus_v5_experiment_tables_are_what_the_panel_makes_of_its_csvs():
    """Each experiments/*.md beside a panel CSV in docs/results/nnbc-plus-v5 (quoted on the nnbc-plus page) equals
    `panel.py --markdown` of that CSV."""
    import importlib.util

    folder = ROOT / "docs" / "results" / "nnbc-plus-v5"
    spec = importlib.util.spec_from_file_location("panel", folder / "panel.py")
    assert spec is not None and spec.loader is not None
    panel = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(panel)
    tables = sorted((folder / "experiments").glob("*.md"))
    assert len(tables) >= 2
    for md in tables:
        assert md.read_text() == panel.markdown(str(md.with_suffix(".csv"))), md.name


def test_nnbc_plus_v4_targets_script_reproduces_its_committed_table():
    """docs/results/nnbc-plus-v4/targets.py, run as its docstring says on the (compacted) v2 dev scorecard, writes
    the committed targets.md (it read the scorecard as plain JSON before, which fails on the compacted file)."""
    import runpy
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    folder = root / "docs" / "results" / "nnbc-plus-v4"
    script = runpy.run_path(str(folder / "targets.py"))
    text = script["main"](str(root / "docs" / "results" / "bench-v2-dev" / "scorecard.json"))
    assert text.rstrip("\n") == (folder / "targets.md").read_text(encoding="utf-8").rstrip("\n")

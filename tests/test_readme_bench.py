"""The README's result tables are generated from committed scorecards: this test fails when a README block
between `<!-- bench:begin PATH -->` and `<!-- bench:end -->` differs from what its scorecard renders to
(fix: `python -m eval bench --render-readme README.md`, or rerun the bench and commit its scorecard)."""

from pathlib import Path

from eval.bench.scorecard import README_BLOCK, load_scorecard, render_readme

ROOT = Path(__file__).resolve().parents[1]


def test_readme_bench_blocks_equal_their_committed_scorecards():
    text = (ROOT / "README.md").read_text()
    blocks = list(README_BLOCK.finditer(text))
    assert blocks, "README.md has no <!-- bench:begin PATH --> block"
    rendered, used = render_readme(text, ROOT)
    for path in used:
        sc = load_scorecard(ROOT / path)
        assert min(sc["protocol"]["seeds"]) >= 10_000, f"{path}: README figures come from reported seeds only"
        assert (ROOT / path).resolve().is_relative_to(ROOT)
    assert rendered == text, (
        "README.md's bench block(s) differ from the committed scorecard(s); run "
        "`python -m eval bench --render-readme README.md`"
    )

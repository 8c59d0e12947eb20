"""The documentation site's structure (mkdocs.yml and docs/hooks.py), checked without building it (CI builds it
with `mkdocs build --strict` in .ci/docs, where the hook's post-build check fails on any broken target):
a section's index page is its own, README text keeps working links at any depth, and the post-build check finds
a missing image or page."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def hooks():
    pytest.importorskip("mkdocs")
    spec = importlib.util.spec_from_file_location("mobman_docs_hooks", ROOT / "docs" / "hooks.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _sections(nav: list, path: str = "") -> list[tuple[str, list[str]]]:
    """(section title, the files of its direct children) of every section of the nav, nested ones too."""
    out = []
    for item in nav:
        if isinstance(item, dict):
            for title, value in item.items():
                if isinstance(value, list):
                    children = [v if isinstance(v, str) else next(iter(v.values())) for v in value]
                    out.append((f"{path}{title}", [c for c in children if isinstance(c, str)]))
                    out += _sections(value, f"{path}{title} / ")
    return out


def test_a_section_opens_its_own_page_and_every_readme_has_an_entry(hooks):
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    assert "navigation.indexes" in config["theme"]["features"]
    for title, files in _sections(config["nav"]):
        # Material makes the first index-like child (index.md or README.md) the section's page and drops its entry
        index_like = [f for f in files if Path(f).name in ("index.md", "README.md")]
        assert not index_like or index_like[0] == files[0], (
            f"section {title!r}: {index_like[0]} would become the section's page (and lose its own entry); make "
            f"the section's first child an index.md"
        )
    rl = dict(_sections(config["nav"]))["Reinforcement learning"]
    assert rl[0] == "rl/index.md"
    nav_files = {f for _, files in _sections(config["nav"]) for f in files}
    readmes = {p.relative_to(ROOT).as_posix() for p in ROOT.glob(hooks.REPO_PAGES_GLOB)}
    assert readmes and readmes <= nav_files


def test_readme_links_are_made_relative_to_the_page(hooks):
    text = "[a](docs/x.md) [b](policies/models/p/README.md) [c](https://e.org/d) [d](#here) [e](/abs) [`f`][g]"
    assert hooks.relink(text, 0) == text.replace("](docs/", "](")
    assert hooks.relink(text, 2) == (
        "[a](../../x.md) [b](../../policies/models/p/README.md) [c](https://e.org/d) [d](#here) [e](/abs) [`f`][g]"
    )


def test_the_post_build_check_finds_missing_images_and_pages(hooks, tmp_path):
    (tmp_path / "a" / "b").mkdir(parents=True)
    (tmp_path / "a" / "b" / "index.html").write_text("<p>b</p>")
    (tmp_path / "a" / "plot.png").write_bytes(b"png")
    (tmp_path / "a" / "index.html").write_text(
        '<img src="plot.png"><img src="missing.png"><a href="b/">b</a><a href="b/#x">x</a><a href="../c/">c</a>'
        '<a href="https://e.org/z.png">z</a><a href="#top">t</a><link href="../style.css"><script src="s%20p.js">'
        '</script><a href="mailto:x@y.z">m</a>'
    )
    assert hooks.missing_targets(tmp_path) == [
        "a/index.html: <img> missing.png",
        "a/index.html: <a> ../c/",
        "a/index.html: <link> ../style.css",
        "a/index.html: <script> s p.js",
    ]


def test_citation_names_the_newest_release_and_the_package_the_next():
    """CITATION.cff cites the newest dated release of CHANGELOG.md (version and date); the package's version is
    that release or, while the changelog has an Unreleased section, its next version as a .dev release."""
    import re

    import mobman_env

    changelog = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    released = re.findall(r"^## \[(\d+\.\d+\.\d+)\] — (\d{4}-\d{2}-\d{2})$", changelog, re.M)
    assert released, "CHANGELOG.md has no dated release heading '## [X.Y.Z] — YYYY-MM-DD'"
    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert (str(citation["version"]), str(citation["date-released"])) == released[0]
    unreleased = re.search(r"^## \[Unreleased\] — (\d+\.\d+\.\d+)$", changelog, re.M)
    expected = f"{unreleased.group(1)}.dev0" if unreleased else released[0][0]
    assert mobman_env.__version__ == expected


def test_the_tutorial_page_shows_what_the_notebook_printed_and_drew(hooks):
    """A run notebook's page holds its stdout as text and its images inline; stderr is dropped and a failed
    cell fails the page (so the strict build fails)."""
    nb = {
        "cells": [
            {"cell_type": "markdown", "source": ["# Title\n", "\n", "text"]},
            {
                "cell_type": "code",
                "source": ["print(1)"],
                "outputs": [
                    {"output_type": "stream", "name": "stderr", "text": ["pybullet build time\n"]},
                    {"output_type": "stream", "name": "stdout", "text": ["1\n"]},
                    {"output_type": "display_data", "data": {"image/png": "iVBORw0K\n", "text/plain": ["<Image>"]}},
                ],
            },
        ]
    }
    md = hooks.notebook_markdown(nb, "t.ipynb")
    assert "```python\nprint(1)\n```\n\n```text\n1\n```\n\n![output](data:image/png;base64,iVBORw0K)" in md
    assert "pybullet" not in md and "run when this site was built" in md
    failed = {"output_type": "error", "ename": "ValueError", "evalue": "bad", "traceback": []}
    with pytest.raises(RuntimeError, match="the notebook failed: ValueError: bad"):
        hooks.output_markdown(failed)


#: the README is a front page; everything else is in the docs pages it links to (issue 29)
README_MAX_LINES = 250


def test_the_readme_is_a_front_page_with_its_picture():
    import json
    import re

    from PIL import Image

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= README_MAX_LINES, (
        f"README.md has {len(text.splitlines())} lines; a front page has at most {README_MAX_LINES}: move a "
        "section to a docs page and link to it"
    )
    picture = re.search(r"!\[[^\]]*\]\((docs/assets/[^)]+\.png)\)", text)
    assert picture, "README.md shows no picture from docs/assets/ (make it: mobman-eval picture)"
    png = ROOT / picture.group(1)
    record = json.loads(png.with_suffix(".json").read_text())
    with Image.open(png) as img:
        assert img.format == "PNG" and list(img.size) == record["size"]
    assert record["command"].startswith("mobman-eval picture ") and record["provenance"]["git"]


def test_every_relative_link_of_the_readme_names_a_file_of_the_repository():
    """The README is read on GitHub: a link is a path relative to the repository, and its file exists."""
    import re

    text = (ROOT / "README.md").read_text(encoding="utf-8")
    targets = [t for t in re.findall(r"\]\(([^)\s]+)\)", text) if not re.match(r"[a-z][a-z0-9+.-]*:|#", t)]
    assert targets
    missing = [t for t in targets if not (ROOT / t.split("#")[0]).exists()]
    assert not missing, f"README.md links to what the repository does not have: {missing}"


def test_running_a_notebook_logs_a_line_per_code_cell(hooks, tmp_path, caplog):
    """The docs build runs the tutorial for minutes: it says so at the start and after every code cell."""
    pytest.importorskip("nbclient")
    nb = {
        "cells": [
            {"cell_type": "markdown", "metadata": {}, "source": ["# title"]},
            {"cell_type": "code", "metadata": {}, "source": ["x = 1"], "outputs": [], "execution_count": None},
            {"cell_type": "code", "metadata": {}, "source": ["print(x + 1)"], "outputs": [], "execution_count": None},
        ],
        "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}},
        "nbformat": 4,
        "nbformat_minor": 5,
    }
    with caplog.at_level("INFO", logger="mkdocs.hooks.mobman"):
        ran = hooks.execute_notebook(nb, tmp_path, name="tiny.ipynb")
    lines = [r.getMessage() for r in caplog.records if r.name == "mkdocs.hooks.mobman"]
    assert lines[0] == "tiny.ipynb: running its 2 code cells"
    assert [line.split(" ran in ")[0] for line in lines[1:]] == [
        "tiny.ipynb: code cell 1/2",
        "tiny.ipynb: code cell 2/2",
    ]
    assert "".join(ran["cells"][2]["outputs"][0]["text"]) == "2\n"


def test_a_reference_page_says_it_is_rendered(hooks, caplog):
    """mkdocstrings renders the API reference silently for tens of seconds: each page says so first."""
    from types import SimpleNamespace

    page = SimpleNamespace(file=SimpleNamespace(src_uri="reference/x.md"))
    config = SimpleNamespace(config_file_path=str(ROOT / "mkdocs.yml"))
    with caplog.at_level("INFO", logger="mkdocs.hooks.mobman"):
        hooks.on_page_markdown("# X\n\n::: eval.grid\n\n::: eval.checks\n", page, config, None)
        hooks.on_page_markdown("# Y\n\nno directive\n", page, config, None)
    lines = [r.getMessage() for r in caplog.records if r.name == "mkdocs.hooks.mobman"]
    assert lines == ["reference/x.md: rendering the API reference of 2 modules (mkdocstrings)"]

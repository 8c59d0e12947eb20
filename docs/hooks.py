"""MkDocs hooks of the documentation site (mkdocs.yml `hooks:`): one source for every text the site shows.

* Repository manuals outside docs/ (the shipped agents' READMEs) become pages at their repository paths, so the
  README text embedded in the site (pymdownx snippets) keeps its relative links working.
* The tutorial notebook becomes a Markdown page (its Markdown cells as they are, code cells as Python blocks,
  no outputs: the notebook is stored without outputs, which is checked here, and run in CI by nbmake), beside
  the `.ipynb` download.
* Every module of the four packages must appear in a `::: module` directive of docs/reference/: a new module
  missing from the API reference is a warning, so `mkdocs build --strict` fails.
* Text that Markdown would swallow or misread is a warning too: a `<word>` outside backticks (taken for an HTML
  tag, so the text disappears) and a list written without the blank line before it (rendered as one paragraph).
* `<!-- mobman:policy-table -->` in a page becomes the table of every built-in policy name and spec form,
  read from `policies.KNOWN_POLICIES` and `policies.SPEC_FORMS` when the site is built.

Imports the repository's `policies` package (from the directory of mkdocs.yml, not an installed copy).
"""

from __future__ import annotations

import json
import logging
import re
import sys
from pathlib import Path
from typing import Any

from mkdocs.structure.files import File, Files

#: Files outside docs/ published as pages at the same path (relative to the repository root): the README of
#: every shipped model (one folder per `sb3:` alias).
REPO_PAGES_GLOB = "policies/models/*/README.md"
#: Notebooks in docs/ rendered as Markdown pages next to them.
NOTEBOOKS = ("tutorials/benchmark-your-controller.ipynb",)
POLICY_TABLE = "<!-- mobman:policy-table -->"
#: The packages whose every module the API reference must document.
PACKAGES = ("mobman_env", "policies", "eval", "train")

#: HTML elements pages and docstrings may contain (those of Python-Markdown, its extensions, mkdocstrings and
#: autorefs); any other `<tag>` is text that Markdown took for HTML.
_TAG_NAMES = (
    "a abbr autoref b blockquote br caption code col colgroup dd del details div dl dt em figcaption figure h1 h2 "
    "h3 h4 h5 h6 hr i img input ins kbd label li mark ol p path pre q s small span strong sub summary sup svg table "
    "tbody td th thead tr u ul var"
)
KNOWN_TAGS = frozenset(_TAG_NAMES.split())
_TAG = re.compile(r"<([A-Za-z][\w-]*)")
_PARAGRAPH = re.compile(r"<p>(.*?)</p>", flags=re.S)
_LIST_LINE = re.compile(r"\n[ \t]*(?:[*+-]|\d+\.) \S")

log = logging.getLogger("mkdocs.hooks.mobman")


def _root(config: Any) -> Path:
    return Path(config.config_file_path).resolve().parent


def notebook_markdown(nb: dict, name: str) -> str:
    """Notebook `nb` (the JSON of file `name`) as Markdown: Markdown cells unchanged, code cells fenced as
    Python, outputs dropped, and a download link under the title."""
    parts = []
    for cell in nb["cells"]:
        source = "".join(cell["source"]).strip("\n")
        if cell["cell_type"] == "markdown":
            parts.append(source)
        elif cell["cell_type"] == "code" and source:
            parts.append(f"```python\n{source}\n```")
    download = f"*This page is the notebook [`{name}`]({name}) without its outputs: download it and run it.*"
    title, _, rest = "\n\n".join(parts).partition("\n")
    return f"{title}\n\n{download}\n{rest}\n"


def undocumented_modules(root: Path, docs_dir: Path) -> list[str]:
    """Modules of `PACKAGES` (package `__init__`s included, `__main__` and `_private` ones not) named by no
    `::: module` line of docs/reference/*.md."""
    named = set()
    for page in sorted((docs_dir / "reference").glob("*.md")):
        named |= set(re.findall(r"^::: *([\w.]+)", page.read_text(encoding="utf-8"), flags=re.M))
    modules = []
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            if not any(p.startswith("_") for p in parts):
                modules.append(".".join(parts))
    return [m for m in modules if m not in named]


def on_files(files: Files, config: Any) -> Files:
    root = _root(config)
    for module in undocumented_modules(root, Path(config.docs_dir)):
        log.warning(f"module {module} is not in the API reference: add '::: {module}' to docs/reference/")
    for path in sorted(root.glob(REPO_PAGES_GLOB)):
        rel = path.relative_to(root).as_posix()
        files.append(File.generated(config, rel, abs_src_path=str(path)))
    for rel in NOTEBOOKS:
        path = Path(config.docs_dir).resolve() / rel
        nb = json.loads(path.read_text(encoding="utf-8"))
        if any(c.get("outputs") or c.get("execution_count") for c in nb["cells"] if c["cell_type"] == "code"):
            shown = path.relative_to(root) if path.is_relative_to(root) else path
            log.warning(
                f"{shown} is stored with outputs: clear them (jupyter nbconvert --clear-output --inplace {shown})"
            )
        md = rel.removesuffix(".ipynb") + ".md"
        files.append(File.generated(config, md, content=notebook_markdown(nb, path.name)))
    return files


def policy_table(root: Path) -> str:
    """Markdown table of the built-in policy names and spec forms, from the repository's `policies`."""
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    import policies

    rows = [f"| `{name}` | {text} |" for name, text in {**policies.KNOWN_POLICIES, **policies.SPEC_FORMS}.items()]
    return "\n".join(["| spec | what |", "|---|---|", *rows])


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    if POLICY_TABLE in markdown:
        markdown = markdown.replace(POLICY_TABLE, policy_table(_root(config)))
    return _embed_readme_sections(markdown, _root(config), page.file.src_uri.count("/"))


_README_SNIPPET = re.compile(r'^--8<-- "README\.md:([\w-]+)"$', re.M)


def _embed_readme_sections(markdown: str, root: Path, depth: int) -> str:
    """Expand `--8<-- "README.md:NAME"` here rather than in pymdownx.snippets, so that the README's links to
    `docs/...` (relative to the repository) can be made relative to the page before mkdocs validates them."""
    readme = (root / "README.md").read_text(encoding="utf-8")

    def section(m: re.Match) -> str:
        name = m.group(1)
        start, end = f"<!-- --8<-- [start:{name}] -->", f"<!-- --8<-- [end:{name}] -->"
        if start not in readme or end not in readme:
            raise ValueError(f"README.md has no section {name!r} (markers {start} ... {end})")
        text = readme.split(start, 1)[1].split(end, 1)[0]
        return text.replace("](docs/", "](" + "../" * depth)

    return _README_SNIPPET.sub(section, markdown)


def rendering_problems(html: str) -> list[str]:
    """Unknown `<tags>` (text taken for HTML) and paragraphs holding list items (a list without a blank line
    before it), each with a little context, in a page's rendered HTML."""
    problems = [
        f"<{tag}> in '...{' '.join(html[max(0, m.start() - 60) : m.end() + 20].split())}...'"
        for m in _TAG.finditer(html)
        if (tag := m.group(1)).lower() not in KNOWN_TAGS
    ]
    for m in _PARAGRAPH.finditer(html):
        if _LIST_LINE.search(m.group(1)):
            text = re.sub(r"<[^>]+>", "", m.group(1))[:100].replace("\n", " ")
            problems.append(f"a list without a blank line before it: '{text}...'")
    return problems


def on_page_content(html: str, page: Any, config: Any, files: Files) -> str:
    for problem in rendering_problems(html):
        log.warning(
            f"{page.file.src_uri}: {problem} (in a docstring? put <words> in backticks; leave a blank line before a list)"
        )
    return html

"""MkDocs hooks of the documentation site (mkdocs.yml `hooks:`): one source for every text the site shows.

* Repository manuals outside docs/ (the shipped agents' READMEs) become pages at their repository paths, so the
  README text embedded in the site (pymdownx snippets) keeps its relative links working.
* The tutorial notebook becomes a Markdown page beside the `.ipynb` download: it is stored without outputs
  (checked here), executed when the site is built (nbclient, the checkout's packages; a failing cell fails the
  build) and shown with what it printed and drew: Markdown cells as they are, code cells as Python blocks, text
  outputs as text blocks, images inline. Running it logs a line per code cell, and a page of the API reference
  a line before mkdocstrings renders it (mkdocs shows INFO lines), so the build is never silent for long.
* Every module of the four packages must appear in a `::: module` directive of docs/reference/: a new module
  missing from the API reference is a warning, so `mkdocs build --strict` fails.
* Text that Markdown would swallow or misread is a warning too: a `<word>` outside backticks (taken for an HTML
  tag, so the text disappears) and a list written without the blank line before it (rendered as one paragraph).
* `<!-- mobman:conditions-table -->` becomes the conditions table (`eval.conditions`, the one table).
* `<!-- mobman:policy-table -->` in a page becomes the table of every built-in policy name and spec form with
  its knowledge class, read from `policies.KNOWN_POLICIES`, `policies.SPEC_FORMS` and `policies.knowledge_of`
  when the site is built.
* After the build, every local target of the built HTML (`<img src>`, `<a href>`, `<link href>`,
  `<script src>`, `<source src>`) must be a file of the site: a missing image or page is a warning, so
  `mkdocs build --strict` fails (mkdocs itself validates the Markdown links, not what HTML, snippets and
  plugins add).

Imports the repository's `policies` package (from the directory of mkdocs.yml, not an installed copy).
"""

from __future__ import annotations

import json
import logging
import re
import sys
from html.parser import HTMLParser
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit

from mkdocs.structure.files import File, Files

#: Files outside docs/ published as pages at the same path (relative to the repository root): the README of
#: every shipped model (one folder per `sb3:` alias).
REPO_PAGES_GLOB = "policies/models/*/README.md"
#: Notebooks in docs/ rendered as Markdown pages next to them.
NOTEBOOKS = ("tutorials/benchmark-your-controller.ipynb",)
POLICY_TABLE = "<!-- mobman:policy-table -->"
CONDITIONS_TABLE = "<!-- mobman:conditions-table -->"
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


def _text(value: str | list[str]) -> str:
    return value if isinstance(value, str) else "".join(value)


def output_markdown(output: dict) -> str:
    """One code cell output as Markdown: a PNG inline (a data URI), text in a text block, stderr (libraries'
    banners and warnings) dropped; an error raises."""
    kind = output["output_type"]
    if kind == "error":
        raise RuntimeError(f"the notebook failed: {output['ename']}: {output['evalue']}")
    if kind == "stream" and output.get("name") == "stderr":
        return ""
    if kind == "stream":
        text = _text(output["text"])
    else:  # execute_result, display_data
        data = output.get("data", {})
        if "image/png" in data:
            return f"![output](data:image/png;base64,{_text(data['image/png']).strip()})"
        text = _text(data.get("text/plain", ""))
    text = text.strip("\n")
    return f"```text\n{text}\n```" if text else ""


def notebook_markdown(nb: dict, name: str) -> str:
    """Notebook `nb` (the JSON of file `name`) as Markdown: Markdown cells unchanged, code cells fenced as
    Python followed by their outputs (if it was executed), and a download link under the title."""
    parts = []
    ran = any(c.get("outputs") for c in nb["cells"] if c["cell_type"] == "code")
    for cell in nb["cells"]:
        source = "".join(cell["source"]).strip("\n")
        if cell["cell_type"] == "markdown":
            parts.append(source)
        elif cell["cell_type"] == "code" and source:
            parts.append(f"```python\n{source}\n```")
            parts += [md for md in map(output_markdown, cell.get("outputs", [])) if md]
    how = "run when this site was built" if ran else "without its outputs"
    download = f"*This page is the notebook [`{name}`]({name}), {how}: download it and run it.*"
    title, _, rest = "\n\n".join(parts).partition("\n")
    return f"{title}\n\n{download}\n{rest}\n"


def execute_notebook(nb: dict, cwd: Path, timeout: int = 900, name: str = "the notebook") -> dict:
    """A copy of notebook `nb` executed in `cwd` (nbclient, a python3 kernel; outputs kept), as JSON.

    Running the tutorial is one of the build's long steps (it runs benchmarks), so the build says what it is
    doing: one INFO line (mkdocs prints them) when the run starts and one as each code cell ends, with its
    seconds and the total, so that neither a terminal nor a CI log sits silent."""
    import time

    import nbformat
    from nbclient import NotebookClient

    node = nbformat.reads(json.dumps(nb), as_version=4)
    code = [i for i, c in enumerate(node.cells) if c.cell_type == "code" and c.source.strip()]
    t0 = time.perf_counter()
    last = [t0]

    def cell_done(cell: Any, cell_index: int, execute_reply: Any) -> None:
        now = time.perf_counter()
        log.info(
            f"{name}: code cell {code.index(cell_index) + 1}/{len(code)} ran in {now - last[0]:.0f} s "
            f"({now - t0:.0f} s so far)"
        )
        last[0] = now

    log.info(f"{name}: running its {len(code)} code cells")
    client = NotebookClient(node, timeout=timeout, kernel_name="python3", resources={"metadata": {"path": str(cwd)}})
    client.on_cell_executed = cell_done
    client.execute()
    return json.loads(nbformat.writes(node))


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
        ran = execute_notebook(nb, root, name=rel)
        files.append(File.generated(config, md, content=notebook_markdown(ran, path.name)))
    return files


def policy_table(root: Path) -> str:
    """Markdown table of the built-in policy names and spec forms, from the repository's `policies`."""
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    import policies

    rows = [f"| `{name}` | {policies.knowledge_of(name)} | {text} |" for name, text in policies.KNOWN_POLICIES.items()]
    forms = {"sb3:PATH": policies.knowledge_of("sb3:PATH"), "module:attr": "its `knowledge` attribute, else unknown"}
    rows += [f"| `{name}` | {forms[name]} | {text} |" for name, text in policies.SPEC_FORMS.items()]
    return "\n".join(["| spec | knowledge | what |", "|---|---|---|", *rows])


def conditions_table(root: Path) -> str:
    """The conditions table, from the repository's `eval.conditions` (the one table)."""
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    from eval.conditions import CONDITIONS, conditions_markdown

    return conditions_markdown({n: c.to_dict() for n, c in CONDITIONS.items()})


_DIRECTIVE = re.compile(r"^::: *[\w.]+", flags=re.M)


def on_page_markdown(markdown: str, page: Any, config: Any, files: Files) -> str:
    if n := len(_DIRECTIVE.findall(markdown)):  # mkdocstrings renders these next: the build's other long step
        log.info(f"{page.file.src_uri}: rendering the API reference of {n} modules (mkdocstrings)")
    if POLICY_TABLE in markdown:
        markdown = markdown.replace(POLICY_TABLE, policy_table(_root(config)))
    if CONDITIONS_TABLE in markdown:
        markdown = markdown.replace(CONDITIONS_TABLE, conditions_table(_root(config)))
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
        return relink(readme.split(start, 1)[1].split(end, 1)[0], depth)

    return _README_SNIPPET.sub(section, markdown)


_RELATIVE_LINK = re.compile(r"\]\((?![a-z][a-z0-9+.-]*:|#|/)(docs/)?")


def relink(text: str, depth: int) -> str:
    """README text (links relative to the repository) made relative to a page `depth` folders below docs/:
    `docs/x.md` -> `../` * depth + `x.md`; a repository page the site publishes at its own path
    (`policies/models/.../README.md`) -> `../` * depth + that path. URLs and anchors are left alone."""
    return _RELATIVE_LINK.sub("](" + "../" * depth, text)


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


#: The HTML elements whose URL the post-build check follows: tag -> the attribute holding the URL.
URL_ATTRIBUTES = {"img": "src", "a": "href", "link": "href", "script": "src", "source": "src"}


class _Targets(HTMLParser):
    """The local targets of one HTML page: the URLs of `URL_ATTRIBUTES`, without query and fragment."""

    def __init__(self) -> None:
        super().__init__()
        self.found: list[tuple[str, str]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        name = URL_ATTRIBUTES.get(tag)
        value = dict(attrs).get(name) if name else None
        if value:
            url = urlsplit(value)
            if not url.scheme and not url.netloc and url.path and not url.path.startswith("/"):
                self.found.append((tag, unquote(url.path)))


def missing_targets(site_dir: Path) -> list[str]:
    """Every local image, link, stylesheet or script of the built site at `site_dir` that names no file (a folder
    counts when it holds index.html), as "page: <tag> target"."""
    missing = []
    for page in sorted(site_dir.rglob("*.html")):
        parser = _Targets()
        parser.feed(page.read_text(encoding="utf-8", errors="replace"))
        for tag, target in parser.found:
            path = (page.parent / target).resolve()
            if not (path.is_file() or (path / "index.html").is_file()):
                missing.append(f"{page.relative_to(site_dir).as_posix()}: <{tag}> {target}")
    return missing


def on_post_build(config: Any) -> None:
    for problem in missing_targets(Path(config.site_dir)):
        log.warning(f"the built site has a broken target: {problem}")


def on_page_content(html: str, page: Any, config: Any, files: Files) -> str:
    for problem in rendering_problems(html):
        log.warning(
            f"{page.file.src_uri}: {problem} (in a docstring? put <words> in backticks; leave a blank line before a list)"
        )
    return html

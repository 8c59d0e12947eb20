"""The Layout of a page (docs/layout.md), generated from the source tree: for each package a table with one row
per module and the first sentence of its docstring, so that no module is left out and no description goes stale.

A block is

```
<!-- layout:begin ../mobman_env ../policies ../eval ../train -->
... one table per package, rebuilt from the files ...
<!-- layout:end -->
```

with the package folders relative to the file that holds the block (inside its repository: `source_path`; the
block above is docs/layout.md's). `render_layout(text, root)` regenerates every block; `mobman-eval readme FILE`
writes the result beside the other generated blocks, and `tests/test_readme_layout.py` keeps docs/layout.md
equal to it. The modules are read as text (`ast`), never imported.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

from eval.errors import EvalError
from eval.output.blocks import replace_blocks
from eval.output.readme import read_text, source_path

#: `<!-- layout:begin PACKAGE... -->` ... `<!-- layout:end -->` (for reading a committed page: rendering finds
#: the blocks in one pass, `eval.output.blocks.replace_blocks`)
LAYOUT_BLOCK = re.compile(r"(<!-- layout:begin (?P<packages>[^>]*?) -->\n)(?P<body>.*?)(<!-- layout:end -->)", re.S)
#: the end of a docstring's first sentence: a full stop before a capital or a code span (not after e.g., i.e., vs)
_SENTENCE_END = re.compile(r"(?<!e\.g)(?<!i\.e)(?<!\bvs)\.(?=\s+[A-Z`])")


def first_sentence(path: Path, name: str) -> str:
    """The first sentence of the module docstring of `path` (its first paragraph, whitespace collapsed), without
    a leading `name:` that repeats the module's name; EvalError when the module has no docstring or is not
    Python source (the module is parsed, never imported)."""
    source = read_text(path, "module")
    try:
        doc = ast.get_docstring(ast.parse(source, filename=str(path)))
    except (SyntaxError, ValueError) as exc:
        raise EvalError(f"{path} is not Python source ({type(exc).__name__}: {exc}); fix the module") from None
    if not doc:
        raise EvalError(f"{path} has no module docstring; the Layout shows its first sentence, so write one")
    paragraph = " ".join(doc.split("\n\n")[0].split())
    end = _SENTENCE_END.search(paragraph)
    sentence = paragraph[: end.end()] if end else paragraph
    prefix = f"{name}: "
    return sentence[len(prefix) :] if sentence.startswith(prefix) else sentence


def modules(package: Path) -> list[Path]:
    """The package's modules, the package's own `__init__.py` first, then by path (a sub-package before its
    modules)."""
    files = sorted(package.rglob("*.py"), key=lambda p: p.relative_to(package).with_suffix("").parts)
    init = package / "__init__.py"
    return [init, *(f for f in files if f != init)] if init.is_file() else files


def _row_name(package: Path, path: Path) -> str:
    rel = path.relative_to(package).with_suffix("")
    if rel.name == "__init__":
        return "/".join(rel.parts[:-1]) + "/"
    return "/".join(rel.parts)


def package_table(package: Path) -> str:
    """`**`pkg/`**: its first sentence`, then one row per module: name, first sentence."""
    found = modules(package)
    if not found:
        raise EvalError(f"{package} holds no Python module")
    dotted = package.name
    head = f"**`{dotted}/`**: {first_sentence(found[0], dotted)}" if found[0].name == "__init__.py" else ""
    rows = ["| module | what it is |", "|---|---|"]
    for path in found[1:] if head else found:
        name = _row_name(package, path)
        own = dotted + "." + name.rstrip("/").replace("/", ".")
        text = first_sentence(path, own).replace("|", "\\|")
        rows.append(f"| `{name}` | {text} |")
    return "\n".join([head, "", *rows] if head else rows) + "\n"


def render_layout(text: str, root: str | Path, repo: Path | None = None) -> tuple[str, list[str]]:
    """`text` with every layout block rebuilt from the package folders it names (relative to `root`, inside
    `repo`), and those folders (each once, in order); the blocks are found and their text escaped by
    `eval.output.blocks.replace_blocks`."""
    root = Path(root)
    found: list[str] = []

    def rebuild(packages: str) -> str:
        tables = []
        for rel in packages.split():
            folder = source_path(root, rel, repo)
            if not folder.is_dir():
                raise EvalError(f"a layout block names {rel}, which is not a folder (relative to {root})")
            tables.append(package_table(folder))
            if rel not in found:
                found.append(rel)
        return "\n".join(tables)

    return replace_blocks(text, "layout", rebuild)[0], found

"""Generated blocks of a Markdown file (the README, docs pages): text copied, by a command, from a committed
Markdown file that mobman wrote from its results (`paper.md` of `mobman-eval paper`, `summary.md` of
`mobman-eval run`), so that no figure in the README is typed by hand and none can go stale unnoticed.

A block is

```
<!-- generated:begin docs/results/paper/paper.md Claims -->
... the body of the section "## Claims" of that file, verbatim ...
<!-- generated:end -->
```

with the path relative to the file that holds the block and the section title after it (the rest of the line;
`*` for the whole file). `render_generated(text, root)` regenerates every block; `mobman-eval readme FILE`
writes the result, and a test keeps the README equal to it.
"""

from __future__ import annotations

import re
from pathlib import Path

from eval.errors import EvalError

#: `<!-- generated:begin PATH SECTION -->` ... `<!-- generated:end -->`
GENERATED_BLOCK = re.compile(
    r"(<!-- generated:begin (?P<path>\S+) (?P<section>[^>]*?) -->\n)(?P<body>.*?)(<!-- generated:end -->)", re.S
)


def markdown_section(text: str, title: str) -> str:
    """The body of the level-2 section "## title" of a Markdown text (up to the next "## " heading), stripped
    and ending with a newline; `*` gives the whole text."""
    if title == "*":
        return text.strip() + "\n"
    marker = f"## {title}\n"
    if marker not in text:
        found = [ln[3:] for ln in text.splitlines() if ln.startswith("## ")]
        raise EvalError(f"no section '## {title}'; the file's sections: {found}")
    body = text.split(marker, 1)[1]
    end = body.find("\n## ")
    return (body if end < 0 else body[:end]).strip() + "\n"


def render_generated(text: str, root: str | Path) -> tuple[str, list[str]]:
    """`text` with every generated block rebuilt from the file it names (relative to `root`), and the paths of
    those files (each once, in order). EvalError when a block names a missing file or section."""
    root = Path(root)
    found: list[str] = []

    def sub(m: re.Match) -> str:
        rel = m.group("path")
        path = root / rel
        if not path.is_file():
            raise EvalError(f"a generated block names {rel}, which does not exist (relative to {root})")
        try:
            body = markdown_section(path.read_text(encoding="utf-8"), m.group("section"))
        except EvalError as exc:
            raise EvalError(f"{rel}: {exc}") from None
        if rel not in found:
            found.append(rel)
        return m.group(1) + body + m.group(5)

    return GENERATED_BLOCK.sub(sub, text), found

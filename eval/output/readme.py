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
`*` for the whole file). `render_generated(text, root)` regenerates every block (`eval.output.blocks`: one pass
over the page, the copied text escaped so that it cannot end its block or inject HTML); `mobman-eval readme
FILE` writes the result, and a test keeps the README equal to it. Pages and sources are read with `read_text`:
a regular file of at most `MAX_PAGE_BYTES`, UTF-8, else `EvalError` naming the file and the fix.

A page copies only from its own repository (`source_path`): the path a block names, symlinks resolved, must lie
inside the page's repository (the nearest folder above it holding `.git` or `pyproject.toml`, else the page's
folder), so that a block naming `/etc/passwd` or `../../x` cannot copy a file from elsewhere into the page.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from eval.errors import EvalError
from eval.output.blocks import replace_blocks
from policies.agents.untrusted import FileRefused, read_regular

#: the largest page or source file `mobman-eval readme` reads (the README is about 60 kB)
MAX_PAGE_BYTES = 16 * 2**20


#: what marks a repository's top folder: a git checkout (`.git`, a folder or a worktree's file), or a source tree
#: without git, such as an unpacked sdist (its `pyproject.toml`)
REPOSITORY_MARKERS = (".git", "pyproject.toml")


def repository_of(folder: Path) -> Path:
    """The repository of a page in `folder`: the nearest folder at or above it holding one of
    `REPOSITORY_MARKERS`, else `folder` itself; resolved."""
    folder = Path(folder).resolve()
    for candidate in (folder, *folder.parents):
        if any((candidate / marker).exists() for marker in REPOSITORY_MARKERS):
            return candidate
    return folder


def source_path(root: Path, rel: str, repo: Path | None = None) -> Path:
    """The file a block names (`rel`, relative to `root`, the page's folder), resolved; EvalError when it
    resolves outside `repo` (default: `repository_of(root)`)."""
    repo = repository_of(root) if repo is None else Path(repo).resolve()
    path = (Path(root) / rel).resolve()
    if not path.is_relative_to(repo):
        raise EvalError(
            f"a generated block names {rel}, which resolves to {path}, outside the page's repository {repo}; "
            f"a page copies only from its own repository: name a results file inside it"
        )
    return path


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


def read_text(path: Path, what: str) -> str:
    """The text of a page or source file: a regular file of at most `MAX_PAGE_BYTES` holding UTF-8; EvalError
    naming the file, what is wrong and the fix otherwise (a FIFO is never opened, a device never read)."""
    try:
        data = read_regular(Path(path), MAX_PAGE_BYTES, what)
    except FileRefused as exc:
        raise EvalError(str(exc)) from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise EvalError(
            f"{path}: the {what} is not UTF-8 text (byte {data[exc.start]:#04x} at offset {exc.start}); save it "
            f"as UTF-8"
        ) from None


#: a Markdown link or image target: `[text](target)` / `![alt](target)`, the target without spaces or a title
_LINK = re.compile(r"(!?\[[^\]\n]*\]\()([^)\s]+)(\))")


def rebase_links(body: str, source_dir: Path, page_dir: Path) -> str:
    """`body` (Markdown copied from a file in `source_dir`) with its relative link and image targets rewritten
    relative to `page_dir`, so that a copied `![plot](plots/x.png)` still shows the file next to its source;
    absolute URLs, absolute paths and anchors stay as they are."""

    def rebase(m: re.Match) -> str:
        target = m.group(2)
        if target.startswith(("#", "/")) or re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", target):
            return m.group(0)
        path, hash_, anchor = target.partition("#")
        moved = Path(os.path.relpath(source_dir / path, page_dir)).as_posix()
        return f"{m.group(1)}{moved}{hash_}{anchor}{m.group(3)}"

    return _LINK.sub(rebase, body)


def render_generated(text: str, root: str | Path, repo: Path | None = None) -> tuple[str, list[str]]:
    """`text` with every generated block rebuilt from the file it names (relative to `root`, inside `repo`:
    `source_path`), and the paths of those files (each once, in order). EvalError when a block names a missing
    file or section, or a file outside the repository, or when the blocks are malformed (`replace_blocks`)."""
    root = Path(root)
    found: list[str] = []

    def rebuild(args: str) -> str:
        rel, _, section = args.partition(" ")
        if not rel or not section.strip():
            raise EvalError(
                f"a generated block names {args!r}; write '<!-- generated:begin PATH SECTION -->' (SECTION: a "
                f"'## ' heading of PATH, or * for the whole file)"
            )
        path = source_path(root, rel, repo)
        if not path.is_file():
            raise EvalError(f"a generated block names {rel}, which does not exist (relative to {root})")
        try:
            body = markdown_section(read_text(path, "source file"), section.strip())
        except EvalError as exc:
            raise EvalError(f"{rel}: {exc}") from None
        if rel not in found:
            found.append(rel)
        return rebase_links(body, path.parent, root)

    return replace_blocks(text, "generated", rebuild)[0], found

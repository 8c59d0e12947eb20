"""The blocks `mobman-eval readme` regenerates in a Markdown page, found in one pass, and the escaping of what is
copied into them.

A block of kind K (`generated`, `bench`, `layout`) is a line `<!-- K:begin ARGS -->`, the body, and a line that
starts with `<!-- K:end -->`; both markers start their line. `replace_blocks(text, K, rebuild)` walks the page's
lines once (linear in its size: the regular expressions it replaces rescanned the rest of the page from every
begin marker, and a 672 KB hostile page took 284 s) and replaces each body with `rebuild(ARGS)`. A begin inside
an open block, an end without a begin and a begin without an end are refused (`EvalError` naming the line), as is
a begin line that does not end in ` -->`.

Everything a body holds was copied from a file (a scorecard's names, a Markdown section, a docstring), so it goes
through `escape_copied` before it enters the page. Outside code, a `<` that could start markup (CommonMark's raw
HTML and autolinks begin `<` + a letter, `/`, `!` or `?`: a tag, a comment, a declaration) becomes `&lt;` and an
`&` that could start an entity reference (`&` + a letter or `#`) becomes `&amp;`: the rendered page shows the
same characters, no copied text can inject HTML, a comment or an entity, and the text a reader sees in the raw
file stays as written where it is plain (`<= 6 mm`, `a -> b`: a `<` before a space or `=`, a `>` and a lone `&`
start nothing, so they are left alone). Inside code spans and fenced code, where entities would show literally,
a `<!--` gets a zero-width space after its `<!`. No copied
text can then hold a block marker, so a body can never close its block early or open another one, and rendering
a page twice gives the same page. Code is recognised as CommonMark does on one line (a run of n backticks up to
the next run of exactly n) and between fence lines (```` ``` ```` or `~~~`); a code span across a line break is
escaped as text (it then shows `&lt;` where `<` was: safe, and rare in mobman's own files).

Imports the standard library and `eval.errors` only.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from eval.errors import EvalError

__all__ = ["escape_copied", "replace_blocks"]

_BACKTICKS = re.compile(r"`+")
#: a `<` that starts a tag, comment, declaration or autolink; an `&` that starts an entity reference
_MARKUP_LT = re.compile(r"<(?=[A-Za-z/!?])")
_ENTITY_AMP = re.compile(r"&(?=[A-Za-z#])")
_FENCE = re.compile(r" {0,3}(```|~~~)")
#: what a comment opener becomes inside code: `<!` + ZERO WIDTH SPACE + `--` (looks the same, opens nothing)
_INERT_COMMENT = "<!\u200b--"


def _code_inert(code: str) -> str:
    return code.replace("<!--", _INERT_COMMENT)


def _text_inert(text: str) -> str:
    return _MARKUP_LT.sub("&lt;", _ENTITY_AMP.sub("&amp;", text))


def _escape_line(line: str) -> str:
    """One line outside fenced code: text escaped, code spans kept but for their comment openers. Linear: each
    backtick run is paired with the next run of the same length (a table built right to left)."""
    runs = [(m.start(), m.end()) for m in _BACKTICKS.finditer(line)]
    if not runs:
        return _text_inert(line)
    following: list[int | None] = [None] * len(runs)
    last: dict[int, int] = {}
    for k in range(len(runs) - 1, -1, -1):
        size = runs[k][1] - runs[k][0]
        following[k] = last.get(size)
        last[size] = k
    out, pos, k = [], 0, 0
    while k < len(runs):
        close = following[k]
        if close is None:  # backticks with no closer are text
            k += 1
            continue
        start, end = runs[k][0], runs[close][1]
        out += [_text_inert(line[pos:start]), _code_inert(line[start:end])]
        pos, k = end, close + 1
    out.append(_text_inert(line[pos:]))
    return "".join(out)


def escape_copied(text: str) -> str:
    """`text` (Markdown copied from a file) safe inside a page's block: see the module docstring."""
    out, fence = [], ""
    for line in text.split("\n"):
        opener = _FENCE.match(line)
        if fence:
            out.append(_code_inert(line))
            if opener and opener.group(1) == fence:
                fence = ""
        elif opener:
            fence = opener.group(1)
            out.append(_code_inert(line))
        else:
            out.append(_escape_line(line))
    return "\n".join(out)


def replace_blocks(text: str, kind: str, rebuild: Callable[[str], str]) -> tuple[str, int]:
    """`text` with the body of every block of `kind` replaced by `escape_copied(rebuild(ARGS))` (a body always
    ends with a line break), and the number of blocks; one pass over the lines (see the module docstring)."""
    begin, end = f"<!-- {kind}:begin ", f"<!-- {kind}:end -->"
    out: list[str] = []
    open_line = 0  # the line number of the open block's begin marker; 0: none is open
    count = 0
    for number, line in enumerate(text.split("\n"), 1):
        if line.startswith(begin):
            if open_line:
                raise EvalError(
                    f"line {number}: a {kind} block begins inside the one begun on line {open_line}; close that "
                    f"one first with a line '{end}'"
                )
            marker = line.rstrip("\r")
            if not marker.endswith(" -->"):
                raise EvalError(
                    f"line {number}: {marker[:80]!r} starts a {kind} block but does not end with ' -->'; write "
                    f"'{begin}ARGS -->' on one line"
                )
            body = escape_copied(rebuild(marker[len(begin) : -len(" -->")].strip()))
            out += [line, body[:-1] if body.endswith("\n") else body]
            open_line, count = number, count + 1
        elif line.startswith(end):
            if not open_line:
                raise EvalError(f"line {number}: '{end}' closes no block; remove it or add a '{begin}... -->' above")
            out.append(line)
            open_line = 0
        elif not open_line:
            out.append(line)
    if open_line:
        raise EvalError(f"line {open_line}: the {kind} block begun there has no line '{end}' after it; add one")
    return "\n".join(out), count

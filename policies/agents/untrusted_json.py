"""The one reader of every JSON file mobman loads (`read_json`), and the small schema language that checks its shape.

A results file, a scorecard or a run's `config.json` may come from a stranger. Before any work is done with
one, `read_json(path, max_bytes, what, schema)`:

1. opens it only if it is a regular file after following symlinks (`policies.agents.untrusted.open_regular`: a FIFO
   is never opened, so it cannot hang the reader; a symlink to `/dev/zero` is a device and is refused);
2. refuses it if it holds more than `max_bytes` (checked on the size before reading, and again on what was read);
3. decodes it as UTF-8, naming the byte offset of a bad byte;
4. parses it, refusing nesting deeper than `MAX_DEPTH` (Python's json parser recurses once per level: 100,000
   levels raise RecursionError; mobman's own files are at most 7 deep);
5. checks it against `schema` (the classes below), so that a file of the wrong shape is refused with the path of
   the field, what was found and what is expected, before anything runs: no traceback after an hour of episodes.

A large file may be stored compressed (xz, `eval.output.compact`): `NAME.json.xz` stands for `NAME.json`, which
`read_json` reads when only the compressed twin exists (or when it is named). The cap then bounds both the
compressed bytes and what they unpack to, checked while unpacking: a small xz file of a gigabyte of zeros is
refused after `max_bytes + 1` bytes, not after a gigabyte.

Every failure is a `policies.agents.untrusted.FileRefused` (a ValueError) naming the file; callers turn it into
their own error type (`eval.errors.EvalError`, exit 2 on the command line).

The schema language is a handful of classes, written once, with no dependency: `Int`, `Num`, `Str`, `Bool`,
`Nullable(s)`, `ListOf(s)`, `MapOf(s)` (an object with any keys, each value `s`), `Obj(required, optional)`
(an object whose named keys are checked; other keys are allowed: newer writers may add fields), `AnyJSON`.
A field path reads like Python: `rows[0].n`, `protocol.conditions.default.envs[2]`.

May import the standard library and `policies.agents.untrusted` only.
"""

from __future__ import annotations

import json
import lzma
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from policies.agents.untrusted import FileRefused, read_regular

__all__ = [
    "COMPRESSED_SUFFIX",
    "MAX_DEPTH",
    "AnyJSON",
    "Bool",
    "Int",
    "ListOf",
    "MapOf",
    "Nullable",
    "Num",
    "Obj",
    "Schema",
    "SchemaError",
    "Str",
    "json_depth",
    "parse_json",
    "read_json",
    "read_stored",
    "read_xz",
    "stored_path",
]

#: The suffix of a JSON file's compressed twin (`scorecard.json.xz` for `scorecard.json`).
COMPRESSED_SUFFIX = ".xz"

#: Deepest nesting a file may have (mobman's scorecards, results and configs are at most 7 levels deep).
MAX_DEPTH = 32


class SchemaError(FileRefused):
    """A JSON document whose shape is not what its kind requires (the message names the field path)."""


def describe(value: Any) -> str:
    """What was found, for an error message: `the string 'abc'`, `a list of 3 items`, `null`."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"the boolean {str(value).lower()}"
    if isinstance(value, (int, float)):
        return f"the number {value!r}"
    if isinstance(value, str):
        text = value if len(value) <= 60 else value[:57] + "..."
        return f"the string {text!r}"
    if isinstance(value, list):
        return f"a list of {len(value)} items"
    if isinstance(value, dict):
        return f"an object with {len(value)} keys"
    return type(value).__name__


class Schema:
    """A shape a JSON value must have: `check(value, where)` raises `SchemaError` naming `where`."""

    expected = "a JSON value"

    def check(self, value: Any, where: str) -> None:
        if not self.accepts(value):
            self.refuse(value, where)

    def refuse(self, value: Any, where: str) -> None:
        raise SchemaError(f"{where or 'the top level'} is {describe(value)}; expected {self.expected}")

    def accepts(self, value: Any) -> bool:
        return True


class _Type(Schema):
    def __init__(self, types: tuple[type, ...], expected: str):
        self.types = types
        self.expected = expected

    def accepts(self, value: Any) -> bool:
        return isinstance(value, self.types) and not (isinstance(value, bool) and bool not in self.types)


#: An integer (not a boolean).
Int = _Type((int,), "an integer")
#: A number, integer or float (not a boolean).
Num = _Type((int, float), "a number")
#: A string.
Str = _Type((str,), "a string")
#: true or false.
Bool = _Type((bool,), "true or false")
#: Any JSON value.
AnyJSON = Schema()


class Nullable(Schema):
    """`inner`, or null."""

    def __init__(self, inner: Schema):
        self.inner = inner
        self.expected = f"{inner.expected} or null"

    def check(self, value: Any, where: str) -> None:
        if value is not None:
            self.inner.check(value, where)


class ListOf(Schema):
    """A list whose every item is `item`."""

    def __init__(self, item: Schema):
        self.item = item
        self.expected = f"a list (of {item.expected})"

    def check(self, value: Any, where: str) -> None:
        if not isinstance(value, list):
            self.refuse(value, where)
        for i, v in enumerate(value):
            self.item.check(v, f"{where}[{i}]")


class MapOf(Schema):
    """An object with any keys, whose every value is `value`."""

    def __init__(self, value: Schema):
        self.value = value
        self.expected = f"an object (of {value.expected})"

    def check(self, value: Any, where: str) -> None:
        if not isinstance(value, dict):
            self.refuse(value, where)
        for k, v in value.items():
            self.value.check(v, _key(where, k))


class Obj(Schema):
    """An object with the `required` keys (each checked), and the `optional` ones checked where present; other
    keys are allowed (a newer writer may add fields, and nothing reads them)."""

    def __init__(self, required: Mapping[str, Schema], optional: Mapping[str, Schema] | None = None):
        self.required = dict(required)
        self.optional = dict(optional or {})
        self.expected = "an object" + (f" with the keys {', '.join(self.required)}" if self.required else "")

    def check(self, value: Any, where: str) -> None:
        if not isinstance(value, dict):
            self.refuse(value, where)
        for key, schema in self.required.items():
            if key not in value:
                raise SchemaError(f"{_key(where, key)} is missing; expected {schema.expected}")
            schema.check(value[key], _key(where, key))
        for key, schema in self.optional.items():
            if key in value:
                schema.check(value[key], _key(where, key))


def _key(where: str, key: str) -> str:
    """The field path of `key` inside `where` ("" is the top level): dotted for a plain name, else quoted
    (`conditions['a.b']`), so a key with a terminal escape or a dot cannot garble or fake the message."""
    if key.replace("_", "a").replace("-", "a").isalnum() and key.isascii():
        return f"{where}.{key}" if where else key
    return f"{where}[{key!r}]"


def json_depth(data: Any) -> int:
    """The nesting depth of a parsed JSON value (a scalar is 0, `[1]` is 1), without recursion."""
    deepest = 0
    stack = [(data, 0)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, dict):
            stack.extend((v, depth + 1) for v in value.values())
        elif isinstance(value, list):
            stack.extend((v, depth + 1) for v in value)
        else:
            continue
        deepest = max(deepest, depth + 1)
    return deepest


def parse_json(data: bytes, where: str, schema: Schema | None = None) -> Any:
    """The JSON value in `data` (UTF-8), at most `MAX_DEPTH` deep, checked against `schema`; `FileRefused`
    naming `where` (the file, or a file and a line) and the field path otherwise."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise FileRefused(f"{where}: not UTF-8 text (byte {exc.start} is {data[exc.start]:#04x})") from None
    try:
        value = json.loads(text)
    except RecursionError:
        raise FileRefused(f"{where}: nested deeper than {MAX_DEPTH} levels; no mobman file is") from None
    except ValueError as exc:
        raise FileRefused(f"{where}: not valid JSON ({exc})") from None
    depth = json_depth(value)
    if depth > MAX_DEPTH:
        raise FileRefused(f"{where}: nested {depth} levels deep; at most {MAX_DEPTH} are read, and no mobman file is")
    if schema is not None:
        try:
            schema.check(value, "")
        except SchemaError as exc:
            raise SchemaError(f"{where}: {exc}") from None
    return value


def stored_path(path: str | Path) -> Path:
    """The file that holds `path`'s content: `path` itself if it exists (or is a symlink), else its compressed twin
    `path.xz` if that exists, else `path` (whose reader then says it does not exist)."""
    path = Path(path)
    if path.exists() or path.is_symlink():
        return path
    twin = path.with_name(path.name + COMPRESSED_SUFFIX)
    return twin if twin.exists() or twin.is_symlink() else path


def read_xz(path: Path, max_bytes: int, what: str) -> bytes:
    """The bytes the xz file `path` unpacks to, if it is a regular file of at most `max_bytes` and unpacks to at
    most `max_bytes` (checked while unpacking); `FileRefused` naming the file, the cap and the fix otherwise."""
    packed = read_regular(path, max_bytes, what)
    unpacker = lzma.LZMADecompressor(format=lzma.FORMAT_XZ)
    try:
        data = unpacker.decompress(packed, max_length=max_bytes + 1)
    except lzma.LZMAError as exc:
        raise FileRefused(f"{path}: not a valid xz file ({exc}); copy the {what} again") from None
    if len(data) > max_bytes:
        raise FileRefused(
            f"{path} unpacks to more than {max_bytes} bytes; a {what} is at most that: copy it again from the run"
        )
    if not unpacker.eof:
        raise FileRefused(f"{path}: the xz stream is cut short; copy the {what} again")
    return data


def read_stored(path: str | Path, max_bytes: int, what: str) -> tuple[Path, bytes]:
    """The file that holds `path` (`stored_path`: it, or its compressed twin) and the JSON bytes it stands for
    (unpacked if it is an xz file), under the checks of the module docstring; `FileRefused` naming the file and
    the fix otherwise, FileNotFoundError when neither exists."""
    path = stored_path(path)
    if not path.exists() and not path.is_symlink():
        raise FileNotFoundError(f"{path}: no such {what}")
    if path.name.endswith(COMPRESSED_SUFFIX):
        return path, read_xz(path, max_bytes, what)
    return path, read_regular(path, max_bytes, what)


def read_json(path: str | Path, max_bytes: int, what: str, schema: Schema | None = None) -> Any:
    """The JSON value of the file `path` (a `what`: "results file", "scorecard", ...), after the checks of the
    module docstring; `FileRefused` naming the file and the fix otherwise (FileNotFoundError passes through
    unchanged when the file does not exist, so callers can say how to make it). `path` may be, or stand for, an
    xz-compressed twin (`read_stored`)."""
    stored, data = read_stored(path, max_bytes, what)
    return parse_json(data, str(stored), schema)

"""Compact storage of large results: `NAME.json` -> `NAME.json.xz`, read back by every JSON reader.

A scorecard of a full bench holds about 2,000 aggregate rows of float statistics (8-18 MB of JSON); xz packs
one to about 14% of that. `compact(path)` writes the twin (deterministic: the same bytes give the same file),
unpacks it again and compares the bytes before it removes the original, and returns a record of both (sizes,
the original's SHA-256 and git blob id). `policies.agents.untrusted_json.read_json` reads `NAME.json` from its twin
when only the twin exists, so `load_scorecard`, `load_results` (a file or its folder), `bench --against DIR`,
`mobman-eval readme`, `mobman-eval plots` and `mobman-train report --include` take either form, and a compacted
file's bytes are the original's: nothing is rounded. docs/results/compacted.json records the committed files
compacted so (`tests/test_compact.py` checks each against its record, and that every reader gives the same from
it as from the original).

Command line: `mobman-eval compact FILE... [--manifest FILE]`.
"""

from __future__ import annotations

import hashlib
import json
import lzma
from pathlib import Path

from eval.errors import EvalError
from eval.output.files import atomic_write_bytes, atomic_write_json
from policies.agents.untrusted_json import COMPRESSED_SUFFIX, parse_json, read_stored, read_xz

__all__ = ["MAX_JSON_BYTES", "compact", "git_blob_id", "stored_bytes", "update_manifest"]

#: The largest JSON file `compact` packs (and the cap its check reads back with).
MAX_JSON_BYTES = 1 << 30

#: xz preset: level 9 (a 64 MiB dictionary; unpacking needs about 65 MiB).
PRESET = 9


def git_blob_id(data: bytes) -> str:
    """The id git gives a file of these bytes (`git hash-object`), so the original can be found in the history."""
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def stored_bytes(path: str | Path, max_bytes: int = MAX_JSON_BYTES) -> bytes:
    """The JSON bytes of the file `path` stands for, read from `path` or from its compressed twin (`path.xz`):
    `policies.agents.untrusted_json.read_stored` with this module's cap."""
    return read_stored(path, max_bytes, "JSON file")[1]


def compact(path: str | Path) -> dict:
    """Pack the JSON file `path` into `path.xz`, check that it unpacks to the same bytes, remove `path`, and return
    the record {file, bytes, xz_bytes, sha256, git_blob}. EvalError (nothing removed) if `path` is not a JSON file
    or its twin exists."""
    path = Path(path)
    if path.name.endswith(COMPRESSED_SUFFIX):
        raise EvalError(f"{path} is already compacted; give the .json file it stands for")
    twin = path.with_name(path.name + COMPRESSED_SUFFIX)
    if twin.exists():
        raise EvalError(f"{twin} exists already; remove it (or {path}) first, so that no file is overwritten")
    try:
        data = read_stored(path, MAX_JSON_BYTES, "JSON file")[1]  # `path` itself: it is not .xz, no twin exists
        parse_json(data, str(path))
    except FileNotFoundError:
        raise EvalError(f"{path}: no such file; give a JSON file to compact") from None
    except ValueError as exc:
        raise EvalError(f"cannot compact {path}: {exc}") from None
    packed = lzma.compress(data, format=lzma.FORMAT_XZ, check=lzma.CHECK_CRC64, preset=PRESET)
    atomic_write_bytes(twin, packed)
    if read_xz(twin, MAX_JSON_BYTES, "JSON file") != data:  # pragma: no cover - lzma is lossless
        twin.unlink()
        raise EvalError(f"{twin} did not unpack to {path}'s bytes; {path} is kept")
    path.unlink()
    return {
        "file": path.name,
        "bytes": len(data),
        "xz_bytes": len(packed),
        "sha256": hashlib.sha256(data).hexdigest(),
        "git_blob": git_blob_id(data),
    }


def update_manifest(manifest: str | Path, records: list[dict], paths: list[Path]) -> None:
    """Add `records` (of the files `paths`, named relative to the manifest's folder) to the JSON manifest."""
    manifest = Path(manifest)
    entries = json.loads(manifest.read_text()) if manifest.exists() else {}
    for rec, p in zip(records, paths, strict=True):
        key = Path(p).resolve().relative_to(manifest.resolve().parent).as_posix()
        entries[key] = {k: v for k, v in rec.items() if k != "file"}
    atomic_write_json(manifest, dict(sorted(entries.items())))

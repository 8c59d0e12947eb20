"""`mobman-eval compact FILE...`: store large JSON results (a scorecard, a results file) as `FILE.xz`, which every
mobman reader takes in place of `FILE` (`eval.output.compact`); prints a line per file."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from eval.cli.options import Opt, add_options, build
from eval.output.compact import compact, update_manifest


@dataclass(frozen=True)
class CompactCommand:
    """The files `mobman-eval compact` packs."""

    files: tuple[str, ...]
    """JSON files to store as FILE.xz (each is unpacked again and compared before FILE is removed)."""
    manifest: str | None = None
    """A JSON file to add each file's record to (sizes, SHA-256 and git blob id of the original bytes)."""


OPTIONS = (Opt("files", positional=True, metavar="FILE"), Opt("manifest", metavar="FILE"))


def add_parser(sub) -> None:
    p = sub.add_parser(
        "compact",
        help="store large JSON results as FILE.xz, which every mobman reader takes in place of FILE",
        description=(__doc__ or "").split("\n\n")[0],
    )
    add_options(p, CompactCommand, OPTIONS)


def main(args) -> int:
    config = build(CompactCommand, args, OPTIONS)
    paths = [Path(f) for f in config.files]
    records = []
    for path in paths:
        rec = compact(path)
        records.append(rec)
        print(f"{path} -> {path.name}.xz: {rec['bytes']} -> {rec['xz_bytes']} bytes ({json.dumps(rec['sha256'])})")
    if config.manifest:
        update_manifest(config.manifest, records, paths)
    return 0

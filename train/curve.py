"""The learning-curve file of a run folder, `learning_curve.csv`: its columns, reading and writing (the
periodic evaluation appends to it; `mobman-train report` reads it without loading SB3 or torch).

Imports: the standard library and `eval.output.files`.
"""

from __future__ import annotations

import csv
from pathlib import Path

from eval.output.files import atomic_write_text

#: Columns: env steps, wall-clock seconds since the start of training (all sessions), and the summary of the
#: periodic evaluation on the development seeds (m; success rate in [0, 1]).
CURVE_FIELDS = (
    "timesteps",
    "wall_s",
    "median_rms_error_m",
    "max_rms_error_m",
    "median_max_error_m",
    "max_max_error_m",
    "success_rate",
)


def read_curve(path: Path) -> list[dict]:
    """The rows (floats); [] when the file does not exist yet."""
    if not Path(path).exists():
        return []
    with open(path, newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def write_curve(path: Path, rows: list[dict]) -> None:
    """Write `rows` (atomically), every value as a float's repr."""
    lines = [",".join(CURVE_FIELDS)] + [",".join(repr(float(r[k])) for k in CURVE_FIELDS) for r in rows]
    atomic_write_text(path, "\n".join(lines) + "\n")

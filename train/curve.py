"""The learning-curve file of a run folder, `learning_curve.csv`: its columns, reading and writing (the
periodic evaluation appends to it; `mobman-train report` reads it without loading SB3 or torch).

Imports: the standard library, `eval.output.files` and `policies.agents.untrusted`.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

from eval.output.files import atomic_write_text
from policies.agents.untrusted import read_regular

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


#: Cap on a curve file (a row per evaluation: about 100 bytes).
MAX_CURVE_BYTES = 64 * 2**20


def read_curve(path: Path, run_columns: tuple[str, ...] = ()) -> list[dict]:
    """The rows (floats; the `run_columns` kept as text); [] when the file does not exist yet. ValueError
    naming the file, the line and the value for a file that is not a regular file of at most
    `MAX_CURVE_BYTES` (`policies.agents.untrusted.read_regular`), lacks the `timesteps` / `wall_s` columns, or has a
    row with more or fewer fields than the header or a value that is not a number."""
    path = Path(path)
    if not path.exists() and not path.is_symlink():
        return []
    try:
        text = read_regular(path, MAX_CURVE_BYTES, "learning curve").decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path} is not a text CSV file ({exc}); copy it again from the run") from None
    reader = csv.DictReader(io.StringIO(text, newline=""))
    header = reader.fieldnames or []
    missing = [c for c in ("timesteps", "wall_s") if c not in header]
    if missing:
        raise ValueError(f"{path}: the header {header} lacks the column(s) {missing}; copy the file again from the run")
    rows = []
    for row in reader:
        where = f"{path}, line {reader.line_num}"
        if None in row or None in row.values():
            raise ValueError(
                f"{where}: {len(header) + len(row.get(None) or [])} fields where the header has {len(header)} "
                f"(or fewer); every row needs one value per column: copy the file again from the run"
            )
        try:
            rows.append({k: v if k in run_columns else float(v) for k, v in row.items()})
        except ValueError:
            bad = next(k for k, v in row.items() if k not in run_columns and not _is_number(v))
            raise ValueError(
                f"{where}: {bad} = {row[bad]!r} is not a number; copy the file again from the run"
            ) from None
    return rows


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def write_curve(path: Path, rows: list[dict]) -> None:
    """Write `rows` (atomically), every value as a float's repr."""
    lines = [",".join(CURVE_FIELDS)] + [",".join(repr(float(r[k])) for k in CURVE_FIELDS) for r in rows]
    atomic_write_text(path, "\n".join(lines) + "\n")

"""Results for analysis: `eval.load_results(path)` reads a results.json (or the folder holding one) of any
readable schema (1, 2, 3) and returns a `Results`, whose `to_dataframe()` and `aggregate_dataframe()` are pandas
DataFrames.

```python
import eval
res = eval.load_results("runs/first")          # a run or sweep folder, or its results.json (or results.json.xz)
df = res.to_dataframe()                         # one row per episode
df.groupby("policy")["max_error_m"].median()
res.aggregate_dataframe()                       # one row per (env, policy, dynamics, model_error, obs_noise)
```

Flattening (one column per scalar, so `df["max_error_m.iqm"]` and `df.query("`path.type` == 'circle'")`
work): a nested dict's keys are joined with dots (`path.type`, `path.radius`, `max_error_m.iqm`); a point or
per-axis triple (`start`, `axis_max_error_m`) becomes `.x`, `.y`, `.z` columns; an interval (`*_ci95`) becomes
`.low`, `.high`; other lists (the 31 points of `success_curve`) stay one column of lists. Values keep the
file's SI units (m, s, rad/s); null is NaN or None.

pandas is an optional extra (`pip install "mobman[pandas]"`); only the two DataFrame methods need it.
Imports `eval.output.results` and, inside the DataFrame methods, pandas.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from eval.errors import EvalError
from eval.output.results import ResultsView
from eval.output.results import load_results as load_results_dict
from policies.agents.untrusted_json import stored_path

#: List-valued keys split into one column per component: key -> component names.
COMPONENTS: dict[str, tuple[str, ...]] = {"start": ("x", "y", "z"), "axis_max_error_m": ("x", "y", "z")}

#: The components of an interval (a key ending in one of INTERVAL_SUFFIXES).
INTERVAL = ("low", "high")
INTERVAL_SUFFIXES = ("_ci95", "_ci")

PANDAS_HINT = 'pip install "mobman[pandas]"'


class Results(ResultsView):
    """A results.json loaded for analysis: `results` (the dict, in schema 2's shape; `schema` keeps the file's
    number), `path` (the file), `episodes`, `aggregate`, and the two DataFrame views."""

    def __init__(self, results: dict, path: Path):
        self.results = results
        self.path = path

    @property
    def schema(self) -> int:
        return int(self.results["schema"])

    def to_dataframe(self) -> Any:
        """The episode records as a pandas DataFrame: one row per episode, nested values flattened (module
        docstring), columns in the records' order."""
        return _dataframe([flatten(r) for r in self.episodes])

    def aggregate_dataframe(self) -> Any:
        """The aggregate rows as a pandas DataFrame: one row per (env, policy, dynamics, model_error,
        obs_noise), each statistic flattened (`max_error_m.median`, `max_error_m.iqm_ci95.low`, ...)."""
        return _dataframe([flatten(r) for r in self.aggregate])

    def __repr__(self) -> str:
        return f"Results({str(self.path)!r}, schema {self.schema}, {len(self.episodes)} episodes)"


def load_results(path: str | Path) -> Results:
    """Read `path`, a results.json or the folder of a run, sweep or bench holding one, of schema 1 to 4.

    EvalError naming the fix for a missing file, a folder without results.json (a bench folder of mobman < 0.4:
    a condition's `conditions/<name>/results.json`), or a file that is not a readable results file.
    """
    path = Path(path)
    if path.is_dir():
        folder, path = path, path / "results.json"
        stored = stored_path(path)  # results.json, or its compacted twin results.json.xz
        if not stored.exists() and not stored.is_symlink():  # a FIFO or a device there is refused by the reader
            bench = sorted(str(p.relative_to(folder)) for p in folder.glob("conditions/*/results.json"))
            hint = (
                f"it is a bench: load a condition's file, one of {', '.join(bench)}"
                if bench
                else "give the folder of a `mobman-eval run` or `sweep`, or the path of its results.json"
            )
            raise EvalError(f"{str(folder)!r} holds no results.json; {hint}")
    return Results(load_results_dict(path), path)


def flatten(record: dict, prefix: str = "") -> dict[str, Any]:
    """One level of columns from a nested record (the rules of the module docstring)."""
    out: dict[str, Any] = {}
    for key, value in record.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, name + "."))
            continue
        parts = _parts(str(key), value) if isinstance(value, (list, tuple)) else None
        if parts is None:
            out[name] = value
        else:
            out.update({f"{name}.{part}": v for part, v in zip(parts, value)})
    return out


def _parts(key: str, value: list | tuple) -> tuple[str, ...] | None:
    parts = COMPONENTS.get(key) or (INTERVAL if key.endswith(INTERVAL_SUFFIXES) else None)
    return parts if parts is not None and len(value) == len(parts) else None


def _dataframe(rows: list[dict]) -> Any:
    try:
        import pandas as pd
    except ImportError:
        raise ImportError(
            f"Results.to_dataframe() and aggregate_dataframe() need pandas, which is not installed: {PANDAS_HINT}"
        ) from None
    return pd.DataFrame.from_records(rows)

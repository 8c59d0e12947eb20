"""Reports: records -> results.json, results.csv (tidy rows), summary.md, the console table; atomic writes.

Files of one run directory:

| file | content |
|---|---|
| results.json | schema 1: config, versions, git, episodes (one record each), aggregate (one row per condition); SI |
| results.csv | one row per episode, one column per variable (SI units; axis errors split into x/y/z columns) |
| summary.md | a table per env and dynamics mode, errors in mm |
| config.json | the resolved config (what the run was asked to do) |
| episodes.npz | per-step arrays: key "ep00012__r_a" = array "r_a" of the episode whose "arrays_key" is "ep00012" |
| plots/*.png | per env and dynamics mode: 3-D paths, per-axis errors and error norms of episode 0 |

Every file is written to a temporary name in the same directory and renamed (`os.replace`), so a crash never
leaves a half-written file and never destroys the previous version of a file before the new one is complete.

## results.json, schema 1 (SI units: m, s, rad/s; NaN/inf are written as null)

```
{"schema": 1,
 "config": {...},            # the resolved EvalConfig (as config.json), plus "policy_objects" {name: class}
 "versions": {"python", "mobman", "numpy", "gymnasium", "pybullet", "matplotlib", "stable-baselines3", "torch"},
 "git": "<sha>[-dirty]" | "unknown",
 "wall_s": float,            # time spent running the episodes
 "episodes": [ one record per (env, dynamics, policy, episode k), in that order:
   {"env", "policy", "episode": k, "seed": S + k, "dynamics", "model_error", "obs_noise", "control_freq" (Hz),
    "path": spec dict, "start": [x, y, z] (m), "true_params_hash",
    "status": "ok" | "failed", "error": traceback | null,
    "max_error_m", "rms_error_m", "final_error_m", "axis_max_error_m": [x, y, z],   # null if failed
    "effort" (s, integral of ||a||^2), "peak_joint_speed", "peak_wheel_speed" (rad/s, commanded),
    "joint_limit_hits", "n_clipped", "tipped_over", "terminated", "n_steps", "success",
    "predict_us_median", "predict_us_p99" (whole predict call, microseconds), "wall_s", "pid",
    "index" (position in this list), "arrays_key" (prefix in episodes.npz, or null)}],
 "aggregate": [ one row per (env, policy, dynamics, model_error, obs_noise):
   {"env", "policy", "dynamics", "model_error", "obs_noise", "n", "n_failed", "n_tipped_over", "success_rate",
    "max_error_m" | "rms_error_m" | "final_error_m" | "effort" | "peak_joint_speed" | "peak_wheel_speed" |
    "predict_us_median" | "predict_us_p99": {"median", "mean", "std", "min", "max"}}]}   # over status-ok episodes
```
Comparisons across workers or machines skip `wall_s`, `pid` and `predict_us_*`.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import platform
import subprocess
import tempfile
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

SCHEMA = 1
_VERSION_PACKAGES = ("mobman", "numpy", "gymnasium", "pybullet", "matplotlib", "stable-baselines3", "torch")


# --- atomic writes ---------------------------------------------------------------------------------------


def atomic_write_bytes(path: Path, data: bytes) -> None:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def atomic_write_text(path: Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: Path, data: Any) -> None:
    atomic_write_text(path, json.dumps(to_jsonable(data), indent=2, allow_nan=False) + "\n")


def atomic_save_figure(fig, path: Path, dpi: int = 110) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    atomic_write_bytes(path, buf.getvalue())


def atomic_savez(path: Path, arrays: dict[str, np.ndarray]) -> None:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def to_jsonable(x: Any) -> Any:
    """Plain JSON data: numpy scalars/arrays to Python, NaN/inf to None, tuples to lists."""
    if isinstance(x, dict):
        return {str(k): to_jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return to_jsonable(x.tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else None
    if x is None or isinstance(x, str):
        return x
    if isinstance(x, Path):
        return str(x)
    return repr(x)


# --- provenance ------------------------------------------------------------------------------------------


def versions() -> dict[str, str | None]:
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name in _VERSION_PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def git_rev() -> str:
    """The commit of the source tree the eval package runs from ("<sha>" or "<sha>-dirty"), or "unknown"."""
    here = Path(__file__).resolve().parent
    try:
        sha = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True, text=True, timeout=5)
        if sha.returncode != 0:
            return "unknown"
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=5,
        )
        return sha.stdout.strip() + ("-dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def build_results(config: dict, records: list[dict], aggregate: list[dict], wall_s: float | None = None) -> dict:
    return to_jsonable(
        {
            "schema": SCHEMA,
            "config": config,
            "versions": versions(),
            "git": git_rev(),
            "wall_s": wall_s,
            "episodes": records,
            "aggregate": aggregate,
        }
    )


def arrays_key(index: int) -> str:
    return f"ep{index:05d}"


# --- tidy rows -------------------------------------------------------------------------------------------

CSV_COLUMNS = (
    "index",
    "env",
    "policy",
    "episode",
    "seed",
    "dynamics",
    "model_error",
    "obs_noise",
    "control_freq",
    "path_type",
    "path",
    "true_params_hash",
    "status",
    "success",
    "max_error_m",
    "rms_error_m",
    "final_error_m",
    "axis_max_error_x_m",
    "axis_max_error_y_m",
    "axis_max_error_z_m",
    "effort",
    "peak_joint_speed",
    "peak_wheel_speed",
    "joint_limit_hits",
    "n_clipped",
    "tipped_over",
    "terminated",
    "n_steps",
    "predict_us_median",
    "predict_us_p99",
    "wall_s",
    "pid",
    "error_summary",
)


def csv_rows(records: list[dict]) -> list[dict]:
    """One tidy row per episode (SI units); the path spec as JSON, the traceback reduced to its last line."""
    rows = []
    for r in records:
        axis = r.get("axis_max_error_m") or [None, None, None]
        path = r.get("path")
        err = r.get("error")
        row = {k: r.get(k) for k in CSV_COLUMNS}
        row.update(
            {
                "path_type": path.get("type") if isinstance(path, dict) else None,
                "path": json.dumps(path, sort_keys=True) if path is not None else None,
                "axis_max_error_x_m": axis[0],
                "axis_max_error_y_m": axis[1],
                "axis_max_error_z_m": axis[2],
                "error_summary": err.strip().splitlines()[-1] if err else None,
            }
        )
        rows.append(row)
    return rows


def csv_text(records: list[dict]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, lineterminator="\n")
    w.writeheader()
    for row in csv_rows(records):
        w.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return buf.getvalue()


def _mm(x: float | None, digits: int = 2) -> str:
    return "-" if x is None else f"{x * 1e3:.{digits}f}"


def _num(x: float | None, fmt: str = "{:.2f}") -> str:
    return "-" if x is None else fmt.format(x)


SUMMARY_HEADER = (
    "policy",
    "n",
    "failed",
    "tipped over",
    "success",
    "max err median (mm)",
    "max err mean ± std (mm)",
    "rms median (mm)",
    "final median (mm)",
    "effort median (s)",
    "peak joint (rad/s)",
    "peak wheel (rad/s)",
    "predict median / p99 (µs)",
)


def summary_row(a: dict) -> list[str]:
    me = a["max_error_m"]
    return [
        str(a["policy"]),
        str(a["n"]),
        str(a["n_failed"]),
        str(a.get("n_tipped_over", 0)),
        f"{a['success_rate'] * 100:.0f}%",
        _mm(me["median"]),
        "-" if me["mean"] is None else f"{me['mean'] * 1e3:.2f} ± {me['std'] * 1e3:.2f}",
        _mm(a["rms_error_m"]["median"]),
        _mm(a["final_error_m"]["median"]),
        _num(a["effort"]["median"]),
        _num(a["peak_joint_speed"]["median"]),
        _num(a["peak_wheel_speed"]["median"]),
        f"{_num(a['predict_us_median']['median'], '{:.0f}')} / {_num(a['predict_us_p99']['median'], '{:.0f}')}",
    ]


def _conditions(aggregate: list[dict]) -> dict[tuple, list[dict]]:
    groups: dict[tuple, list[dict]] = {}
    for a in aggregate:
        groups.setdefault((a["env"], a["dynamics"], a["model_error"], a["obs_noise"]), []).append(a)
    return groups


def markdown_table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def summary_markdown(results: dict) -> str:
    cfg = results["config"]
    lines = [
        "# mobman-eval summary",
        "",
        f"{cfg['episodes']} episode(s) per policy and condition, seeds {cfg['seed']}..{cfg['seed'] + cfg['episodes'] - 1}; "
        f"success = max tracking error <= {cfg['tolerance'] * 1e3:g} mm over the whole episode (failed or tipped-over "
        f"episodes are not successes). Errors in mm, statistics over the episodes that ran (status ok). "
        f"git {results['git']}.",
        "",
    ]
    for (env, dyn, me, on), rows in _conditions(results["aggregate"]).items():
        lines += [
            f"## {env} — {dyn} (model_error {me}, obs_noise {on} m)",
            "",
            markdown_table(SUMMARY_HEADER, [summary_row(a) for a in rows]),
            "",
        ]
    lines += failed_episode_lines(
        results["episodes"],
        lambda r: f"{r['env']} / {r['dynamics']} / {r['policy']} / seed {r['seed']}",
        " (traceback in results.json)",
    )
    return "\n".join(lines)


class ResultsView:
    """`episodes` and `aggregate` of the results.json dict held in `self.results` (run and sweep results)."""

    results: dict

    @property
    def episodes(self) -> list[dict]:
        return self.results["episodes"]

    @property
    def aggregate(self) -> list[dict]:
        return self.results["aggregate"]


def failed_episode_lines(episodes: list[dict], describe, suffix: str = "") -> list[str]:
    """A Markdown section listing the failed episodes (last line of each traceback); [] when none failed.
    `describe(record)` names the episode's condition."""
    failed = [r for r in episodes if r["status"] != "ok"]
    if not failed:
        return []
    lines = [f"## Failed episodes ({len(failed)})", ""]
    for r in failed:
        last = (r.get("error") or "").strip().splitlines()
        lines.append(f"* {describe(r)}: `{last[-1] if last else 'unknown error'}`{suffix}")
    return lines + [""]


CONSOLE_HEADER = (
    "policy",
    "n",
    "failed\n/tipped",
    "succ",
    "max\nmed",
    "max\nmean",
    "rms\nmed",
    "final\nmed",
    "pred\nµs",
)


def console_row(a: dict) -> list[str]:
    me = a["max_error_m"]
    return [
        str(a["policy"]),
        str(a["n"]),
        f"{a['n_failed']}/{a.get('n_tipped_over', 0)}",
        f"{a['success_rate'] * 100:.0f}%",
        _mm(me["median"], 1),
        _mm(me["mean"], 1),
        _mm(a["rms_error_m"]["median"], 1),
        _mm(a["final_error_m"]["median"], 1),
        _num(a["predict_us_median"]["median"], "{:.0f}"),
    ]


def print_table(results: dict, out: Path | None = None) -> None:
    """A compact table per condition on stdout (errors in mm; summary.md has every column)."""
    from rich import box
    from rich.console import Console
    from rich.table import Table

    console = Console()
    for (env, dyn, me, on), rows in _conditions(results["aggregate"]).items():
        table = Table(
            title=f"{env} — {dyn} (model_error {me}, obs_noise {on} m)",
            box=box.SIMPLE_HEAD,
            caption="errors in mm: max over each episode, then median/mean over episodes; pred: median "
            "predict call; summary.md has all columns",
            padding=(0, 1),
        )
        for h in CONSOLE_HEADER:
            if h == "policy":
                longest = max(len(str(a["policy"])) for a in rows)
                table.add_column(h, justify="left", overflow="fold", min_width=min(max(longest, 6), 16))
            else:
                table.add_column(h, justify="right", no_wrap=True)
        for a in rows:
            table.add_row(*console_row(a))
        console.print(table)
    if out is not None:
        console.print(f"results in {out}")


# --- the run directory -----------------------------------------------------------------------------------


def write_run(result, config) -> None:
    """Write every file of a run directory (see the module docstring)."""
    out = Path(result.out)
    out.mkdir(parents=True, exist_ok=True)
    results = result.results
    atomic_write_json(out / "config.json", results["config"])
    atomic_write_json(out / "results.json", results)
    atomic_write_text(out / "results.csv", csv_text(results["episodes"]))
    atomic_write_text(out / "summary.md", summary_markdown(results))
    saved = {}
    for rec in results["episodes"]:
        key = rec.get("arrays_key")
        if key is not None:
            for name, arr in result.arrays[rec["index"]].items():
                saved[f"{key}__{name}"] = np.asarray(arr, dtype=np.float32)
    if saved:
        atomic_savez(out / "episodes.npz", saved)
    if config.plots:
        write_plots(result, out / "plots", config.tolerance)


def traces_for_plots(result) -> dict[tuple[str, str], list[dict]]:
    """(env, dynamics) -> the records of episode 0 of each policy with their arrays merged in."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for rec in result.results["episodes"]:
        if rec.get("episode") == 0 and rec["index"] in result.arrays:
            groups.setdefault((rec["env"], rec["dynamics"]), []).append({**rec, **result.arrays[rec["index"]]})
    return groups


def slug(text: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "-" for c in text)


def write_plots(result, plot_dir: Path, tolerance: float) -> list[Path]:
    import matplotlib.pyplot as plt

    from eval import plots

    written = []
    for (env, dyn), traces in traces_for_plots(result).items():
        stem = f"{slug(env)}_{dyn}"
        for name, fig in (
            ("paths3d", plots.plot_paths_3d(traces)),
            ("axis_errors", plots.plot_axis_errors(traces)),
            ("error_norm", plots.plot_error_norm(traces, tolerance)),
        ):
            path = plot_dir / f"{stem}_{name}.png"
            atomic_save_figure(fig, path)
            plt.close(fig)
            written.append(path)
    return written

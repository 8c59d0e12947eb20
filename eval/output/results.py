"""Results: records -> results.json, results.csv (tidy rows) and the whole run folder.

Files of one run directory:

| file | content |
|---|---|
| results.json | schema 4: config, versions, git, provenance, statistics, episodes (one record each), aggregate (one row per condition); SI |
| results.csv | one row per episode, one column per variable (SI units; axis errors split into x/y/z columns) |
| summary.md | a table per env and dynamics mode, errors in mm |
| config.json | the resolved config (what the run was asked to do) |
| episodes.npz | per-step arrays: key "ep00012__r_a" = array "r_a" of the episode whose "arrays_key" is "ep00012" |
| plots/*.png | per env and dynamics mode: 3-D paths, per-axis errors and error norms of episode 0 |

Every file is written to a temporary name in the same directory and renamed (`os.replace`), so a crash never
leaves a half-written file and never destroys the previous version of a file before the new one is complete.

## results.json, schema 4 (SI units: m, s, rad/s; NaN/inf are written as null)

```
{"schema": 3,
 "config": {...},            # the resolved EvalConfig (as config.json), plus "policy_objects" {name: class}
 "versions": {"python", "mobman", "numpy", "gymnasium", "pybullet", "matplotlib", "stable-baselines3", "torch"},
 "git": "<sha>[-dirty]" | "unknown",
 "provenance": {"cpu", "machine", "cpu_count", "platform", "python", "numpy", "numpy_build", "blas": [{
    "user_api", "internal_api", "version", "architecture", "threading_layer", "num_threads", ...}],
    "env": {"OPENBLAS_CORETYPE", ...}, "versions", "git",
    "schema": 4, "code": sha256 of the four packages' source, "diff": {"sha256", "paths"} | null (a dirty
    tree's uncommitted changes, named; since provenance schema 4),
    "kernels": {module: sha256[:16] of its source}},   # eval.output.provenance.provenance()
 "statistics": {"iqm", "ci", "bootstrap_resamples", "bootstrap_seed", "success_interval",
    "success_curve_tolerances_m": [31 tolerances, 1e-4 .. 0.1 m], "settle_time_s"},  # how aggregates are made
 "wall_s": float,            # time spent running the episodes
 "episodes": [ one record per (env, dynamics, policy, episode k), in that order:
   {"env", "policy", "condition" (its name in the conditions table, `eval.conditions`, or the name its env
    arguments make: within one file a name means one set of env arguments; None only from `rollout` called
    directly), "episode": k, "seed": S + k, "robot", "knowledge" (none | structure | nominal | true |
    unknown), "artefacts" (files an SB3 agent loaded: [{"path", "sha256"}] | null), "dynamics", "model_error", "obs_noise", "control_freq" (Hz),
    "path": spec dict, "start": [x, y, z] (m), "true_params_hash",
    "feasible" (the path is within the true robot's speed limits with a 10% margin, `mobman_env.feasibility`;
    null for an env without mobman's engine), "feasibility_peak" (the reference law's peak speed ratio),
    "status": "ok" | "failed" | "interrupted" (Ctrl-C: never finished), "error": traceback | null,
    "max_error_m", "rms_error_m", "final_error_m", "axis_max_error_m": [x, y, z],   # null if failed
    "steady_max_error_m", "steady_rms_error_m",  # over t >= settle_time_s; null if failed or shorter
    "effort" (s, integral of ||a||^2), "peak_joint_speed", "peak_wheel_speed" (rad/s, commanded),
    "cmd_accel_rms" (rad/s^2), "cmd_jerk_rms" (rad/s^3),   # the commands' smoothness, from rest
    "limit_margin_min" (rad), "converge_time_s" (null: ends outside the tolerance),
    "joint_limit_hits", "n_clipped", "tipped_over", "terminated", "n_steps", "success", "clean_success",
    "predict_us_median", "predict_us_p99" (whole predict call, microseconds), "wall_s", "pid",
    "code" (SHA-256 of the four packages' source that ran it, `eval.output.provenance.code_hash`; absent for
    an episode that never ran and in files written before it existed),
    "index" (position in this list), "arrays_key" (prefix in episodes.npz, or null)}],
 "aggregate": [ one row per (env, policy, condition, dynamics, model_error, obs_noise):
   {"env", "policy", "condition", "dynamics", "model_error", "obs_noise", "n", "n_failed", "n_tipped_over", "success_rate",
    "success_rate_ci95": [low, high],           # Wilson 95%; failed episodes count as failures
    "clean_success_rate", "clean_success_rate_ci95": [low, high],   # successes without a joint-limit hit
    "success_curve": [rate at each of statistics.success_curve_tolerances_m],
    "success_curve_ci95": [[low, high] at each tolerance],            # Wilson 95%, point by point
    "max_error_m" | "rms_error_m" | "final_error_m" | "steady_max_error_m" | "steady_rms_error_m" | "effort" |
    "peak_joint_speed" | "peak_wheel_speed" | "cmd_accel_rms" | "cmd_jerk_rms" | "limit_margin_min" |
    "converge_time_s" | "predict_us_median" | "predict_us_p99":
        {"median", "mean", "std", "min", "max", "p90"},  # over status-ok episodes
    # max_error_m, steady_max_error_m, steady_rms_error_m also: "iqm", "iqm_ci95": [low, high], "worst" (= max)
   }]}
```
The statistics are defined in `eval.metrics` (IQM = scipy's trim_mean(x, 0.25), rliable's definition; 95%
percentile bootstrap with a fixed seed; Wilson intervals).

**Schema 1** (mobman 0.1) lacks `provenance`, `statistics`, the steady-state errors, the IQMs and intervals;
**schema 2** (mobman 0.2) lacks `robot`, the smoothness, limit-margin and convergence fields, `clean_success`,
the tails (`p90`, `worst`) and the success curve's band; **schema 3** (mobman 0.3) lacks `condition`,
`feasible` and `feasibility_peak`. `load_results` reads all four and fills what an older schema lacks with None,
except `condition`, which it names from the record's env arguments (`upgrade_results`; `"schema"` keeps the
file's number), so code that reads results handles one shape.
Comparisons across workers or machines skip `wall_s`, `pid` and `predict_us_*`.
"""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from eval import metrics as M
from eval.errors import EvalError
from eval.output.files import (
    atomic_save_figure,
    atomic_savez,
    atomic_write_json,
    atomic_write_text,
    json_text,
    slug,
    to_jsonable,
)
from eval.output.provenance import git_rev, provenance, versions
from eval.output.tables import print_table, summary_markdown

SCHEMA = 4

#: The schema numbers `load_results` reads.
READABLE_SCHEMAS = (1, 2, 3, 4)
#: per-episode fields schema 4 added: `condition` (filled on loading an older file with the name its env
#: arguments make, `eval.conditions.condition_name`), `feasible` and `feasibility_peak` (None in older files)
_SCHEMA4_EPISODE = ("feasible", "feasibility_peak")
#: per-episode fields schema 3 added (None in older files)
_SCHEMA3_EPISODE = (
    "robot",
    "knowledge",
    "artefacts",
    "cmd_accel_rms",
    "cmd_jerk_rms",
    "limit_margin_min",
    "converge_time_s",
    "clean_success",
)


def statistics_block(settle_time: float | None = M.DEFAULT_SETTLE_TIME) -> dict:
    """How the aggregate statistics were made (results.json "statistics"): definitions, bootstrap settings,
    the success-curve tolerances and the settle time."""
    return {
        "iqm": "interquartile mean: scipy.stats.trim_mean(x, 0.25) (rliable's IQM)",
        "ci": "95% stratified percentile bootstrap of the IQM",
        "bootstrap_resamples": M.BOOTSTRAP_RESAMPLES,
        "bootstrap_seed": M.BOOTSTRAP_SEED,
        "success_interval": "Wilson score interval, 95%",
        "success_curve_tolerances_m": list(M.SUCCESS_CURVE_TOLERANCES),
        "settle_time_s": settle_time,
    }


def build_results(config: dict, records: list[dict], aggregate: list[dict], wall_s: float | None = None) -> dict:
    """The results.json dict (schema 4) of `records` and their `aggregate`; the settle time is the config's."""
    return to_jsonable(
        {
            "schema": SCHEMA,
            "config": config,
            "versions": versions(),
            "git": git_rev(),
            "provenance": provenance(),
            "statistics": statistics_block(config.get("settle_time", M.DEFAULT_SETTLE_TIME)),
            "wall_s": wall_s,
            "episodes": records,
            "aggregate": aggregate,
        }
    )


def upgrade_results(data: dict, source: str = "results") -> dict:
    """A results dict of any readable schema in schema 4's shape: what an older schema lacks is None (episodes:
    steady-state errors, schema 3's and 4's fields; aggregate rows: intervals, success curve and its band, IQMs,
    tails; top level: provenance, statistics), except each episode's and aggregate row's `condition`, which is
    the name its env arguments make (`eval.conditions.condition_name` of the record's dynamics, model error, noise
    and the file's `env_kwargs`: the same name a schema-4 run of those arguments records). `"schema"` keeps the
    number the data had. EvalError for anything else."""
    if not isinstance(data, dict) or "schema" not in data:
        raise EvalError(f"{source} is not a mobman results file (no 'schema' key)")
    schema = data["schema"]
    if schema not in READABLE_SCHEMAS:
        raise EvalError(
            f"{source} has results schema {schema!r}; this mobman reads schemas "
            f"{', '.join(map(str, READABLE_SCHEMAS))} (a newer mobman wrote it: upgrade mobman)"
        )
    if schema == SCHEMA:
        return data
    out = dict(data)
    out.setdefault("provenance", None)
    out.setdefault("statistics", None)
    old = ("steady_max_error_m", "steady_rms_error_m", *_SCHEMA3_EPISODE, *_SCHEMA4_EPISODE)
    extra = dict((data.get("config") or {}).get("env_kwargs") or {})
    out["episodes"] = [
        {**r, **{k: r.get(k) for k in old}, "condition": r.get("condition") or _condition_of(r, extra)}
        for r in data.get("episodes", [])
    ]
    rows = []
    for a in data.get("aggregate", []):
        row = dict(a)
        row.setdefault("condition", _condition_of(a, extra))
        for key in ("success_rate_ci95", "success_curve", "success_curve_ci95", "clean_success_rate"):
            row.setdefault(key, None)
        row.setdefault("clean_success_rate_ci95", None)
        for name in M.SUMMARY_METRICS:
            stats = dict(row.get(name) or dict.fromkeys(("median", "mean", "std", "min", "max")))
            stats.setdefault("p90", None)
            if name in M.IQM_METRICS:
                stats.setdefault("iqm", None)
                stats.setdefault("iqm_ci95", None)
                stats.setdefault("worst", stats.get("max"))
            row[name] = stats
        rows.append(row)
    out["aggregate"] = rows
    return out


def _condition_of(rec: dict, env_kwargs: dict) -> str | None:
    """The condition name of an older file's record or aggregate row (see `upgrade_results`)."""
    from eval.conditions import condition_name

    if rec.get("dynamics") is None:
        return None
    axes = {k: rec.get(k) for k in ("dynamics", "model_error", "obs_noise")}
    return condition_name({**env_kwargs, **axes})


def load_results(path: str | Path) -> dict:
    """Read a results.json of schema 1, 2, 3 or 4 (`upgrade_results` gives them one shape) as a dict, through the
    one JSON reader (`eval.schemas`: a regular file of at most `MAX_RESULTS_BYTES`, UTF-8, bounded nesting) and
    its shape checked (`eval.schemas.RESULTS`) before anything uses it; `eval.load_results` wraps it for analysis
    (pandas DataFrames). EvalError naming the file, the field and the fix otherwise."""
    from eval.schemas import MAX_RESULTS_BYTES, RESULTS, check_shape, read_eval_json

    path = Path(path)
    try:
        data = read_eval_json(path, MAX_RESULTS_BYTES, "results file")
    except FileNotFoundError:
        raise EvalError(f"results file {str(path)!r} not found") from None
    if isinstance(data, dict) and data.get("schema") in READABLE_SCHEMAS:  # else upgrade_results names the schema
        check_shape(data, RESULTS, str(path))
    return upgrade_results(data, str(path))


def arrays_key(index: int) -> str:
    return f"ep{index:05d}"


#: The largest episodes.npz `load_arrays` reads, packed and inflated (the paper's 14 first episodes: 2.9 MB).
MAX_ARRAYS_BYTES = 1024 * 2**20


def load_arrays(path: str | Path) -> dict[str, dict[str, np.ndarray]]:
    """The per-step arrays of an episodes.npz (`write_run`'s "KEY__NAME" entries) as {arrays_key: {name: array}}:
    a regular file of at most `MAX_ARRAYS_BYTES` whose entries inflate to at most that, arrays only (no pickle is
    loaded); EvalError naming the file and the entry otherwise."""
    import zipfile

    from policies.agents.untrusted import FileRefused, check_zip_sizes, read_regular

    path = Path(path)
    out: dict[str, dict[str, np.ndarray]] = {}
    try:
        data = io.BytesIO(read_regular(path, MAX_ARRAYS_BYTES, "arrays file"))
        with zipfile.ZipFile(data) as zf:
            check_zip_sizes(zf, path, {}, MAX_ARRAYS_BYTES)
        with np.load(data, allow_pickle=False) as npz:
            for name in npz.files:
                key, sep, field = name.partition("__")
                if not sep or not key or not field:
                    raise ValueError(
                        f"{path}: entry {name!r} is not KEY__NAME, as every entry of mobman's episodes.npz"
                    )
                out.setdefault(key, {})[field] = npz[name]
    except (FileRefused, OSError, ValueError, zipfile.BadZipFile) as exc:
        raise EvalError(f"cannot read the arrays file: {exc}") from None
    return out


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
    "steady_max_error_m",
    "steady_rms_error_m",
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


class ResultsView:
    """`episodes` and `aggregate` of the results.json dict held in `self.results` (run and sweep results)."""

    results: dict

    @property
    def episodes(self) -> list[dict]:
        return self.results["episodes"]

    @property
    def aggregate(self) -> list[dict]:
        return self.results["aggregate"]


#: What `mobman-eval run` writes into its folder (globs relative to it): an --overwrite run removes the files of
#: an earlier run that match these and that it did not write itself (`eval.output.files.remove_stale`).
RUN_OUTPUTS = (
    "config.json",
    "episodes.jsonl",
    "results.json",
    "results.json.xz",  # an earlier results.json compacted (`mobman-eval compact`): stale beside a new one
    "results.csv",
    "summary.md",
    "episodes.npz",
    "plots/*_paths3d.png",
    "plots/*_axis_errors.png",
    "plots/*_error_norm.png",
    "videos/*.mp4",
    "videos/*.gif",
)


def write_run(result, config) -> list[Path]:
    """Write every file of a run directory (see the module docstring); returns the paths written."""
    out = Path(result.out)
    out.mkdir(parents=True, exist_ok=True)
    results = result.results
    written = [out / "config.json", out / "results.json", out / "results.csv", out / "summary.md"]
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
        written.append(out / "episodes.npz")
    if config.plots:
        written += write_plots(result, out / "plots", config.tolerance)
    return written


def traces_for_plots(result) -> dict[tuple[str, str], list[dict]]:
    """(env, dynamics) -> the records of episode 0 of each policy with their arrays merged in."""
    groups: dict[tuple[str, str], list[dict]] = {}
    for rec in result.results["episodes"]:
        if rec.get("episode") == 0 and rec["index"] in result.arrays:
            groups.setdefault((rec["env"], rec["dynamics"]), []).append({**rec, **result.arrays[rec["index"]]})
    return groups


def write_plots(result, plot_dir: Path, tolerance: float) -> list[Path]:
    import matplotlib.pyplot as plt

    from eval.output import plots

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


def print_results(results: dict, out: Path, fmt: str = "table") -> None:
    """Print the results on stdout in `fmt`: "table" (the console table), or the content of summary.md
    ("markdown"), results.json ("json") or results.csv ("csv"); where the files are goes to stderr, so stdout
    stays parseable."""
    import sys

    if fmt == "table":
        print_table(results)
    else:
        text = {"markdown": summary_markdown, "json": json_text, "csv": lambda r: csv_text(r["episodes"])}[fmt](results)
        sys.stdout.write(text if text.endswith("\n") else text + "\n")
        sys.stdout.flush()
    print(f"results in {out}", file=sys.stderr)

"""Metrics: pure functions over the arrays one rollout records, and aggregates over episode records.

Conventions (SI units throughout; the Markdown and console reports convert to mm):

* `r_d`, `r_a`: desired and true (noise-free) end-effector positions, shape (n + 1, 3), m, sampled at
  t_0 = 0, t_1 = dt, ..., t_n (the state after each of the n control steps, plus the start).
* `actions`: the normalised actions the env applied, shape (n, 8), in [-1, 1]; action k is held over
  [t_k, t_k+1].
* The tracking error is e_k = ||r_d(t_k) - r_a(t_k)||. Max, RMS (over all n + 1 samples) and final error are
  taken from it; the per-axis max error is max_k |r_d - r_a| for x, y and z separately.
* Effort = integral over time of ||a||^2 (a: the normalised action), i.e. sum_k ||a_k||^2 dt, in s.
* Peak speeds are the largest commanded actuator speeds |a_i| * action_scale_i (rad/s), arm joints and wheels
  separately (the command the env applied, after its own clipping).
* Success: the episode ran to its end (`status == "ok"`, not tipped over) and its max error is <= the tolerance
  (default 6 mm, the paper's figure). A failed episode is never a success.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

#: The paper's bound on NNBC's max tracking error (section IV), m.
DEFAULT_TOLERANCE = 0.006

#: Episode fields that identify an experimental condition; `aggregate` groups by them.
GROUP_KEYS = ("env", "policy", "dynamics", "model_error", "obs_noise")

#: Scalar episode metrics that `aggregate` summarises with median / mean / std (over successful rollouts,
#: i.e. status "ok"; failed episodes only count in `n_failed` and lower the success rate).
SUMMARY_METRICS = (
    "max_error_m",
    "rms_error_m",
    "final_error_m",
    "effort",
    "peak_joint_speed",
    "peak_wheel_speed",
    "predict_us_median",
    "predict_us_p99",
)


def error_norm(r_d: np.ndarray, r_a: np.ndarray) -> np.ndarray:
    """||r_d - r_a|| per sample, (n,) m."""
    return np.linalg.norm(np.asarray(r_d, float) - np.asarray(r_a, float), axis=-1)


def max_error(err: np.ndarray) -> float:
    err = np.asarray(err, float)
    return float(np.max(err)) if err.size else math.nan


def rms_error(err: np.ndarray) -> float:
    err = np.asarray(err, float)
    return float(np.sqrt(np.mean(err * err))) if err.size else math.nan


def final_error(err: np.ndarray) -> float:
    err = np.asarray(err, float)
    return float(err[-1]) if err.size else math.nan


def axis_max_error(r_d: np.ndarray, r_a: np.ndarray) -> list[float]:
    """max_k |r_d - r_a| for each axis (x, y, z), m."""
    diff = np.abs(np.asarray(r_d, float) - np.asarray(r_a, float))
    if diff.size == 0:
        return [math.nan] * 3
    return [float(v) for v in diff.max(axis=0)]


def effort(actions: np.ndarray, dt: float) -> float:
    """Integral of the squared normalised action over time: sum_k ||a_k||^2 dt (s)."""
    a = np.asarray(actions, float)
    if a.size == 0:
        return 0.0
    return float(np.sum(a * a) * dt)


def peak_speeds(actions: np.ndarray, action_scale: Sequence[float], n_arm: int = 6) -> tuple[float, float]:
    """(peak arm joint speed, peak wheel speed), rad/s: max |a_i| * scale_i over time, per actuator group."""
    a = np.asarray(actions, float)
    scale = np.asarray(action_scale, float)
    if a.size == 0:
        return 0.0, 0.0
    speeds = np.abs(a) * scale
    return float(speeds[:, :n_arm].max()), float(speeds[:, n_arm:].max())


def timing_stats(us: np.ndarray) -> tuple[float, float]:
    """(median, 99th percentile) of per-call times in microseconds."""
    us = np.asarray(us, float)
    if us.size == 0:
        return math.nan, math.nan
    return float(np.median(us)), float(np.percentile(us, 99))


def is_success(
    max_err: float | None, tolerance: float = DEFAULT_TOLERANCE, *, status: str = "ok", tipped_over: bool = False
) -> bool:
    """Max error within tolerance, the episode ran to its end and did not tip over. Failed -> False."""
    if status != "ok" or tipped_over or max_err is None or not math.isfinite(max_err):
        return False
    return bool(max_err <= tolerance)


def episode_metrics(
    r_d: np.ndarray,
    r_a: np.ndarray,
    actions: np.ndarray,
    dt: float,
    action_scale: Sequence[float],
    tolerance: float = DEFAULT_TOLERANCE,
    tipped_over: bool = False,
    err: np.ndarray | None = None,
) -> dict[str, Any]:
    """All per-episode tracking metrics of one completed rollout, as a dict of plain floats.

    `err` is the error norm per sample if it was recorded (the env's exact `info["tracking_error"]`);
    otherwise it is computed from `r_d` and `r_a`."""
    err = error_norm(r_d, r_a) if err is None else np.asarray(err, float)
    joint_peak, wheel_peak = peak_speeds(actions, action_scale)
    m = max_error(err)
    return {
        "max_error_m": m,
        "rms_error_m": rms_error(err),
        "final_error_m": final_error(err),
        "axis_max_error_m": axis_max_error(r_d, r_a),
        "effort": effort(actions, dt),
        "peak_joint_speed": joint_peak,
        "peak_wheel_speed": wheel_peak,
        "success": is_success(m, tolerance, tipped_over=tipped_over),
    }


def describe(values: Iterable[float | None]) -> dict[str, float | None]:
    """median / mean / std (population) / min / max of the finite values; None when there are none."""
    v = np.array([x for x in values if x is not None and math.isfinite(x)], float)
    if v.size == 0:
        return {"median": None, "mean": None, "std": None, "min": None, "max": None}
    return {
        "median": float(np.median(v)),
        "mean": float(np.mean(v)),
        "std": float(np.std(v)),
        "min": float(np.min(v)),
        "max": float(np.max(v)),
    }


def aggregate(
    records: Sequence[dict], group_keys: Sequence[str] = GROUP_KEYS, metrics: Sequence[str] = SUMMARY_METRICS
) -> list[dict]:
    """One row per condition (the distinct values of `group_keys`, in first-seen order): n, n_failed,
    success_rate (successes / n, failed episodes counting as failures) and `describe()` of each metric over the
    episodes with status "ok"."""
    groups: dict[tuple, list[dict]] = {}
    for rec in records:
        groups.setdefault(tuple(rec.get(k) for k in group_keys), []).append(rec)
    rows = []
    for key, recs in groups.items():
        ok = [r for r in recs if r.get("status") == "ok"]
        row: dict[str, Any] = dict(zip(group_keys, key))
        row["n"] = len(recs)
        row["n_failed"] = len(recs) - len(ok)
        row["n_tipped_over"] = sum(bool(r.get("tipped_over")) for r in ok)
        row["success_rate"] = sum(bool(r.get("success")) for r in recs) / len(recs)
        for name in metrics:
            row[name] = describe(r.get(name) for r in ok)
        rows.append(row)
    return rows

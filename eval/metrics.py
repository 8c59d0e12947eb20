"""Metrics: pure functions over the arrays one rollout records, and aggregates over episode records.

Conventions (SI units throughout; the Markdown and console reports convert to mm):

* `r_d`, `r_a`: desired and true (noise-free) end-effector positions, shape (n + 1, 3), m, sampled at
  t_0 = 0, t_1 = dt, ..., t_n (the state after each of the n control steps, plus the start).
* `actions`: the normalised actions the env applied, shape (n, n_act) (n_act = arm joints + 2 wheels), in [-1, 1]; action k is held over
  [t_k, t_k+1].
* The tracking error is e_k = ||r_d(t_k) - r_a(t_k)||. Max, RMS (over all n + 1 samples) and final error are
  taken from it; the per-axis max error is max_k |r_d - r_a| for x, y and z separately.
* Effort = integral over time of ||a||^2 (a: the normalised action), i.e. sum_k ||a_k||^2 dt, in s.
* Peak speeds are the largest commanded actuator speeds |a_i| * action_scale_i (rad/s), arm joints and wheels
  separately (the command the env applied, after its own clipping).
* Jacobian-estimate quality (controllers exposing `jacobian_estimate`): per step the relative error
  ||J_hat - J||_F / ||J||_F and the largest principal angle between the row spaces of J_hat and J (rad), J the
  true robot's Jacobian of the same kind at the same state, computed by eval; per episode their median and max.
* Success: the episode ran to its end (`status == "ok"`, not tipped over) and its max error is <= the tolerance
  (default 6 mm, the paper's figure). A failed episode is never a success.
* Steady-state errors (`steady_max_error_m`, `steady_rms_error_m`): max and RMS of e_k over the samples with
  t_k >= the settle time (default `DEFAULT_SETTLE_TIME` = 0.5 s), so a start-up transient (NNBC's probe, a
  controller converging from its initial estimate) is visible beside the whole-episode figures and separable
  from them. None when the episode ended before the settle time.
* Command smoothness (schema 3), what a real actuator is asked to do: with u_k = a_k * action_scale the commanded
  speeds (rad/s) and u_{-1} = 0 (the robot starts at rest), `cmd_accel_rms` = sqrt(mean_k ||u_k - u_{k-1}||^2) / dt
  (rad/s^2) and `cmd_jerk_rms` the same of the second difference / dt^2 (rad/s^3), the norm over all actuators.
  A dither or a chattering law shows here while its `effort` (the squared action's integral) stays small.
* `limit_margin_min` (rad): the smallest distance of any arm joint to its limit over the episode (the joint
  angles as observed: noise-free, delayed under `obs_delay`); `clean_success`: a success without a single
  joint-limit hit (a controller that "tracks" by riding a stop is not clean).
* `converge_time_s`: the first time after which the error stays within the tolerance to the end (0 when it
  never leaves it); None when the episode ends outside it.

Statistics over episodes (results.json schemas 2 and 3; all pure functions with fixed seeds):

* IQM, the interquartile mean: `scipy.stats.trim_mean(x, 0.25)`, i.e. sort the n values, cut
  floor(0.25 n) from each end and average the rest (for n = 20: the middle 10 values; n = 5: the middle 3).
  This is rliable's `aggregate_iqm` (Agarwal et al., "Deep RL at the edge of the statistical precipice",
  NeurIPS 2021), which calls that same scipy function; it is not the fractionally weighted variant.
* Its 95% confidence interval: a stratified percentile bootstrap (`BOOTSTRAP_RESAMPLES` = 2000 resamples from
  `np.random.default_rng(BOOTSTRAP_SEED)`): each resample draws, within every stratum (a task or condition
  pooled into one figure; one stratum for a single condition), as many values with replacement as the
  stratum has, pools them and takes the IQM; the interval is the 2.5th and 97.5th percentile of the
  resampled IQMs (rliable's `StratifiedBootstrap`, percentile method). Same values, same interval.
* Success rate intervals: the Wilson score interval at 95% (z = 1.959964), which, unlike the normal
  approximation, stays inside [0, 1] and is not empty at 0/n or n/n.
* `success_curve`: the success rate at every tolerance of `SUCCESS_CURVE_TOLERANCES` (31 points, 10 per decade,
  0.1 mm to 100 mm; recorded in results.json), so controllers that all pass the 6 mm line are still ranked;
  `success_curve_ci95` (schema 3) its Wilson band, point by point.
* Tails (schema 3): every summary metric's `p90`, and for the metrics with an IQM the `worst` episode (= `max`);
  the IQM of 20 episodes ignores the worst 5, and a benchmark that saturates at the top shows its differences
  there. `clean_success_rate` with its interval beside `success_rate`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: The paper's bound on NNBC's max tracking error (section IV), m.
DEFAULT_TOLERANCE = 0.006

#: Settle time of the steady-state errors, s: samples with t >= this count (the default of the config field).
DEFAULT_SETTLE_TIME = 0.5

#: Tolerances of `success_curve`, m: 10 per decade from 0.1 mm to 100 mm (31 points, log-spaced).
SUCCESS_CURVE_TOLERANCES: tuple[float, ...] = tuple(float(v) for v in np.logspace(-4.0, -1.0, 31))

#: Resamples and generator seed of the bootstrap confidence intervals (fixed: same values, same interval).
BOOTSTRAP_RESAMPLES = 2000
BOOTSTRAP_SEED = 20211206  # the day rliable's paper was presented at NeurIPS 2021; any fixed value would do

#: z of a two-sided 95% normal interval, for the Wilson score interval.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Field:
    """One field of an episode record and what the aggregation does with it: `group` (it identifies an
    experimental condition: `aggregate` groups by it), `summary` (a scalar metric `aggregate` summarises with
    median / mean / std / min / max / p90 over the episodes that ran), `iqm` (a summary metric that also gets an
    IQM with its bootstrap CI)."""

    name: str
    group: bool = False
    summary: bool = False
    iqm: bool = False


def _fields(*names: str, **flags: bool) -> tuple[Field, ...]:
    return tuple(Field(n, **flags) for n in names)


#: Per-episode Jacobian-estimate fields of a record (`jacobian_quality`); None for a policy without an estimate.
JACOBIAN_KEYS = (
    "jacobian_kind",
    "jacobian_rel_error_median",
    "jacobian_rel_error_max",
    "jacobian_angle_median_rad",
    "jacobian_angle_max_rad",
)

#: Every field of an episode record, in order, with its flags: the one schema of a record (`eval.rollout` fills
#: it; eval/README.md, "results.json", says what each holds). Failed episodes only count in `n_failed` and lower
#: the success rate of `aggregate`.
RECORD_FIELDS: tuple[Field, ...] = (
    *_fields("env", "policy", "condition", group=True),
    *_fields("episode", "seed", "robot", "knowledge", "artefacts"),
    *_fields("dynamics", "model_error", "obs_noise", group=True),
    *_fields("control_freq", "path", "start", "true_params_hash", "feasible", "feasibility_peak", "status", "error"),
    Field("max_error_m", summary=True, iqm=True),
    *_fields("rms_error_m", "final_error_m", summary=True),
    *_fields("steady_max_error_m", "steady_rms_error_m", summary=True, iqm=True),
    Field("axis_max_error_m"),
    *_fields("effort", "peak_joint_speed", "peak_wheel_speed", "cmd_accel_rms", "cmd_jerk_rms", summary=True),
    *_fields("limit_margin_min", "converge_time_s", summary=True),
    *_fields("success", "clean_success", "n_steps", "joint_limit_hits", "n_clipped", "tipped_over", "terminated"),
    *_fields("predict_us_median", "predict_us_p99", summary=True),
    *_fields(*JACOBIAN_KEYS),
    *_fields("wall_s", "pid"),
)
RECORD_KEYS = tuple(f.name for f in RECORD_FIELDS)

#: Episode fields that identify an experimental condition; `aggregate` groups by them.
GROUP_KEYS = tuple(f.name for f in RECORD_FIELDS if f.group)

#: Scalar episode metrics that `aggregate` summarises (see `Field`).
SUMMARY_METRICS = tuple(f.name for f in RECORD_FIELDS if f.summary)

#: Summary metrics that `aggregate` also gives an IQM with its bootstrap CI (`iqm`, `iqm_ci95`).
IQM_METRICS = tuple(f.name for f in RECORD_FIELDS if f.iqm)


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


def steady_errors(err: np.ndarray, dt: float, settle_time: float = DEFAULT_SETTLE_TIME) -> tuple[float, float]:
    """(max, RMS) of the error samples e_k with t_k = k dt >= `settle_time` (m); NaN if there are none.

    A sample counts when k dt >= settle_time - 1e-9 s, so a settle time that is a whole number of control
    steps includes its own sample despite rounding (0.5 s at 100 Hz: samples 50, 51, ...)."""
    err = np.asarray(err, float)
    first = max(0, math.ceil(settle_time / dt - 1e-9 / dt)) if dt > 0 else 0
    tail = err[first:]
    return max_error(tail), rms_error(tail)


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


def peak_speeds(
    actions: np.ndarray, action_scale: Sequence[float] | np.ndarray, n_arm: int | None = None
) -> tuple[float, float]:
    """(peak arm joint speed, peak wheel speed), rad/s: max |a_i| * scale_i over time, per actuator group.
    `n_arm`: the arm joints (the last two actuators are the wheels); None: len(action_scale) - 2."""
    a = np.asarray(actions, float)
    scale = np.asarray(action_scale, float)
    if n_arm is None:
        n_arm = len(scale) - 2
    if a.size == 0:
        return 0.0, 0.0
    speeds = np.abs(a) * scale
    return float(speeds[:, :n_arm].max()), float(speeds[:, n_arm:].max())


def command_smoothness(
    actions: np.ndarray, dt: float, action_scale: Sequence[float] | np.ndarray
) -> tuple[float, float]:
    """(`cmd_accel_rms` rad/s^2, `cmd_jerk_rms` rad/s^3) of the commanded speeds u_k = a_k * action_scale, from
    rest (u_{-1} = u_{-2} = 0): RMS over the steps of the norm over the actuators of the first and second
    differences, divided by dt and dt^2."""
    a = np.asarray(actions, float)
    if a.size == 0 or dt <= 0:
        return 0.0, 0.0
    u = np.vstack([np.zeros((2, a.shape[1])), a * np.asarray(action_scale, float)])
    d1 = np.diff(u, axis=0)  # u_k - u_{k-1}, from u_{-1}
    d2 = np.diff(d1, axis=0)  # the second difference, from u_{-1} - u_{-2} = 0
    accel = math.sqrt(float(np.mean(np.sum(d1[1:] * d1[1:], axis=1)))) / dt
    jerk = math.sqrt(float(np.mean(np.sum(d2 * d2, axis=1)))) / (dt * dt)
    return accel, jerk


def limit_margin(q: np.ndarray, lower: Sequence[float], upper: Sequence[float]) -> float:
    """The smallest distance of any joint to its limit over the samples q (n, joints), rad (negative beyond)."""
    q = np.asarray(q, float)
    if q.size == 0:
        return math.nan
    return float(np.minimum(q - np.asarray(lower, float), np.asarray(upper, float) - q).min())


def converge_time(err: np.ndarray, dt: float, tolerance: float = DEFAULT_TOLERANCE) -> float | None:
    """The first t_k = k dt from which every later error sample is within `tolerance` (s); None when the last
    sample is outside it."""
    err = np.asarray(err, float)
    if err.size == 0 or not err[-1] <= tolerance:
        return None
    later_max = np.maximum.accumulate(err[::-1])[::-1]  # max of e_k .. e_n
    return float(np.argmax(later_max <= tolerance) * dt)


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
    action_scale: Sequence[float] | np.ndarray,
    tolerance: float = DEFAULT_TOLERANCE,
    tipped_over: bool = False,
    err: np.ndarray | None = None,
    settle_time: float = DEFAULT_SETTLE_TIME,
    q: np.ndarray | None = None,
    limits: tuple[Sequence[float], Sequence[float]] | None = None,
    limit_hits: int = 0,
) -> dict[str, Any]:
    """All per-episode tracking metrics of one completed rollout, as a dict of plain floats.

    `err` is the error norm per sample if it was recorded (the env's exact `info["tracking_error"]`);
    otherwise it is computed from `r_d` and `r_a`. The steady-state errors use the samples at t >= `settle_time`
    (s; sample k is at t = k dt). `q` (samples, arm joints) and `limits` (lower, upper) give `limit_margin_min`
    (None without them); `limit_hits` (the env's count) decides `clean_success`."""
    err = error_norm(r_d, r_a) if err is None else np.asarray(err, float)
    joint_peak, wheel_peak = peak_speeds(actions, action_scale)
    m = max_error(err)
    steady_max, steady_rms = steady_errors(err, dt, settle_time)
    accel, jerk = command_smoothness(actions, dt, action_scale)
    success = is_success(m, tolerance, tipped_over=tipped_over)
    return {
        "max_error_m": m,
        "rms_error_m": rms_error(err),
        "final_error_m": final_error(err),
        "steady_max_error_m": steady_max,
        "steady_rms_error_m": steady_rms,
        "axis_max_error_m": axis_max_error(r_d, r_a),
        "effort": effort(actions, dt),
        "peak_joint_speed": joint_peak,
        "peak_wheel_speed": wheel_peak,
        "cmd_accel_rms": accel,
        "cmd_jerk_rms": jerk,
        "limit_margin_min": None if q is None or limits is None else limit_margin(q, *limits),
        "converge_time_s": converge_time(err, dt, tolerance),
        "success": success,
        "clean_success": success and limit_hits == 0,
    }


def _finite(values: Iterable[float | None]) -> np.ndarray:
    return np.array([x for x in values if x is not None and math.isfinite(x)], float)


def iqm(values: Iterable[float | None]) -> float | None:
    """Interquartile mean of the finite values: `scipy.stats.trim_mean(x, 0.25)` (rliable's IQM; see the module
    docstring); None when there are none."""
    v = np.sort(_finite(values))
    if v.size == 0:
        return None
    cut = int(0.25 * v.size)
    return float(np.mean(v[cut : v.size - cut]))


def _iqm_rows(samples: np.ndarray) -> np.ndarray:
    """IQM of every row of a (B, n) array (the same trimming as `iqm`)."""
    n = samples.shape[1]
    cut = int(0.25 * n)
    return np.sort(samples, axis=1)[:, cut : n - cut].mean(axis=1)


def iqm_ci95(
    strata: Sequence[Iterable[float | None]],
    *,
    resamples: int = BOOTSTRAP_RESAMPLES,
    seed: int = BOOTSTRAP_SEED,
) -> list[float] | None:
    """95% stratified percentile-bootstrap interval [low, high] of the IQM of the pooled strata.

    `strata` is a list of value lists (one per task or condition pooled; a single list for one condition).
    Each of `resamples` resamples draws len(s) values with replacement within every stratum s (non-finite
    values dropped first), pools them and takes their IQM; the interval is the 2.5th and 97.5th percentile
    of those IQMs. A fixed `seed` makes it a pure function. None when no stratum has a value."""
    groups = [g for g in (_finite(s) for s in strata) if g.size]
    if not groups:
        return None
    rng = np.random.default_rng(seed)
    parts = [g[rng.integers(0, g.size, size=(resamples, g.size))] for g in groups]
    stats = _iqm_rows(np.concatenate(parts, axis=1))
    low, high = np.percentile(stats, [2.5, 97.5])
    return [float(low), float(high)]


def wilson_interval(successes: int, n: int, z: float = Z95) -> list[float] | None:
    """Wilson score interval [low, high] of a success rate (95% for the default z); None when n == 0."""
    if n <= 0:
        return None
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    # exact at the ends: 0/n has low 0 and n/n has high 1 (the formula gives them up to rounding)
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return [low, high]


#: Protocol v3's success thresholds, m: 1, 2 and 6 mm (the paper's figure), reported over feasible episodes.
V3_TOLERANCES: tuple[float, ...] = (0.001, 0.002, 0.006)


def feasible_success(records: Sequence[dict], tolerances: Sequence[float] = V3_TOLERANCES) -> dict[str, Any]:
    """Protocol v3's success block of `records`: over the episodes whose path the true robot can follow
    (`feasible` true, `mobman_env.feasibility`), the success rate at each of `tolerances` with its Wilson 95%
    interval; the infeasible episodes and those of unknown feasibility (older records, another package's env)
    are counted, never scored. Rates are None when no episode is feasible."""
    feasible = [r for r in records if r.get("feasible") is True]
    n = len(feasible)
    rates = success_curve(feasible, tolerances) if n else [None] * len(tolerances)
    return {
        "tolerances_m": [float(t) for t in tolerances],
        "n_feasible": n,
        "n_infeasible": sum(r.get("feasible") is False for r in records),
        "n_unknown": sum(r.get("feasible") is None for r in records),
        "success": rates,
        "success_ci95": [None if rate is None else wilson_interval(round(rate * n), n) for rate in rates],
    }


def success_curve(records: Sequence[dict], tolerances: Sequence[float] = SUCCESS_CURVE_TOLERANCES) -> list[float]:
    """Success rate of `records` at every tolerance (m), by `is_success`'s rule on each record's max error,
    status and tipping; failed episodes count as failures. [] when there are no records."""
    if not records:
        return []
    errs = np.array(
        [
            r["max_error_m"]
            if r.get("status") == "ok"
            and not r.get("tipped_over")
            and r.get("max_error_m") is not None
            and math.isfinite(r["max_error_m"])
            else math.inf
            for r in records
        ],
        float,
    )
    tol = np.asarray(tolerances, float)
    return [float(v) for v in (errs[None, :] <= tol[:, None]).mean(axis=1)]


def describe(values: Iterable[float | None]) -> dict[str, float | None]:
    """median / mean / std (population) / min / max / p90 (the 90th percentile, numpy's linear interpolation) of
    the finite values; None when there are none."""
    v = _finite(values)
    if v.size == 0:
        return {"median": None, "mean": None, "std": None, "min": None, "max": None, "p90": None}
    return {
        "median": float(np.median(v)),
        "mean": float(np.mean(v)),
        "std": float(np.std(v)),
        "min": float(np.min(v)),
        "max": float(np.max(v)),
        "p90": float(np.percentile(v, 90)),
    }


def aggregate(
    records: Sequence[dict],
    group_keys: Sequence[str] = GROUP_KEYS,
    metrics: Sequence[str] = SUMMARY_METRICS,
    *,
    strata_key: str | None = None,
) -> list[dict]:
    """One row per condition (the distinct values of `group_keys`, in first-seen order): n, n_failed,
    success_rate (successes / n, failed episodes counting as failures) with its Wilson 95% interval
    `success_rate_ci95`, `success_curve` (at `SUCCESS_CURVE_TOLERANCES`), and `describe()` of each metric over
    the episodes with status "ok"; the metrics of `IQM_METRICS` also get `iqm` and `iqm_ci95`.

    `strata_key` (e.g. "env" when rows pool several tasks) names the record field whose values are the strata
    of the bootstrap; None: one stratum per row."""
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
        n_success = sum(bool(r.get("success")) for r in recs)
        row["success_rate"] = n_success / len(recs)
        row["success_rate_ci95"] = wilson_interval(n_success, len(recs))
        n_clean = sum(bool(r.get("clean_success")) for r in recs)
        row["clean_success_rate"] = n_clean / len(recs)
        row["clean_success_rate_ci95"] = wilson_interval(n_clean, len(recs))
        row["success_curve"] = curve = success_curve(recs)
        row["success_curve_ci95"] = [wilson_interval(round(p * len(recs)), len(recs)) for p in curve]
        for name in metrics:
            row[name] = describe(r.get(name) for r in ok)
            if name in IQM_METRICS:
                strata: dict[Any, list] = {}
                for r in ok:
                    strata.setdefault(r.get(strata_key) if strata_key else None, []).append(r.get(name))
                row[name]["iqm"] = iqm(r.get(name) for r in ok)
                row[name]["iqm_ci95"] = iqm_ci95(list(strata.values()))
                row[name]["worst"] = row[name]["max"]  # the tail the IQM hides (failed episodes: n_failed)
        rows.append(row)
    return rows


# --- Jacobian-estimate quality -------------------------------------------------------------------------------
#: A matrix's row space has the dimension of its singular values above this fraction of the largest one.
RANK_RTOL = 1e-10


def jacobian_relative_error(J_hat: np.ndarray, J: np.ndarray) -> np.ndarray:
    """||J_hat - J||_F / ||J||_F over the last two axes (J_hat, J: (..., m, n)); returns shape (...,).

    Dimensionless; inf where J = 0 and J_hat != 0, nan where both are 0."""
    J_hat, J = np.asarray(J_hat, float), np.asarray(J, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.linalg.norm(J_hat - J, axis=(-2, -1)) / np.linalg.norm(J, axis=(-2, -1))


def row_space_angle(J_hat: np.ndarray, J: np.ndarray) -> np.ndarray:
    """The largest principal angle between the row spaces of J_hat and J (rad, in [0, pi/2]), over the last two
    axes of (..., m, n) arrays; returns shape (...,).

    0 when J_hat's rows span exactly J's row space (whatever their scale), pi/2 when some direction of one is
    orthogonal to the other, and pi/2 whenever the two ranks differ (a rank-deficient estimate misses a whole
    direction). With orthonormal bases V1, V2 of the two row spaces (rows of the SVD's V^T), the angle is
    atan2(||(I - V1^T V1) V2^T||_2, sigma_min(V1 V2^T)): accurate for small angles too (arccos alone is not:
    it cannot resolve angles below about 1e-8 rad). Equals the largest angle of `scipy.linalg.subspace_angles`
    (J_hat.T, J.T) when the ranks are equal."""
    A, B = np.asarray(J_hat, float), np.asarray(J, float)
    if A.shape != B.shape or A.ndim < 2:
        raise ValueError(f"J_hat and J must be arrays of the same shape (..., m, n), got {A.shape} and {B.shape}")
    lead = A.shape[:-2]
    m, n = A.shape[-2:]
    A = A.reshape(-1, m, n)
    B = B.reshape(-1, m, n)
    out = np.full(A.shape[0], np.nan)
    _, sa, va = np.linalg.svd(A, full_matrices=False)
    _, sb, vb = np.linalg.svd(B, full_matrices=False)
    with np.errstate(invalid="ignore"):
        ra = np.sum(sa > RANK_RTOL * sa[:, :1], axis=1)
        rb = np.sum(sb > RANK_RTOL * sb[:, :1], axis=1)
    valid = (sa[:, 0] > 0) & (sb[:, 0] > 0) & np.isfinite(sa).all(axis=1) & np.isfinite(sb).all(axis=1)
    out[valid & (ra != rb)] = math.pi / 2
    for r in range(1, min(m, n) + 1):  # one batched computation per common rank
        idx = np.flatnonzero(valid & (ra == r) & (rb == r))
        if idx.size == 0:
            continue
        V1, V2 = va[idx, :r], vb[idx, :r]  # (k, r, n): orthonormal rows
        M = V1 @ V2.transpose(0, 2, 1)
        cos = np.linalg.svd(M, compute_uv=False)[:, -1]
        resid = V2.transpose(0, 2, 1) - V1.transpose(0, 2, 1) @ M  # (I - V1^T V1) V2^T, (k, n, r)
        sin = np.linalg.norm(resid, ord=2, axis=(-2, -1))
        out[idx] = np.arctan2(sin, cos)
    return out.reshape(lead)


def jacobian_quality(rel_error: np.ndarray, angle: np.ndarray) -> dict[str, float | None]:
    """Per-episode summary of the per-step Jacobian-estimate quality: median and max of the relative error and
    of the row-space angle (rad) over the steps that had an estimate (finite values); None if there were none.

    Keys: `jacobian_rel_error_median`, `jacobian_rel_error_max`, `jacobian_angle_median_rad`,
    `jacobian_angle_max_rad`."""
    out: dict[str, float | None] = {}
    for key, values in (("jacobian_rel_error", rel_error), ("jacobian_angle", angle)):
        v = np.asarray(values, float)
        v = v[np.isfinite(v)]
        unit = "_rad" if key == "jacobian_angle" else ""
        out[f"{key}_median{unit}"] = float(np.median(v)) if v.size else None
        out[f"{key}_max{unit}"] = float(np.max(v)) if v.size else None
    return out


# --- probability of improvement ------------------------------------------------------------------------------------
def probability_of_improvement(
    x: Sequence[Sequence[float]],
    y: Sequence[Sequence[float]],
    resamples: int = 1000,
    seed: int = BOOTSTRAP_SEED,
) -> tuple[float, list[float]] | None:
    """rliable's probability of improvement on a lower-is-better score: P(X < Y), with X, Y the max errors of two
    controllers, per task (stratum) the share of pairs (x_i, y_j) with x_i < y_j (ties count half), averaged over
    the tasks both have; and its 95% stratified percentile bootstrap interval (each resample redraws, within every
    task, each controller's episodes with replacement). `x[t]`, `y[t]`: the episodes of task t (a failed episode
    is +inf: worse than any). None when no task has episodes of both.

    (Agarwal et al., "Deep RL at the edge of the statistical precipice", NeurIPS 2021, the average probability of
    improvement; here on the max tracking error, so "improvement" is a smaller error.)"""
    pairs = [(np.asarray(a, float), np.asarray(b, float)) for a, b in zip(x, y) if len(a) and len(b)]
    if not pairs:
        return None

    def p_lt(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        # a (..., n), b (..., m) -> the share of pairs with a < b, ties half, over the last two axes
        lt = (a[..., :, None] < b[..., None, :]).mean(axis=(-1, -2))
        eq = (a[..., :, None] == b[..., None, :]).mean(axis=(-1, -2))
        return lt + 0.5 * eq

    point = float(np.mean([p_lt(a, b) for a, b in pairs]))
    rng = np.random.default_rng(seed)
    boot = np.zeros(resamples)
    for a, b in pairs:
        ia = rng.integers(0, len(a), (resamples, len(a)))
        ib = rng.integers(0, len(b), (resamples, len(b)))
        boot += p_lt(a[ia], b[ib])
    boot /= len(pairs)
    return point, [float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))]

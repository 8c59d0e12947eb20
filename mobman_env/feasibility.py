"""Is an episode's path within the true robot's actuator limits? The `feasible` flag of protocol v3's records.

Success partly measured path luck in protocol v2: nobody tracked the difficulty ladder's 2.5 s rung, and most of
the known-model ceiling's failures ran at the actuator limits. A controller cannot be blamed for a path that the
robot cannot follow, so every episode is checked against the true robot before it is scored.

**The check.** A reference law with everything known runs the episode in the ideal kinematic world (the true robot
of the episode, its wear drift included; no lag, no noise, no joint limits): the speeds of least scaled norm that
track the path, u = S w with w = A^T (A A^T + lambda^2 I)^-1 v, A = J_wb(q) S, S = diag(the speed limits),
v = r_d_dot + gain (r_d - r_a), integrated exactly as the engine integrates commands (arm angles by u dt, the
platform along the unicycle's arc). Its **peak speed ratio** is the largest |u_j| / limit_j over the episode's
control steps; the path is **feasible** when that peak is at most 1 - `margin` (default 10%: a controller needs some
authority beyond the path's own speed to correct an error).

What it says and what it does not: least-norm speeds within the limits along the whole path prove the path
followable (sufficient); a peak above the limits means this law needs more than the robot has, which for the
benchmark's paths (smooth, of bounded size) is where every known-model law saturates: the 2.5 s ladder rung peaks
at several times the limits, the 20 s tasks well below them. Joint position limits are left to the controllers
(the whole-body QPs respect them; they do not make a path infeasible). Computed once per episode by one compiled
kernel over the rows of an engine batch (a few milliseconds for a 2,000-step episode); the gain is the
benchmark's task-space gain (20 1/s) and lambda = 1e-3 m/s keeps the solve finite at a singularity (where the peak
then shows as infeasible).

Imports numpy, numba and `mobman_env.engine`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mobman_env import engine as E
from mobman_env.numba_cache import njit

#: The default margin: a path is feasible when its peak speed ratio is at most 1 - FEASIBILITY_MARGIN.
FEASIBILITY_MARGIN = 0.1
#: The reference law's task-space gain, 1/s (the benchmark's one gain).
REFERENCE_GAIN = 20.0
#: Damping of the reference law's solve, m/s.
REFERENCE_DAMPING = 1e-3


@dataclass(frozen=True)
class Feasibility:
    """The check of one episode (see the module docstring)."""

    peak_ratio: float
    """Largest |u_j| / limit_j of the reference law over the episode (1 = at the limit)."""
    peak_time: float
    """When that peak is reached, s."""
    peak_actuator: int
    """Which actuator (0..n-1 arm joints, n left wheel, n + 1 right wheel)."""
    margin: float
    """The margin the flag used."""
    reference_error: float
    """Largest tracking error of the reference law over the episode, m (tiny where the path is feasible: the law
    knows everything; it shows the check integrated the robot it judged)."""

    @property
    def feasible(self) -> bool:
        """The peak is within the limits with the margin."""
        return bool(self.peak_ratio <= 1.0 - self.margin)


@njit(cache=True, inline="always")
def _least_norm(jac, scale, m, v, damping, w):
    """w = A^T (A A^T + damping^2 I)^-1 v with A = jac diag(scale) (3 x m); returns max_j |w_j| and its j."""
    g00 = g01 = g02 = g11 = g12 = g22 = 0.0
    for j in range(m):
        a0, a1, a2 = jac[0, j] * scale[j], jac[1, j] * scale[j], jac[2, j] * scale[j]
        g00 += a0 * a0
        g01 += a0 * a1
        g02 += a0 * a2
        g11 += a1 * a1
        g12 += a1 * a2
        g22 += a2 * a2
    d2 = damping * damping
    g00 += d2
    g11 += d2
    g22 += d2
    # the symmetric 3 x 3 inverse by cofactors
    c00, c01, c02 = g11 * g22 - g12 * g12, g02 * g12 - g01 * g22, g01 * g12 - g02 * g11
    c11, c12, c22 = g00 * g22 - g02 * g02, g01 * g02 - g00 * g12, g00 * g11 - g01 * g01
    det = g00 * c00 + g01 * c01 + g02 * c02
    y0 = (c00 * v[0] + c01 * v[1] + c02 * v[2]) / det
    y1 = (c01 * v[0] + c11 * v[1] + c12 * v[2]) / det
    y2 = (c02 * v[0] + c12 * v[1] + c22 * v[2]) / det
    peak, which = 0.0, 0
    for j in range(m):
        w[j] = scale[j] * (jac[0, j] * y0 + jac[1, j] * y1 + jac[2, j] * y2)
        if abs(w[j]) > peak:
            peak, which = abs(w[j]), j
    return peak, which


@njit(cache=True)
def _peaks(arm, prm, rows, q0, pose0, dt, steps, gain, damping, out):
    """For each row r (a robot of `arm`, `prm` with its path): the reference law's peak speed ratio, the time
    and the actuator of the peak and the law's largest tracking error (m) into out[r] = (peak, time, actuator,
    error). q0 (k, m) and pose0 (k, 3): the start."""
    m = arm.shape[2]
    n = m - 2
    axes, f, ee, pc = np.empty((n, 6)), np.empty(3), np.empty(3), np.empty(2)
    jac, jpc, target = np.empty((3, m)), np.empty((2, 2)), np.empty((3, 3))
    v, w, scale, q = np.empty(3), np.empty(m), np.empty(m), np.empty(m)
    for r in range(rows.shape[0]):
        i = rows[r]
        for j in range(m):
            scale[j] = arm[i, E.ARM.action_scale, j]
            q[j] = q0[r, j]
        x, y, yaw = pose0[r, 0], pose0[r, 1], pose0[r, 2]
        peak, when, which, worst = 0.0, 0.0, 0, 0.0
        c = prm[i, E.PRM.path :]
        for k in range(int(steps[r])):
            t = k * dt
            fac = 1.0 + prm[i, E.PRM.wear_rate] * t
            E._whole_body(arm, prm, i, n, fac, q, x, y, yaw, ee, pc, jac, jpc, axes, f)
            E.path_eval(c, t, target)
            e2 = 0.0
            for a in range(3):
                e = target[0, a] - ee[a]
                e2 += e * e
                v[a] = target[1, a] + gain * e
            worst = max(worst, math.sqrt(e2))
            ratio, j_max = _least_norm(jac, scale, m, v, damping, w)
            if ratio > peak:
                peak, when, which = ratio, t, j_max
            for j in range(n):
                q[j] += scale[j] * w[j] * dt
            r_w, b_w = prm[i, E.PRM.wheel_radius] * fac, prm[i, E.PRM.half_track] * fac
            dl, dr = scale[n] * w[n] * dt, scale[n + 1] * w[n + 1] * dt
            x, y, yaw = E.arc(x, y, yaw, 0.5 * r_w * (dl + dr), 0.5 * r_w / b_w * (dr - dl))
        out[r, 0], out[r, 1], out[r, 2], out[r, 3] = peak, when, which, worst


def check_rows(batch, rows, margin: float = FEASIBILITY_MARGIN) -> list[Feasibility]:
    """The check of the episodes just begun in rows `rows` of an engine batch (`mobman_env.batch.RobotBatch`,
    after its reset: it holds each row's true robot, path and start)."""
    rows = np.asarray(rows, dtype=np.intp)
    m = batch.m
    S = batch.S
    q0 = batch.st[rows, S.q : S.q + m].copy()
    pose0 = batch.st[rows][:, [S.x, S.y, S.yaw]]
    steps = batch.prm[rows, E.PRM.n_steps].copy()
    out = np.zeros((len(rows), 4))
    _peaks(batch.arm, batch.prm, rows, q0, pose0, batch.dt, steps, REFERENCE_GAIN, REFERENCE_DAMPING, out)
    return [Feasibility(float(p), float(t), int(j), float(margin), float(e)) for p, t, j, e in out]


def check_env(env, margin: float = FEASIBILITY_MARGIN) -> Feasibility:
    """The check of a single env's current episode (call it after `reset`): `WheeledPumaEnv` or a wrapper of it."""
    base = env.unwrapped
    if not math.isfinite(margin) or not 0.0 <= margin < 1.0:
        raise ValueError(f"margin={margin!r}: a fraction of the limits in [0, 1), e.g. {FEASIBILITY_MARGIN}")
    return check_rows(base._batch, [0], margin)[0]


def warm() -> float:
    """Compile `_peaks` (or load it from numba's cache); returns the seconds it took (`python -m mobman_env`)."""
    import time

    t0 = time.perf_counter()
    m = 8
    arm = np.zeros((1, E.ARM_ROWS, m))
    arm[0, E.ARM.cos_alpha] = 1.0
    arm[0, E.ARM.action_scale] = 1.0
    prm = np.zeros((1, E.P_LEN))
    prm[0, E.PRM.wheel_radius] = prm[0, E.PRM.half_track] = 0.2
    prm[0, E.PRM.path + 3] = 1.0  # the path's duration
    rows = np.arange(1)
    out = np.zeros((1, 4))
    _peaks(arm, prm, rows, np.zeros((1, m)), np.zeros((1, 3)), 0.01, np.full(1, 2.0), 20.0, 1e-3, out)
    return time.perf_counter() - t0

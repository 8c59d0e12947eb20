"""The prediction model of `mpc` and `mpc-oracle`: the actuator lag over a horizon, the path's preview and the
condensed QP, as scalar per-row kernels over N rows.

Horizon: H prediction steps of h = `step` control periods each; the commands are blocked: B input blocks, the
first one prediction step long, the others sharing the remaining H - 1 steps (`block_lengths`). Within a block
every actuator's command u_b is constant.

Lag (exact, as `mobman_env.engine._actuate`): every actuator's realised speed w follows its command u through a
first-order lag of time constant tau, so over one prediction step of length h with a constant command

    w_{k+1} = a w_k + (1 - a) u_k,          a = exp(-h / tau)
    dq_k    = beta w_k + (h - beta) u_k,    beta = tau (1 - a)   (the integral of w over the step)

(tau = 0: a = beta = 0, w = u, dq = h u). A constant command over `step` control periods gives the same
numbers as `step` env steps (exact discretisation: equal to rounding, `tests/test_mpc.py`). Unrolled from the
measured realised speeds w_0 (`joint_vel`), the angle change after k steps is D_k = c_k w_0 + sum_b G_kb u_b
with scalars c (H,) and G (H, B) (`lag_coefficients`) shared by every actuator.

End effector: r_k = r_0 + J D_k with the whole-body Jacobian J at the measured state (the platform's wheel angles
included: J maps every actuator's angle change to the point's displacement), held over the horizon.

Preview: r_d(t + k h) of the episode's path (`engine.path_eval`, the env's own function, from the path spec and
start that `info["task"]` echoes at reset: `task_coefficients`); a row started without its task (an
`episode_start` in `predict`, which carries no info) extrapolates the observed target with constant
acceleration, r_d(t) + r_d_dot(t) kh + a (kh)^2 / 2, a the finite difference of `target_vel`.

Imports numpy, numba, the standard library and `mobman_env` (engine, paths) only.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mobman_env import engine as E
from mobman_env.numba_cache import njit
from mobman_env.paths import path_from_spec


def block_lengths(horizon: int, blocks: int) -> np.ndarray:
    """The lengths (prediction steps) of the `blocks` input blocks over `horizon` steps: the first is 1 step (the
    move applied now gets its own variable), the others share the rest as evenly as possible, the longer ones
    last."""
    if not 1 <= blocks <= horizon:
        raise ValueError(f"blocks must be in [1, horizon={horizon}], got {blocks}")
    if blocks == 1:
        return np.array([horizon])
    rest, extra = divmod(horizon - 1, blocks - 1)
    tail = [rest + (1 if j >= blocks - 1 - extra else 0) for j in range(blocks - 1)]
    return np.array([1, *tail])


@njit(cache=True)
def lag_coefficients(tau, h, lengths, c, G):
    """c (H,) and G (H, B) of D_k = c_k w_0 + sum_b G_kb u_b (k = 1 .. H in rows 0 .. H-1) for the lag `tau` (s,
    >= 0) over prediction steps of h s with the input blocks of `lengths` (see the module docstring)."""
    H, B = G.shape
    a, beta = 0.0, 0.0
    if tau > 0.0:
        a = math.exp(-h / tau)
        beta = -tau * math.expm1(-h / tau)
    # w_k = cw w_0 + sum_b gw_b u_b;  D_k = cd w_0 + sum_b gd_b u_b
    gw = np.zeros(B)
    gd = np.zeros(B)
    cw, cd = 1.0, 0.0
    b, left = 0, lengths[0]
    for k in range(H):
        if left == 0:
            b += 1
            left = lengths[b]
        left -= 1
        cd += beta * cw
        for j in range(B):
            gd[j] += beta * gw[j]
        gd[b] += h - beta
        cw = a * cw
        for j in range(B):
            gw[j] = a * gw[j]
        gw[b] += 1.0 - a
        c[k] = cd
        for j in range(B):
            G[k, j] = gd[j]


@njit(cache=True)
def preview_rows(coef, has_path, t, h, target_pos, target_vel, target_acc, out):
    """r_d(t_i + k h) - for k = 1 .. H into out (N, H, 3): from the path coefficients coef (N, PATH_LEN) where
    has_path, else the constant-acceleration extrapolation of the observed target."""
    N, H = out.shape[0], out.shape[1]
    pe = np.empty((3, 3))
    for i in range(N):
        for k in range(H):
            s = (k + 1) * h
            if has_path[i]:
                E.path_eval(coef[i], t[i] + s, pe)
                for a in range(3):
                    out[i, k, a] = pe[0, a]
            else:
                for a in range(3):
                    out[i, k, a] = target_pos[i, a] + s * target_vel[i, a] + 0.5 * s * s * target_acc[i, a]


@njit(cache=True)
def condensed_qp(J, d, w0, c, G, omega, h, reg, z, rate, u_prev, P, f):
    """The condensed QP of one row, minimise 1/2 x^T P x + f^T x over the blocked commands x = [u_0; ...; u_{B-1}]
    (B m), into P (B m, B m) and f (B m,):

        sum_k omega_k ||d_k - J (c_k w_0 + sum_b G_kb u_b)||^2 / h^2 + sum_b (u_b - z)^T diag(reg_b) (u_b - z)
        + rate (||u_0 - u_prev||^2 + sum_b>0 ||u_b - u_{b-1}||^2)

    (halved; the constant dropped). J (3, m); d (H, 3): r_d(t + k h) - r_0; w0 (m,); reg (B, m): each block's
    effort weights (its length times the actuator's weight times effort_weight)."""
    H, B = G.shape
    m = J.shape[1]
    inv_h2 = 1.0 / (h * h)
    JtJ = np.zeros((m, m))
    for i in range(m):
        for j in range(m):
            JtJ[i, j] = J[0, i] * J[0, j] + J[1, i] * J[1, j] + J[2, i] * J[2, j]
    Jw0 = np.zeros(3)
    for a in range(3):
        for j in range(m):
            Jw0[a] += J[a, j] * w0[j]
    for x in range(B * m):
        f[x] = 0.0
        for y in range(B * m):
            P[x, y] = 0.0
    for k in range(H):
        wk = omega[k] * inv_h2
        e0 = d[k, 0] - c[k] * Jw0[0]
        e1 = d[k, 1] - c[k] * Jw0[1]
        e2 = d[k, 2] - c[k] * Jw0[2]
        for b in range(B):
            gb = wk * G[k, b]
            for i in range(m):
                f[b * m + i] -= gb * (J[0, i] * e0 + J[1, i] * e1 + J[2, i] * e2)
            for b2 in range(B):
                g = gb * G[k, b2]
                for i in range(m):
                    for j in range(m):
                        P[b * m + i, b2 * m + j] += g * JtJ[i, j]
    for b in range(B):
        for i in range(m):
            x = b * m + i
            P[x, x] += reg[b, i] + (2.0 * rate if b < B - 1 else rate)
            f[x] -= reg[b, i] * z[i]
            if b == 0:
                f[x] -= rate * u_prev[i]
            else:
                P[x, x - m] -= rate
                P[x - m, x] -= rate


#: the accumulated excitation sum_k sum_j ((w_k - u_k) / scale_j)^2 above which `lag_fit_rows` trusts its fit
LAG_MIN_EXCITATION = 1e-6
#: the fitted decay per control period a below which `lag_fit_rows` reads no lag: the float32 rounding of the
#: measured speeds reads as a ~ 1e-8 (tau ~ dt / 18) without lag, and a lag that decays by 1e-3 within a control
#: period (tau < dt / 6.9) moves nothing the next prediction step can see
LAG_MIN_DECAY = 1e-3


@njit(cache=True)
def lag_fit_rows(rows, w_prev, w, u, scale, dt, sxy, sxx, tau):
    """One step of the online lag fit of the rows `rows`: with x = (w_prev - u) / scale, y = (w - u) / scale per
    actuator (w_prev, w the measured speeds before and after the command u of the last control period), adds
    sum x y and sum x^2 to sxy, sxx (N,) and sets tau (N,) to -dt / ln(a), a = sxy / sxx capped at 0.999
    (tau = 0 for a <= `LAG_MIN_DECAY`), once sxx passes `LAG_MIN_EXCITATION`."""
    m = w.shape[1]
    for r in range(rows.shape[0]):
        i = rows[r]
        for j in range(m):
            x = (w_prev[i, j] - u[i, j]) / scale[j]
            y = (w[i, j] - u[i, j]) / scale[j]
            sxy[i] += x * y
            sxx[i] += x * x
        if sxx[i] > LAG_MIN_EXCITATION:
            a = min(sxy[i] / sxx[i], 0.999)
            tau[i] = -dt / math.log(a) if a > LAG_MIN_DECAY else 0.0


def task_coefficients(info: Any, i: int) -> np.ndarray | None:
    """Row i's path coefficients (`engine.PATH_LEN`) from a reset's `info["task"]`: a single env's (a dict holding
    the path spec and its start) or a vector env's (Gymnasium's dict of per-row arrays with `_key` masks); None
    when the info holds no task for row i (an `episode_start` without info, a loop that passes none)."""
    task = info.get("task") if isinstance(info, dict) else None
    if not isinstance(task, dict) or "path" not in task or "start" not in task:
        return None
    spec, start = task["path"], task["start"]
    if isinstance(spec, dict) and "_type" in spec:  # the vector env's form: one array per key, masks in `_key`
        if not task.get("_path", np.ones(i + 1, bool))[i]:
            return None
        spec = {key: _item(v[i]) for key, v in spec.items() if not key.startswith("_") and spec["_" + key][i]}
        start = start[i]
    elif i != 0:
        return None
    path = path_from_spec(spec, np.asarray(start, dtype=float))
    return np.asarray(path.coef, dtype=float)


def _item(v: Any) -> Any:
    return v.item() if isinstance(v, np.generic) else v

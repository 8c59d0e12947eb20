"""Batched kernels the controllers' laws share: the damped pseudo-inverse and a model's Jacobian, over N rows.

Every array carries a leading axis of N robots (states (N, ...), observations (N, k)); a single-env controller
is the N = 1 case of the same functions (STYLE 14: one implementation per law), so row i of a batch equals the
N = 1 call on row i by construction: the laws are scalar per-row code compiled with numba (`@njit(cache=True)`,
STYLE 17), looped over the rows, with no matrix product (no BLAS): J J^T, the smallest eigenvalue of the 3 x 3
(Smith's closed form), the damping, the cofactor solve and J^T w are sums written out in a fixed order, so the
bits do not depend on the BLAS build or kernel.

`damped_pinv_apply_rows` is the law of NNBC, JMPI, CLIK and the oracle; `ModelJacobians` evaluates the paper's or
the whole-body Jacobian of each row's robot (nominal or true) with `mobman_env.engine.jacobians`, the env's own
chain (so a model-based controller sees the env's numbers for its model). The model is the robot's, not the law.

Imports numpy, numba, the standard library, `mobman_env` modules and `policies.base` only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from mobman_env import engine as E
from mobman_env.numba_cache import njit
from policies.base import missing_keys_error

_THIRD_TURN = 2.0 * math.pi / 3.0


@njit(cache=True)
def _sigma_min_3(a00, a01, a02, a11, a12, a22):
    """Smallest eigenvalue of the symmetric 3 x 3 matrix of these entries (closed form, Smith 1961). On A = J J^T
    it is sigma_min(J)^2."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1
    if p2 <= 1e-30 * (q * q + 1e-300):  # a multiple of the identity: every eigenvalue is q
        return q
    p = math.sqrt(p2 / 6.0)
    det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02)
    r = det / (2.0 * p * p * p)
    r = min(max(r, -1.0), 1.0)
    return q + 2.0 * p * math.cos(math.acos(r) / 3.0 + _THIRD_TURN)


@njit(cache=True)
def _dpinv_rows(J, v, damping, sigma_threshold, u):
    """u_i = J_i^T (J_i J_i^T + lambda_i^2 I)^{-1} v_i into u (N, m); returns the rows whose damped J J^T is
    exactly singular (their u is left for the caller's least-squares fallback), as a boolean array."""
    nrow, m = J.shape[0], J.shape[2]
    t2 = sigma_threshold * sigma_threshold
    singular = np.zeros(nrow, dtype=np.bool_)
    for i in range(nrow):
        a00 = a01 = a02 = a11 = a12 = a22 = 0.0
        for j in range(m):
            x, y, z = J[i, 0, j], J[i, 1, j], J[i, 2, j]
            a00 += x * x
            a01 += x * y
            a02 += x * z
            a11 += y * y
            a12 += y * z
            a22 += z * z
        s2 = _sigma_min_3(a00, a01, a02, a11, a12, a22)
        lam2 = damping * damping * (1.0 - s2 / t2) if s2 < t2 else 0.0
        a00 += lam2
        a11 += lam2
        a22 += lam2
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        det = a00 * c00 + a01 * c01 + a02 * c02
        if det == 0.0 or not math.isfinite(det):
            singular[i] = True
            continue
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        c22 = a00 * a11 - a01 * a01
        inv = 1.0 / det
        v0, v1, v2 = v[i, 0], v[i, 1], v[i, 2]
        w0 = (c00 * v0 + c01 * v1 + c02 * v2) * inv
        w1 = (c01 * v0 + c11 * v1 + c12 * v2) * inv
        w2 = (c02 * v0 + c12 * v1 + c22 * v2) * inv
        for j in range(m):
            u[i, j] = w0 * J[i, 0, j] + w1 * J[i, 1, j] + w2 * J[i, 2, j]
    return singular


def damped_pinv_apply_rows(J: np.ndarray, v: np.ndarray, damping: float, sigma_threshold: float) -> np.ndarray:
    """u_i = J_i^T (J_i J_i^T + lambda_i^2 I)^{-1} v_i for J (N, 3, m) and v (N, 3) -> u (N, m).

    lambda as in `policies.laws.nnbc` (zero unless J_i's smallest singular value is below sigma_threshold:
    lambda^2 = damping^2 (1 - sigma_min^2 / threshold^2)). A row whose damped J J^T is exactly singular
    (damping = 0 and a rank-deficient J) gets the least-squares solution; a row holding NaN or inf (a non-finite
    observation) gets NaN: that row's problem, which the env refuses naming the robot, never a LAPACK error that
    would fail the whole batch.
    """
    J = np.ascontiguousarray(J, dtype=float)
    v = np.ascontiguousarray(v, dtype=float)
    u = np.empty((J.shape[0], J.shape[2]))
    singular = _dpinv_rows(J, v, float(damping), float(sigma_threshold), u)
    for i in np.flatnonzero(singular).tolist():
        if np.isfinite(J[i]).all() and np.isfinite(v[i]).all():
            u[i] = np.linalg.lstsq(J[i], v[i], rcond=None)[0]
        else:
            u[i] = np.nan
    return u


def sigma_min_3(A: Any) -> float:
    """Smallest eigenvalue of a symmetric 3 x 3 matrix (nested lists or an array; closed form, Smith 1961).
    Used on A = J J^T, so it returns sigma_min(J)^2."""
    return float(
        _sigma_min_3(float(A[0][0]), float(A[0][1]), float(A[0][2]), float(A[1][1]), float(A[1][2]), float(A[2][2]))
    )


def damped_pinv_apply(J: np.ndarray, v: np.ndarray, damping: float, sigma_threshold: float) -> np.ndarray:
    """u = J^T (J J^T + lambda^2 I)^{-1} v for a 3 x n J, lambda as in `policies.laws.nnbc`'s module docstring: the
    one-row case of `damped_pinv_apply_rows` (what the laws run)."""
    J1, v1 = np.asarray(J, dtype=float)[None], np.asarray(v, dtype=float)[None]
    return damped_pinv_apply_rows(J1, v1, damping, sigma_threshold)[0]


def damped_pinv(J: np.ndarray, damping: float, sigma_threshold: float) -> np.ndarray:
    """The damped pseudo-inverse matrix itself (n x 3), same damping rule, by numpy's dense algebra (for
    diagnostics and tests: the independent reference of `damped_pinv_apply`)."""
    JJt = J @ J.T
    s2 = sigma_min_3(JJt)
    t2 = sigma_threshold * sigma_threshold
    lam2 = damping * damping * (1.0 - s2 / t2) if s2 < t2 else 0.0
    return J.T @ np.linalg.inv(JJt + lam2 * np.eye(3))


def obs_rows(observation: dict, keys: Sequence[str]) -> dict[str, np.ndarray]:
    """The observation keys `keys` as float64 (N, k) arrays (a 1-D observation becomes a batch of one); a missing
    key raises ValueError naming it, the keys read and the fix (`policies.base.missing_keys_error`)."""
    out = {}
    try:
        for k in keys:
            x = np.asarray(observation[k], dtype=float)
            out[k] = x[None] if x.ndim == 1 else x
    except KeyError:
        raise missing_keys_error(observation, keys) from None
    return out


class ModelJacobians:
    """The Jacobians of N rows' robot models at measured states, from `mobman_env.engine` (the env's own chain).

    `provider(i)` returns row i's `RobotParams` (the nominal robot, or robot i's true robot for the oracle);
    `load(rows)` packs it for those rows (called at each of their episode starts). Rows may hold different arms
    (the random family) with the same number of joints. `__call__(joint_pos, base_yaw, full, rows=None)` ->
    (k, 3, n + 2) at joint_pos (k, n + 2) and base_yaw (k, 1) of all rows or of the rows `rows` (an index array):
    the whole-body Jacobian (full=True) or the paper's J (`mobman_env.kinematics.whole_body_jacobian` and
    `paper_jacobian` of each row's robot, bit for bit: the same kernel). `params[i]` is the `RobotParams` row i
    loaded.
    """

    def __init__(self, n: int, provider: Callable[[int], Any]):
        self._provider = provider
        self.params: list[Any] = [None] * n
        self._n = n
        self._all = np.arange(n)
        self._arm = np.zeros((0, 0, 0))
        self._prm = np.zeros((0, 0))

    @property
    def arm(self) -> np.ndarray:
        """The packed `arm` rows (N, 8, n + 2) of the models (`mobman_env.engine`'s layout). A law that calibrates its
        model (`policies.laws.calib_qp`) writes its estimates into them in place; the next `__call__` uses them."""
        return self._arm

    @property
    def prm(self) -> np.ndarray:
        """The packed `prm` rows (N, `P_LEN`) of the models; written in place like `arm`."""
        return self._prm

    def load(self, rows: Any) -> None:
        """Read the robots of the rows `rows` (an index array or a sequence of ints)."""
        for i in rows:
            p = self._provider(i)
            if p is self.params[i]:
                continue
            if self._arm.shape[0] == 0:
                self._arm = np.zeros((self._n, E.ARM_ROWS, p.n_actuators))
                self._prm = np.zeros((self._n, E.P_LEN))
            elif p.n_actuators != self._arm.shape[2]:
                raise ValueError(
                    f"row {i}'s robot ({p.arm.name}) has {p.n_actuators} actuators, row 0's {self._arm.shape[2]}: "
                    "cannot batch them"
                )
            self.params[i] = p
            E.pack_robot(self._arm, self._prm, int(i), p)

    def __call__(self, joint_pos: np.ndarray, base_yaw: np.ndarray, full: bool, rows: Any = None) -> np.ndarray:
        sel = self._all if rows is None else np.asarray(rows, dtype=np.intp).reshape(-1)
        out = np.empty((len(sel), 3, self._arm.shape[2]))
        q = np.ascontiguousarray(joint_pos, dtype=float)
        E.jacobians(self._arm, self._prm, sel, q, np.ascontiguousarray(base_yaw[:, 0], dtype=float), full, out)
        return out

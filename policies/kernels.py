"""Batched kernels the controllers' laws share: the damped pseudo-inverse and a model's Jacobian, over N rows.

Every array carries a leading axis of N robots (states (N, ...), observations (N, k)); a single-env controller
is the N = 1 case of the same functions (STYLE 14: one implementation per law), so row i of a batch equals the
N = 1 call on row i. Two rules keep that exact:

* Matrix products (J J^T, J u, w J) go through numpy's stacked `matmul`, which runs the same BLAS kernel once per
  row whatever N is: the N = 1 call and row i of a batch round alike.
* The 3 x 3 algebra after J J^T (the smallest eigenvalue, the damping, the cofactor solve) is about 60 scalar
  operations: written out once (`_solve3`), on Python floats when N = 1 (numpy's per-call overhead, ~0.5 us,
  would otherwise dominate the single-env `predict`) and on (N,) arrays when N > 1. +, -, *, / and sqrt round
  alike in both. arccos does not: `np.arccos` differs from `math.acos` in the last bit on about 9% of arguments
  on our machines, which changes sigma_min's last bit. That bit matters only where the damping acts (sigma_min
  below the threshold), so those rows (with a margin) take sigma_min from the float path, one row at a time:
  rows of a batch, the single-env policy and release 0.1's single-env code then agree bit for bit (checked:
  `nnbc` over whole Circle and Line episodes, damped steps included).

`damped_pinv_apply_rows` is `policies.nnbc.damped_pinv_apply` for N rows (the law of NNBC, JMPI, CLIK and the
oracle); `ModelJacobians` evaluates the paper's or the whole-body Jacobian of each row's robot (nominal or true)
with `mobman_env.vector_kinematics`, which equals `mobman_env.kinematics` bit for bit (the env's own contract,
and `tests/test_batched_policies.py` checks it for these Jacobians); a batch of one row calls
`mobman_env.kinematics` itself, whose 4 x 4 products cost less than the batched ones' bookkeeping at N = 1. The
model is the robot's, not the law: the law (`damped_pinv_apply_rows` and the controllers' feedback) is the same
code for every N.

Imports numpy, the standard library and `mobman_env` modules only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from mobman_env import kinematics as K
from mobman_env import vector_kinematics as VK

_THIRD_TURN = 2.0 * math.pi / 3.0


def _acos(x: Any) -> Any:
    return math.acos(x) if isinstance(x, float) else np.arccos(x)


def _cos(x: Any) -> Any:
    return math.cos(x) if isinstance(x, float) else np.cos(x)


def _sqrt(x: Any) -> Any:
    """Correctly rounded square root of a float or an array (`x ** 0.5` is pow for a float, sqrt for an array)."""
    return math.sqrt(x) if isinstance(x, float) else np.sqrt(x)


def sigma_min_3_entries(a00: Any, a01: Any, a02: Any, a11: Any, a12: Any, a22: Any) -> Any:
    """Smallest eigenvalue of the symmetric 3 x 3 matrix of these entries (closed form, Smith 1961); floats or
    (N,) arrays. On A = J J^T it is sigma_min(J)^2."""
    p1 = a01 * a01 + a02 * a02 + a12 * a12
    q = (a00 + a11 + a22) / 3.0
    b00, b11, b22 = a00 - q, a11 - q, a22 - q
    p2 = b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * p1
    degenerate = p2 <= 1e-30 * (q * q + 1e-300)  # a multiple of the identity: every eigenvalue is q
    if isinstance(degenerate, bool):
        if degenerate:
            return q
    else:
        p2 = np.where(degenerate, 1.0, p2)  # the value is discarded below; avoids dividing by zero
    p = _sqrt(p2 / 6.0)
    det = b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02)
    r = det / (2.0 * p * p * p)
    r = np.minimum(np.maximum(r, -1.0), 1.0) if isinstance(r, np.ndarray) else (-1.0 if r < -1.0 else min(r, 1.0))
    phi = _acos(r) / 3.0
    out = q + 2.0 * p * _cos(phi + _THIRD_TURN)
    return out if isinstance(degenerate, bool) else np.where(degenerate, q, out)


def _solve3(A: Sequence[Any], v: Sequence[Any], damping: float, sigma_threshold: float) -> tuple[Any, ...]:
    """w = (A + lambda^2 I)^{-1} v for A = J J^T given as its 6 entries (a00, a01, a02, a11, a12, a22) and v as 3
    entries, floats or (N,) arrays; lambda^2 as in `policies.nnbc` (damping only below sigma_threshold).
    Returns (w0, w1, w2, det); a row with det == 0 or a non-finite det is singular (the caller falls back)."""
    a00, a01, a02, a11, a12, a22 = A
    s2 = sigma_min_3_entries(a00, a01, a02, a11, a12, a22)
    t2 = sigma_threshold * sigma_threshold
    lam2: Any
    if isinstance(s2, float):
        lam2 = damping * damping * (1.0 - s2 / t2) if s2 < t2 else 0.0
    else:
        # rows that may be damped take sigma_min from the float path: numpy's arccos and math's differ in the
        # last bit, and only a damped row's command depends on that bit (the margin covers the boundary)
        for i in np.flatnonzero(s2 < t2 * (1.0 + 1e-6) + 1e-12).tolist():
            s2[i] = sigma_min_3_entries(*(float(x[i]) for x in (a00, a01, a02, a11, a12, a22)))
        lam2 = np.where(s2 < t2, damping * damping * (1.0 - s2 / t2), 0.0)
    a00 = a00 + lam2
    a11 = a11 + lam2
    a22 = a22 + lam2
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    v0, v1, v2 = v
    inv: Any
    if isinstance(det, float):
        inv = 1.0 / det if det != 0.0 and math.isfinite(det) else 0.0
    else:
        ok = (det != 0.0) & np.isfinite(det)
        inv = 1.0 / np.where(ok, det, 1.0)
    return (
        (c00 * v0 + c01 * v1 + c02 * v2) * inv,
        (c01 * v0 + c11 * v1 + c12 * v2) * inv,
        (c02 * v0 + c12 * v1 + c22 * v2) * inv,
        det,
    )


def damped_pinv_apply_rows(J: np.ndarray, v: np.ndarray, damping: float, sigma_threshold: float) -> np.ndarray:
    """u_i = J_i^T (J_i J_i^T + lambda_i^2 I)^{-1} v_i for J (N, 3, m) and v (N, 3) -> u (N, m).

    lambda as in `policies.nnbc` (zero unless J_i's smallest singular value is below sigma_threshold). A row
    whose damped J J^T is exactly singular (damping = 0 and a rank-deficient J) gets the least-squares solution.
    """
    n = J.shape[0]
    JJt = np.matmul(J, J.transpose(0, 2, 1))
    if n == 1:
        (a00, a01, a02), (_, a11, a12), (_, _, a22) = JJt[0].tolist()
        w0, w1, w2, det = _solve3((a00, a01, a02, a11, a12, a22), v[0].tolist(), damping, sigma_threshold)
        if det == 0.0 or not math.isfinite(det):
            return np.linalg.lstsq(J[0], v[0], rcond=None)[0][None]
        w = np.array([[[w0, w1, w2]]])
    else:
        entries = (JJt[:, 0, 0], JJt[:, 0, 1], JJt[:, 0, 2], JJt[:, 1, 1], JJt[:, 1, 2], JJt[:, 2, 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            w0, w1, w2, det = _solve3(entries, (v[:, 0], v[:, 1], v[:, 2]), damping, sigma_threshold)
        w = np.stack([w0, w1, w2], axis=1)[:, None, :]
        bad = np.flatnonzero((det == 0.0) | ~np.isfinite(det))
    u = np.matmul(w, J)[:, 0, :]
    if n > 1:
        for i in bad.tolist():
            u[i] = np.linalg.lstsq(J[i], v[i], rcond=None)[0]
    return u


def sigma_min_3(A: list) -> float:
    """Smallest eigenvalue of a symmetric 3 x 3 matrix given as nested lists (closed form, Smith 1961).

    Used on A = J J^T, so it returns sigma_min(J)^2. Pure-Python floats: ~3x faster than `eigvalsh` here
    (`sigma_min_3_entries`, which takes (N,) arrays too).
    """
    return sigma_min_3_entries(A[0][0], A[0][1], A[0][2], A[1][1], A[1][2], A[2][2])


def damped_pinv_apply(J: np.ndarray, v: np.ndarray, damping: float, sigma_threshold: float) -> np.ndarray:
    """u = J^T (J J^T + lambda^2 I)^{-1} v for a 3 x n J, lambda as in `policies.nnbc`'s module docstring.

    The one-row case of `damped_pinv_apply_rows` (what the laws run): J J^T + lambda^2 I is
    inverted in closed form (cofactors, pure-Python floats for one row): exact for 3 x 3 and several times faster
    than `np.linalg.solve` for such a small system.
    """
    J1, v1 = np.asarray(J, dtype=float)[None], np.asarray(v, dtype=float)[None]
    return damped_pinv_apply_rows(J1, v1, damping, sigma_threshold)[0]


def damped_pinv(J: np.ndarray, damping: float, sigma_threshold: float) -> np.ndarray:
    """The damped pseudo-inverse matrix itself (n x 3), same damping rule (for diagnostics and tests)."""
    JJt = J @ J.T
    s2 = sigma_min_3(JJt.tolist())
    t2 = sigma_threshold * sigma_threshold
    lam2 = damping * damping * (1.0 - s2 / t2) if s2 < t2 else 0.0
    return J.T @ np.linalg.inv(JJt + lam2 * np.eye(3))


def obs_rows(observation: dict, keys: Sequence[str]) -> dict[str, np.ndarray]:
    """The observation keys `keys` as float64 (N, k) arrays (a 1-D observation becomes a batch of one)."""
    out = {}
    for k in keys:
        x = np.asarray(observation[k], dtype=float)
        out[k] = x[None] if x.ndim == 1 else x
    return out


#: the lengths of a robot the Jacobian reads, by `mobman_env.vector_kinematics` key
_LENGTHS = ("a", "d", "tool", "wheel_radius", "half_track", "mount_offset")


class ModelJacobians:
    """The Jacobians of N rows' robot models at measured states, batched (`mobman_env.vector_kinematics`).

    `provider(i)` returns row i's `RobotParams` (the nominal robot, or robot i's true robot for the oracle);
    `load(rows)` reads it for those rows (called at each of their episode starts). Every row must have the arm of
    row 0 (joint count, DH twists and offsets, convention): only lengths may differ, as the worn robots do.
    `__call__(joint_pos, base_yaw, full, rows=None)` -> (N, 3, n + 2) at joint_pos (N, n + 2) and base_yaw (N, 1)
    (or those of the rows `rows` only, an index array), equal bit
    for bit to `mobman_env.kinematics.paper_jacobian` (full=False) or `whole_body_jacobian` (full=True) of each
    row's robot. `params[i]` is the `RobotParams` row i loaded.
    """

    def __init__(self, n: int, provider: Callable[[int], Any]):
        self._provider = provider
        self.params: list[Any] = [None] * n
        self._n = n
        self._lengths: dict[str, np.ndarray] = {}
        self._arm: Any = None

    def load(self, rows: Any) -> None:
        """Read the robots of the rows `rows` (an index array or a sequence of ints)."""
        for i in rows:
            p = self._provider(i)
            if p is self.params[i]:
                continue
            if self._arm is None:
                self._set_arm(p)
            elif p.arm.n_joints != self._nj or p.arm.modified != self._modified:
                raise ValueError(f"row {i}'s robot has another arm ({p.arm.name}) than row 0's: cannot batch them")
            self.params[i] = p
            a, d, _, _ = p.dh_constants
            self._lengths["a"][i], self._lengths["d"][i] = a, d
            for k in _LENGTHS[2:]:
                self._lengths[k][i] = getattr(p, k)

    def _set_arm(self, p: Any) -> None:
        self._arm = p.arm
        self._nj = nj = p.n_joints
        self._modified = p.arm.modified
        _, _, self._ca, self._sa = p.dh_constants
        self._offset = p.theta_offset
        self._lengths = {k: np.zeros((self._n, nj) if k in ("a", "d") else self._n) for k in _LENGTHS}

    def __call__(self, joint_pos: np.ndarray, base_yaw: np.ndarray, full: bool, rows: Any = None) -> np.ndarray:
        if joint_pos.shape[0] == 1:  # one row: the single env's kinematics, equal bit for bit and 2-3x faster
            i = 0 if rows is None else int(np.asarray(rows).reshape(-1)[0])
            jacobian = K.whole_body_jacobian if full else K.paper_jacobian
            return jacobian(self.params[i], joint_pos[0], float(base_yaw[0, 0]))[None]
        th = joint_pos[:, : self._nj]
        if self._offset is not None:
            th = th + self._offset
        yaw = base_yaw[:, 0]
        lengths = self._lengths if rows is None else {k: v[rows] for k, v in self._lengths.items()}
        return VK.jacobian(lengths, self._ca, self._sa, th, self._modified, np.cos(yaw), np.sin(yaw), full)

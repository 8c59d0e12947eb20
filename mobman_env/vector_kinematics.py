"""The kinematic simulation step of N robots in one numpy pass, in the single env's floating-point operations.

`mobman_env.vector.WheeledPumaVectorEnv` steps N robots with these functions; robot i must equal a single
`WheeledPumaEnv` bit for bit, so every expression here performs, per robot, the operations of
`mobman_env.kinematics` and `mobman_env.sim` (kinematic mode) in the same order:

* Elementwise numpy operations (+, -, *, /, sqrt, clip) round exactly as their scalar counterparts; numpy's
  float64 cos and sin equal `math.cos` and `math.sin` on the machines we test (`tests/test_vector_env.py` checks
  whole episodes, so a platform where they differ fails there).
* The single env's matrix products (the 4 x 4 DH chain, R(phi) f, R(phi) df/dtheta, J u, a @ a, the norm's dot)
  go through BLAS, whose kernels use fused multiply-adds: no elementwise numpy expression rounds like them. They
  are computed here by BLAS too, with the same shapes per robot: numpy's batched `matmul` calls the same kernel
  once per robot (`_bmm`). For the DH chain, the costliest part, `_chain_products` instead stacks G = 4 robots
  into one block-diagonal product (12 x 16 times 16 x 4): every entry is then the same FMA chain as the 4 x 4
  product (the other terms are exact zeros) at a quarter of the calls. Whether a BLAS build rounds the two the
  same is probed once (`_block_chain_exact`); where it does not, the per-robot products are used.

Any arm of `mobman_env.robots.ArmDescription` (n joints, standard or modified DH, theta offsets): the sizes come
from the arrays (n = a.shape[1], n + 2 actuators), the convention from `modified`, as in `mobman_env.kinematics`.
Arrays are batched along axis 0 (N robots). Lengths that differ per robot (the worn robots) are (N,) or (N, n)
arrays; joint angles (N, n + 2). Imports numpy only.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

#: robots per block-diagonal BLAS product of the DH chain (4 was fastest of 4, 8, 16, 32, measured)
GROUP = 4


def _bmm(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched matmul (one BLAS call per robot, the single env's shapes)."""
    return np.matmul(a, b)


def _bdot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (N, k) arrays as the single env's `x @ y` / `x.dot(y)` of 1-D arrays (BLAS dot),
    shape (N,)."""
    return np.matmul(a[:, None, :], b[:, :, None])[:, 0, 0]


def _bmv(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Matrix-vector products (N, r, k) x (N, k) -> (N, r) as the single env's `M @ v` (BLAS gemv)."""
    return np.matmul(m, v[:, :, None])[:, :, 0]


@functools.cache
def _block_buffer(ng: int) -> tuple[np.ndarray, np.ndarray]:
    """A zeroed (ng, 3G, 4G) block-diagonal matrix and a writable view of its G diagonal (3, 4) blocks,
    (ng, G, 3, 4); the off-diagonal zeros are never written, so the buffer is reused."""
    L = np.zeros((ng, 3 * GROUP, 4 * GROUP))
    s0, s1, s2 = L.strides
    diag = np.lib.stride_tricks.as_strided(
        L, shape=(ng, GROUP, 3, 4), strides=(s0, 3 * s1 + 4 * s2, s1, s2), writeable=True
    )
    return L, diag


def _block_products(F: np.ndarray, A: np.ndarray) -> np.ndarray:
    """F (N, 3, 4) @ A (N, 4, 4) for N a multiple of GROUP, G robots per block-diagonal product."""
    n = F.shape[0]
    ng = n // GROUP
    L, diag = _block_buffer(ng)
    diag[...] = F.reshape(ng, GROUP, 3, 4)
    return np.matmul(L, A.reshape(ng, 4 * GROUP, 4)).reshape(n, 3, 4)


@functools.cache
def _block_chain_exact() -> bool:
    """Whether this BLAS rounds the block-diagonal product like the per-robot 4 x 4 products (probed once on
    random matrices, all sizes of the final partial group included)."""
    rng = np.random.default_rng(0)
    F = rng.normal(size=(64, 3, 4))
    A = rng.normal(size=(64, 4, 4))
    return bool(np.array_equal(_block_products(F, A), np.matmul(F, A)))


def _chain_products(F: np.ndarray, A: np.ndarray) -> np.ndarray:
    """F (N, 3, 4) @ A (N, 4, 4): the top 3 rows of the 4 x 4 frame products (row 4 is [0, 0, 0, 1])."""
    n = F.shape[0]
    if n < GROUP or not _block_chain_exact():
        return np.matmul(F, A)
    head = n - n % GROUP
    if head == n:
        return _block_products(F, A)
    out = np.empty((n, 3, 4))
    out[:head] = _block_products(F[:head], A[:head])
    out[head:] = np.matmul(F[head:], A[head:])
    return out


def dh_transforms(
    a: np.ndarray, d: np.ndarray, ca: np.ndarray, sa: np.ndarray, th: np.ndarray, modified: bool
) -> np.ndarray:
    """`kinematics.dh_transforms` for N robots: a, d (N, n), ca, sa (n,) or (N, n), th (N, n) the DH angles
    (q plus the offsets, as the single env adds them) -> (N, n, 4, 4)."""
    ct, st = np.cos(th), np.sin(th)
    A = np.zeros((th.shape[0], th.shape[1], 4, 4))
    if modified:  # Rx(alpha) Tx(a) Rz(theta) Tz(d)
        A[:, :, 0, 0], A[:, :, 0, 1], A[:, :, 0, 3] = ct, -st, a
        A[:, :, 1, 0], A[:, :, 1, 1], A[:, :, 1, 2], A[:, :, 1, 3] = st * ca, ct * ca, -sa, -sa * d
        A[:, :, 2, 0], A[:, :, 2, 1], A[:, :, 2, 2], A[:, :, 2, 3] = st * sa, ct * sa, ca, ca * d
    else:  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
        A[:, :, 0, 0], A[:, :, 0, 1], A[:, :, 0, 2], A[:, :, 0, 3] = ct, -st * ca, st * sa, a * ct
        A[:, :, 1, 0], A[:, :, 1, 1], A[:, :, 1, 2], A[:, :, 1, 3] = st, ct * ca, -ct * sa, a * st
        A[:, :, 2, 1], A[:, :, 2, 2], A[:, :, 2, 3] = sa, ca, d
    A[:, :, 3, 3] = 1.0
    return A


def arm_point_and_jacobian(
    a: np.ndarray,
    d: np.ndarray,
    ca: np.ndarray,
    sa: np.ndarray,
    tool: np.ndarray,
    th: np.ndarray,
    modified: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """`kinematics.arm_point_and_jacobian` for N robots: f (N, 3) and df/dtheta (N, 3, n).

    The frames are the single env's `frames[i] @ A[i]` chain from the identity; frame 1 = I A_1 is A_1 itself
    (the product's FMA chain adds exact zeros), so the chain starts there. Joint axes: frames 0 .. n-1
    (standard DH) or 1 .. n (modified DH), as the single env's.
    """
    A = dh_transforms(a, d, ca, sa, th, modified)
    n, nj = th.shape
    frames = np.empty((n, nj, 3, 4))  # the top 3 rows of T_0^1 .. T_0^n
    frames[:, 0] = A[:, 0, :3]
    for i in range(1, nj):
        frames[:, i] = _chain_products(frames[:, i - 1], A[:, i])
    last = frames[:, -1]
    p = last[:, :, 3] + tool[:, None] * last[:, :, 2]
    if modified:
        z, o = frames[:, :, :, 2], frames[:, :, :, 3]
    else:
        z = np.empty((n, nj, 3))
        o = np.empty((n, nj, 3))
        z[:, 0], o[:, 0] = (0.0, 0.0, 1.0), 0.0  # frame 0 = I
        z[:, 1:], o[:, 1:] = frames[:, :-1, :, 2], frames[:, :-1, :, 3]
    v = p[:, None, :] - o
    J = np.empty((n, 3, nj))
    J[:, 0] = z[:, :, 1] * v[:, :, 2] - z[:, :, 2] * v[:, :, 1]
    J[:, 1] = z[:, :, 2] * v[:, :, 0] - z[:, :, 0] * v[:, :, 2]
    J[:, 2] = z[:, :, 0] * v[:, :, 1] - z[:, :, 1] * v[:, :, 0]
    return p, J


def _parts(
    lengths: dict[str, np.ndarray],
    ca: np.ndarray,
    sa: np.ndarray,
    th: np.ndarray,
    modified: bool,
    cos_yaw: np.ndarray,
    sin_yaw: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`kinematics._paper_parts` for N robots: g = R(phi) f (N, 3), the paper's J (N, 3, n + 2) and
    d p_c_dot / d u (N, 2, n + 2)."""
    n, nj = th.shape
    f, J_arm = arm_point_and_jacobian(lengths["a"], lengths["d"], ca, sa, lengths["tool"], th, modified)
    c, s = cos_yaw, sin_yaw
    R = np.zeros((n, 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    g = _bmv(R, f)
    r, b, dm = lengths["wheel_radius"], lengths["half_track"], lengths["mount_offset"]
    # the wheel maps entry by entry (the single env's outer products: d phi_dot / d w = [-r/2b, r/2b],
    # d v / d w = [r/2, r/2], d p_c_dot / d w = [c, s]^T dv + d [-s, c]^T dphi), the same operations per entry
    dphi = (-0.5 * r / b, 0.5 * r / b)
    hr = 0.5 * r
    ms = -s
    J = np.empty((n, 3, nj + 2))
    J[:, :, :nj] = _bmm(R, J_arm)
    mg1, g0 = -g[:, 1], g[:, 0]
    J_pc = np.zeros((n, 2, nj + 2))
    for k, dk in enumerate(dphi):
        J[:, 0, nj + k] = mg1 * dk
        J[:, 1, nj + k] = g0 * dk
        J[:, 2, nj + k] = 0.0 * dk
        J_pc[:, 0, nj + k] = c * hr + dm * (ms * dk)
        J_pc[:, 1, nj + k] = s * hr + dm * (c * dk)
    return g, J, J_pc


def jacobian(
    lengths: dict[str, np.ndarray],
    ca: np.ndarray,
    sa: np.ndarray,
    th: np.ndarray,
    modified: bool,
    cos_yaw: np.ndarray,
    sin_yaw: np.ndarray,
    full: bool,
) -> np.ndarray:
    """`kinematics.paper_jacobian` (full=False) or `kinematics.whole_body_jacobian` (full=True) for N robots,
    (N, 3, n + 2), bit for bit. `lengths` as for `ee_and_jacobian` (shoulder_height is not read); th (N, n) the DH
    angles; cos_yaw, sin_yaw (N,) of the heading. The model-based controllers' batched kernels use it."""
    _, J, J_pc = _parts(lengths, ca, sa, th, modified, cos_yaw, sin_yaw)
    if full:
        J[:, :2] += J_pc
    return J


def robot_jacobians(params: Any, q_arm: np.ndarray, yaw: np.ndarray, full: bool) -> np.ndarray:
    """`kinematics.paper_jacobian` (full=False) or `kinematics.whole_body_jacobian` (full=True) of ONE robot
    (`RobotParams`) at k states, (k, 3, n + 2), bit for bit: q_arm (k, n) the arm angles (offsets are added here,
    as the single env adds them), yaw (k,) the headings. One numpy pass instead of k FK passes (eval's Jacobian
    metrics use it for a whole episode)."""
    q_arm = np.asarray(q_arm, dtype=float)
    k, nj = q_arm.shape
    a, d, ca, sa = params.dh_constants
    lengths = {"a": np.broadcast_to(a, (k, nj)), "d": np.broadcast_to(d, (k, nj))}
    for key in ("tool", "wheel_radius", "half_track", "mount_offset"):
        lengths[key] = np.full(k, getattr(params, key))
    offset = params.theta_offset
    th = q_arm if offset is None else q_arm + offset
    yaw = np.asarray(yaw, dtype=float)
    return jacobian(lengths, ca, sa, th, params.arm.modified, np.cos(yaw), np.sin(yaw), full)


def ee_and_jacobian(
    lengths: dict[str, np.ndarray],
    ca: np.ndarray,
    sa: np.ndarray,
    th: np.ndarray,
    modified: bool,
    pose: np.ndarray,
    cos_yaw: np.ndarray,
    sin_yaw: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """`kinematics.ee_and_jacobian` and `arm_base_xy` for N robots: r_a (N, 3), the whole-body Jacobian
    (N, 3, n + 2), d p_c_dot / d u (N, 2, n + 2) and p_c (N, 2). `lengths`: the per-robot arrays a (N, n),
    d (N, n), tool, wheel_radius, half_track, mount_offset, shoulder_height (N,); th (N, n) the DH angles."""
    g, J, J_pc = _parts(lengths, ca, sa, th, modified, cos_yaw, sin_yaw)
    J[:, :2] += J_pc
    c, s, dm = cos_yaw, sin_yaw, lengths["mount_offset"]
    pc = np.empty((len(c), 2))
    pc[:, 0] = pose[:, 0] + dm * c
    pc[:, 1] = pose[:, 1] + dm * s
    ee = np.empty((len(c), 3))
    ee[:, 0] = pc[:, 0] + g[:, 0]
    ee[:, 1] = pc[:, 1] + g[:, 1]
    ee[:, 2] = lengths["shoulder_height"] + g[:, 2]
    return ee, J, J_pc, pc


def integrate_unicycle(
    r: np.ndarray, b: np.ndarray, pose: np.ndarray, wheels: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`kinematics.integrate_unicycle` for N robots: the new pose (N, 3) and cos, sin of its yaw (N,)."""
    x, y, yaw = pose[:, 0], pose[:, 1], pose[:, 2]
    wl, wr = wheels[:, 0], wheels[:, 1]
    v = 0.5 * r * (wl + wr)
    w = 0.5 * r / b * (wr - wl)
    small = np.abs(w * dt) < 1e-9
    out = np.empty_like(pose)
    yaw1 = yaw + w * dt
    out[:, 2] = yaw1
    cos1, sin1 = np.cos(yaw1), np.sin(yaw1)
    with np.errstate(divide="ignore", invalid="ignore"):  # w = 0 rows take the series below
        rho = v / w
        out[:, 0] = x + rho * (sin1 - np.sin(yaw))
        out[:, 1] = y - rho * (cos1 - np.cos(yaw))
    if small.any():
        # second-order series of the arc, as the single env
        mid = yaw[small] + 0.5 * w[small] * dt
        vs = v[small]
        out[small, 0] = x[small] + vs * dt * np.cos(mid)
        out[small, 1] = y[small] + vs * dt * np.sin(mid)
    return out, cos1, sin1

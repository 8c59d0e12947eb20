"""Forward kinematics and the position Jacobian of any `ArmDescription` (n joints, standard or modified DH).

Pure numpy and floats, no state. The point is the end-effector point r = o_n + tool z_n in the arm's base frame
0; its Jacobian column k is z_k x (r - o_k), with z_k, o_k the axis and a point of joint k (frame k-1 in the
standard convention, frame k in the modified one), so the Jacobian is analytic, from the same pass as the FK.

One kernel, `_chain`, does the arithmetic for both a single configuration (its inputs are Python floats) and a
batch (its inputs are numpy arrays of shape (N,)): the operators are the same, only cos and sin are taken by
`math` or by numpy before the call. Per link it updates the frame's axes column by column, using the structure
of the DH transforms (Rz(theta) then Rx(alpha) act on two axes at a time) instead of 4 x 4 products: about 30
multiplications per link against 64 for a dense 4 x 4 product (plus building the matrix), and no numpy call per
link (numpy's per-call overhead, ~1 us, dominated the old `dh_frames` loop). Measured with
`python -m mobman_env.robots bench` (best of 5 `timeit` repeats, 2 shared cores at load average ~10, so the
ratios carry over better than the absolute figures): point + Jacobian of the PUMA 43 us with release 0.1's
numpy path (`mobman_env.kinematics.arm_point_and_jacobian`), 74 us with the obvious generic 4 x 4 products +
`np.cross`, 14 us with this kernel (UR5 14 us, Panda 16 us); batched over 1000 configurations 0.4-0.7 us per
configuration.

`link_frames` gives the n + 1 homogeneous frames by plain 4 x 4 products (slow, obvious; for URDF checks).

May import: numpy, the standard library, `mobman_env.robots.description`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mobman_env.robots.description import ArmDescription

__all__ = ["arm_point", "arm_point_and_jacobian", "arm_point_and_jacobian_batch", "link_frames"]


def _chain(desc: ArmDescription, ct: Any, st: Any, n: int) -> tuple[list, list]:
    """The point (3 components) and the 3 rows of the Jacobian (each a list of n entries).

    `ct`, `st`: cos and sin of theta_i, each a sequence of n floats or of n arrays (batch). Frame 0 is the
    identity; the frame is carried as its axes x, y, z and origin p, component by component.
    """
    a, d, ca, sa = desc.dh_constants
    xx, xy, xz = 1.0, 0.0, 0.0
    yx, yy, yz = 0.0, 1.0, 0.0
    zx, zy, zz = 0.0, 0.0, 1.0
    px, py, pz = 0.0, 0.0, 0.0
    axes = []  # (z, o) of each joint: the line it turns about
    if desc.modified:
        for i in range(n):
            c, s, cal, sal = ct[i], st[i], ca[i], sa[i]
            # Rx(alpha) Tx(a): origin along x, then y and z turn about x
            if a[i] != 0.0:
                px, py, pz = px + a[i] * xx, py + a[i] * xy, pz + a[i] * xz
            yx, yy, yz, zx, zy, zz = (
                cal * yx + sal * zx,
                cal * yy + sal * zy,
                cal * yz + sal * zz,
                cal * zx - sal * yx,
                cal * zy - sal * yy,
                cal * zz - sal * yz,
            )
            axes.append((zx, zy, zz, px, py, pz))  # joint i turns about z_i through o_i
            # Rz(theta) Tz(d): x and y turn about z, origin along z
            xx, xy, xz, yx, yy, yz = (
                c * xx + s * yx,
                c * xy + s * yy,
                c * xz + s * yz,
                c * yx - s * xx,
                c * yy - s * xy,
                c * yz - s * xz,
            )
            if d[i] != 0.0:
                px, py, pz = px + d[i] * zx, py + d[i] * zy, pz + d[i] * zz
    else:
        for i in range(n):
            c, s, cal, sal = ct[i], st[i], ca[i], sa[i]
            axes.append((zx, zy, zz, px, py, pz))  # joint i turns about z_{i-1} through o_{i-1}
            # Rz(theta): u = new x, w = new y (before the twist)
            ux, uy, uz = c * xx + s * yx, c * xy + s * yy, c * xz + s * yz
            wx, wy, wz = c * yx - s * xx, c * yy - s * xy, c * yz - s * xz
            # Tz(d) Tx(a): origin along the old z and the new x
            px, py, pz = px + d[i] * zx + a[i] * ux, py + d[i] * zy + a[i] * uy, pz + d[i] * zz + a[i] * uz
            # Rx(alpha): y and z turn about the new x
            xx, xy, xz = ux, uy, uz
            yx, yy, yz, zx, zy, zz = (
                cal * wx + sal * zx,
                cal * wy + sal * zy,
                cal * wz + sal * zz,
                cal * zx - sal * wx,
                cal * zy - sal * wy,
                cal * zz - sal * wz,
            )
    t = desc.tool
    rx, ry, rz = px + t * zx, py + t * zy, pz + t * zz
    j0, j1, j2 = [], [], []
    for ax, ay, az, ox, oy, oz in axes:
        vx, vy, vz = rx - ox, ry - oy, rz - oz
        j0.append(ay * vz - az * vy)
        j1.append(az * vx - ax * vz)
        j2.append(ax * vy - ay * vx)
    return [rx, ry, rz], [j0, j1, j2]


def _trig(desc: ArmDescription, q: Any) -> tuple[list[float], list[float], int]:
    n = desc.n_joints
    if len(q) < n:
        raise ValueError(f"{desc.name} has {n} joints; q must have at least {n} angles (rad), got {len(q)}")
    off = desc.theta_offset
    th = [float(q[i]) + off[i] for i in range(n)]
    return [math.cos(x) for x in th], [math.sin(x) for x in th], n


def arm_point_and_jacobian(desc: ArmDescription, q: Any) -> tuple[np.ndarray, np.ndarray]:
    """The end-effector point in frame 0 (m), shape (3,), and its Jacobian d r / d q, shape (3, n).

    `q`: the n joint angles (rad); extra trailing entries (e.g. wheel angles) are ignored.
    """
    ct, st, n = _trig(desc, q)
    r, J = _chain(desc, ct, st, n)
    return np.array(r), np.array(J)


def arm_point(desc: ArmDescription, q: Any) -> np.ndarray:
    """The end-effector point in frame 0 (m), shape (3,)."""
    return arm_point_and_jacobian(desc, q)[0]


def arm_point_and_jacobian_batch(desc: ArmDescription, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`arm_point_and_jacobian` for N configurations at once: q (N, n) -> points (N, 3), Jacobians (N, 3, n).

    The same kernel as the single call (numpy arrays instead of floats), so row i equals the single call on
    q[i] to rounding (the operations are the same; numpy's and math's cos may differ in the last bit).
    """
    q = np.asarray(q, dtype=float)
    n = desc.n_joints
    if q.ndim != 2 or q.shape[1] < n:
        raise ValueError(f"q must have shape (N, {n}) (N configurations of {desc.name}), got {q.shape}")
    th = q[:, :n] + np.asarray(desc.theta_offset)
    ct, st = np.cos(th).T, np.sin(th).T
    r, J = _chain(desc, ct, st, n)
    points = np.stack([np.broadcast_to(c, (q.shape[0],)) for c in r], axis=1)
    jac = np.stack([np.stack([np.broadcast_to(c, (q.shape[0],)) for c in row], axis=1) for row in J], axis=1)
    return points, jac


def link_frames(desc: ArmDescription, q: Any) -> np.ndarray:
    """The n + 1 homogeneous frames T_0^0 .. T_0^n in the base frame 0, shape (n + 1, 4, 4), by dense 4 x 4
    products of the DH transforms (slow and obvious: for URDF and test checks, not the hot path)."""
    n = desc.n_joints
    frames = np.empty((n + 1, 4, 4))
    frames[0] = np.eye(4)
    for i in range(n):
        th = float(q[i]) + desc.theta_offset[i]
        c, s = math.cos(th), math.sin(th)
        ca, sa = math.cos(desc.alpha[i]), math.sin(desc.alpha[i])
        a, d = desc.a[i], desc.d[i]
        if desc.modified:
            A = np.array([[c, -s, 0.0, a], [s * ca, c * ca, -sa, -sa * d], [s * sa, c * sa, ca, ca * d], [0, 0, 0, 1]])
        else:
            A = np.array([[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0.0, sa, ca, d], [0, 0, 0, 1]])
        frames[i + 1] = frames[i] @ A
    return frames

"""Forward kinematics and the position Jacobian of any `ArmDescription` (n joints, standard or modified DH).

The point is the end-effector point r = o_n + tool z_n in the arm's base frame 0; its Jacobian column k is
z_k x (r - o_k), with z_k, o_k the axis and a point of joint k (frame k-1 in the standard convention, frame k in
the modified one). Both are `mobman_env.engine`'s chain (the env's own numbers): these functions pack the arm into
the engine's rows and call its kernel `arm_points`, for one configuration or a batch.

`link_frames` gives the n + 1 homogeneous frames by plain 4 x 4 products of the DH transforms: the obvious,
independent reference the URDF writer and the tests check the engine against (slow; not a hot path).

May import: numpy, the standard library, `mobman_env.robots.description`, `mobman_env.engine`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mobman_env import engine as E
from mobman_env.robots.description import ArmDescription

__all__ = ["arm_point", "arm_point_and_jacobian", "arm_point_and_jacobian_batch", "link_frames"]


def _rows(desc: ArmDescription) -> tuple[np.ndarray, np.ndarray]:
    arm = np.zeros((1, E.ARM_ROWS, desc.n_actuators))
    prm = np.zeros((1, E.P_LEN))
    E.pack_arm(arm, prm, 0, desc)
    return arm, prm


def arm_point_and_jacobian_batch(desc: ArmDescription, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The end-effector points (N, 3) in frame 0 (m) and their Jacobians d r / d q (N, 3, n) at N configurations
    q (N, >= n) (extra trailing entries, e.g. wheel angles, are ignored)."""
    q = np.asarray(q, dtype=float)
    n = desc.n_joints
    if q.ndim != 2 or q.shape[1] < n:
        raise ValueError(f"q must have shape (N, {n}) (N configurations of {desc.name}), got {q.shape}")
    arm, prm = _rows(desc)
    N = q.shape[0]
    points, jac = np.empty((N, 3)), np.empty((N, 3, n))
    E.arm_points(np.repeat(arm, N, axis=0), np.repeat(prm, N, axis=0), q, points, jac)
    return points, jac


def arm_point_and_jacobian(desc: ArmDescription, q: Any) -> tuple[np.ndarray, np.ndarray]:
    """The end-effector point in frame 0 (m), shape (3,), and its Jacobian d r / d q, shape (3, n).

    `q`: the n joint angles (rad); extra trailing entries (e.g. wheel angles) are ignored.
    """
    n = desc.n_joints
    if len(q) < n:
        raise ValueError(f"{desc.name} has {n} joints; q must have at least {n} angles (rad), got {len(q)}")
    p, J = arm_point_and_jacobian_batch(desc, np.asarray(q, dtype=float)[None, :n])
    return p[0], J[0]


def arm_point(desc: ArmDescription, q: Any) -> np.ndarray:
    """The end-effector point in frame 0 (m), shape (3,)."""
    return arm_point_and_jacobian(desc, q)[0]


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

"""Kinematics of the wheeled mobile manipulator (any arm of `RobotParams`), pure numpy (no PyBullet, no state).

Frames and symbols (the paper's, section II):

* World frame O: z up. The platform pose is (x, y, yaw) of the axle centre P_0 on the ground plane; yaw is the
  heading phi (continuous, not wrapped).
* P_c, where the arm is mounted, lies `mount_offset` (d) ahead of P_0: p_c = P_0 + d [cos phi, sin phi].
* The arm's DH frame 0 sits at (p_c, h) rotated by phi about z; its x axis points along the heading.
* The end-effector point r_a is frame n's origin plus `tool` along z_n (n = `params.n_joints`).

Actuators, in this order everywhere: u = [theta_dot_1..n, wheel_left_dot, wheel_right_dot] (rad/s).

The arm is either DH convention of `mobman_env.robots.description`: standard, A_i = Rz(theta) Tz(d) Tx(a)
Rx(alpha), joint i turning about z_{i-1} through o_{i-1}; or modified (Craig), A_i = Rx(alpha) Tx(a) Rz(theta)
Tz(d), joint i turning about z_i through o_i; theta_i = q_i + theta_offset_i. The numbers are dense 4 x 4
products, the same operations in the same order as release 0.1's PUMA-only code for a standard-DH arm without
offsets (so the PUMA ids keep their results bit for bit); `mobman_env.robots.kinematics` is the faster kernel
of the same maps (equal to 1e-12, tested).

Speed without changing a bit. The kinematic env's results are defined by these products, and numpy's 4 x 4
`matmul` goes through BLAS, whose kernels fuse multiply-adds in their own order (a plain float product differs
in the last bit on 38% of the entries of random 4 x 4 products, measured on OpenBLAS's SkylakeX kernel): so the
chain of products, R f, R J and the env's J u stay numpy calls. Everything around them (the DH transforms'
entries, the cross products, the wheel columns, p_c, r_a) is Python floats doing the same IEEE operations in the
same order as the elementwise numpy they replaced, hence the same bits, without ~40 numpy calls on arrays of 2-8
entries per step. The recorded-episode tests (`tests/test_env_defaults_unchanged.py`) pin the result.

Platform: v = r/2 (w_l + w_r), phi_dot = r/(2b) (w_r - w_l) (eq. (5)).

`paper_jacobian` is the paper's J of eq. (6): r_a_dot = [p_c_dot; 0] + J u, so its wheel columns act only
through the yaw. `whole_body_jacobian` adds the platform's translation: r_a_dot = J_wb u.
"""

from __future__ import annotations

import math

import numpy as np

from mobman_env.params import RobotParams

#: frame 0 of every arm: the identity (copied into each `dh_frames` result, never written)
_EYE4 = np.eye(4)


def _transform_values(params: RobotParams, q: np.ndarray) -> list[float]:
    """The entries of the n link transforms A_i, row by row (16 n floats).

    Every entry is one product (or none) of a cos/sin of theta with a DH constant, taken in Python floats: the
    same IEEE operations, in the same order, as the elementwise numpy expressions they replace (so the same
    bits), without ~20 numpy calls on arrays of 6. cos and sin are numpy's, on the same array as before (numpy's
    and `math`'s may differ in the last bit).
    """
    n = params.n_joints
    th = q[:n] if params.theta_offset is None else q[:n] + params.theta_offset
    ct, st = np.cos(th).tolist(), np.sin(th).tolist()
    a, d, ca, sa = params.dh_floats
    vals: list[float] = []
    if params.arm.modified:  # Rx(alpha) Tx(a) Rz(theta) Tz(d)
        for c, s, ai, di, cai, sai in zip(ct, st, a, d, ca, sa):
            vals += (
                c,
                -s,
                0.0,
                ai,
                s * cai,
                c * cai,
                -sai,
                -sai * di,
                s * sai,
                c * sai,
                cai,
                cai * di,
                0.0,
                0.0,
                0.0,
                1.0,
            )
    else:  # Rz(theta) Tz(d) Tx(a) Rx(alpha)
        for c, s, ai, di, cai, sai in zip(ct, st, a, d, ca, sa):
            vals += (c, -s * cai, s * sai, ai * c, s, c * cai, -c * sai, ai * s, 0.0, sai, cai, di, 0.0, 0.0, 0.0, 1.0)
    return vals


def dh_transforms(params: RobotParams, q: np.ndarray) -> np.ndarray:
    """The n link transforms A_i of the arm's convention at joint angles q (the first n entries), (n, 4, 4)."""
    return np.array(_transform_values(params, q)).reshape(params.n_joints, 4, 4)


def dh_frames(params: RobotParams, q: np.ndarray) -> np.ndarray:
    """The n + 1 homogeneous frames T_0^0 .. T_0^n of the arm in its base frame 0, shape (n + 1, 4, 4).

    The products are numpy's 4 x 4 `matmul` (BLAS): a hand-written float product would round differently
    from the BLAS kernel's fused multiply-adds, and the envs' results are defined by these products.
    """
    A = dh_transforms(params, q)
    n = len(A)
    frames = np.empty((n + 1, 4, 4))
    frames[0] = _EYE4
    for i in range(n):
        np.matmul(frames[i], A[i], out=frames[i + 1])
    return frames


def _point_and_jacobian_floats(params: RobotParams, q: np.ndarray) -> tuple[list[float], list[list[float]]]:
    """f(theta) (3 floats) and the 3 rows of d f / d theta (n floats each) in frame 0, from one pass over the DH
    frames. Column i is z x (p - o) of joint i's axis: frame i-1's (standard DH) or frame i's (modified DH)."""
    frames = dh_frames(params, q).tolist()
    n = len(frames) - 1
    (x0, _, z0, o0), (x1, _, z1, o1), (x2, _, z2, o2), _ = frames[n]
    t = params.tool
    p0, p1, p2 = o0 + t * z0, o1 + t * z1, o2 + t * z2
    j0, j1, j2 = [], [], []
    for F in frames[1:] if params.arm.modified else frames[:-1]:
        (_, _, za, oa), (_, _, zb, ob), (_, _, zc, oc), _ = F
        va, vb, vc = p0 - oa, p1 - ob, p2 - oc
        # the cross product z x v written out (np.cross costs ~10x more for these tiny arrays)
        j0.append(zb * vc - zc * vb)
        j1.append(zc * va - za * vc)
        j2.append(za * vb - zb * va)
    return [p0, p1, p2], [j0, j1, j2]


def arm_point(params: RobotParams, q: np.ndarray) -> np.ndarray:
    """f(theta): the end-effector point in the arm's base frame 0 (m), shape (3,)."""
    T = dh_frames(params, q)[-1]
    return T[:3, 3] + params.tool * T[:3, 2]


def arm_point_and_jacobian(params: RobotParams, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """f(theta) (3,) and d f / d theta (3, n) in frame 0, from one pass over the DH frames.

    Column i is z x (p - o) of joint i's axis: frame i-1's (standard DH) or frame i's (modified DH). A last
    joint that turns about the tool axis has a zero column (the PUMA's joint 6).
    """
    p, J = _point_and_jacobian_floats(params, q)
    return np.array(p), np.array(J)


def arm_jacobian(params: RobotParams, q: np.ndarray) -> np.ndarray:
    """d f / d theta in frame 0, shape (3, n)."""
    return arm_point_and_jacobian(params, q)[1]


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def arm_base_xy(params: RobotParams, base_pose: np.ndarray) -> np.ndarray:
    """p_c = P_0 + d [cos phi, sin phi] (m), shape (2,)."""
    x, y, yaw = base_pose
    return np.array([x + params.mount_offset * math.cos(yaw), y + params.mount_offset * math.sin(yaw)])


def ee_position(params: RobotParams, q_arm: np.ndarray, base_pose: np.ndarray) -> np.ndarray:
    """r_a in the world frame (m) from the n arm angles and the platform pose (x, y, yaw) of P_0."""
    pc = arm_base_xy(params, base_pose)
    g = _rot_z(base_pose[2]) @ arm_point(params, q_arm)
    return np.array([pc[0] + g[0], pc[1] + g[1], params.shoulder_height + g[2]])


def platform_rates(params: RobotParams, wheel_speeds: np.ndarray) -> tuple[float, float]:
    """(v, phi_dot): forward speed of P_0 (m/s) and yaw rate (rad/s) of the unicycle, eq. (5)."""
    wl, wr = float(wheel_speeds[0]), float(wheel_speeds[1])
    r, b = params.wheel_radius, params.half_track
    return 0.5 * r * (wl + wr), 0.5 * r / b * (wr - wl)


def _wheel_maps(params: RobotParams, c: float, s: float) -> tuple[list[float], list[list[float]]]:
    """d(phi_dot)/d(w_l, w_r) (2 floats) and d(p_c_dot)/d(w_l, w_r) (2 x 2 floats) at heading (cos, sin) = (c, s).

    dpc = outer([c, s], dv) + d outer([-s, c], dphi), entry by entry in floats."""
    r, b, d = params.wheel_radius, params.half_track, params.mount_offset
    dphi = [-0.5 * r / b, 0.5 * r / b]
    dv = 0.5 * r
    return dphi, [
        [c * dv + d * (-s * dphi[0]), c * dv + d * (-s * dphi[1])],
        [s * dv + d * (c * dphi[0]), s * dv + d * (c * dphi[1])],
    ]


def _paper_parts_floats(
    params: RobotParams, q_arm: np.ndarray, yaw: float
) -> tuple[np.ndarray, list[list[float]], list[list[float]]]:
    """g = R(phi) f(theta) (3,), the rows of the paper's J (3 x (n + 2) floats) and of d p_c_dot / d u (2 x (n + 2)
    floats), from one FK pass. The rotations are numpy products (BLAS, as the frames); the rest is floats."""
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    f, J_arm = _point_and_jacobian_floats(params, q_arm)
    g = R @ np.array(f)
    RJ = (R @ np.array(J_arm)).tolist()
    dphi, dpc = _wheel_maps(params, c, s)
    g0, g1 = float(g[0]), float(g[1])
    n = len(J_arm[0])
    # wheel columns: d g / d phi * d phi_dot / d w (the 0.0 * keeps numpy's signed zeros of np.outer)
    J = [
        RJ[0] + [-g1 * dphi[0], -g1 * dphi[1]],
        RJ[1] + [g0 * dphi[0], g0 * dphi[1]],
        RJ[2] + [0.0 * dphi[0], 0.0 * dphi[1]],
    ]
    zeros = [0.0] * n
    return g, J, [zeros + dpc[0], zeros + dpc[1]]


def _paper_parts(params: RobotParams, q_arm: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """g = R(phi) f(theta) (3,), the paper's J (3, n + 2) and d p_c_dot / d u (2, n + 2), from one FK pass."""
    g, J, J_pc = _paper_parts_floats(params, q_arm, yaw)
    return g, np.array(J), np.array(J_pc)


def paper_jacobian(params: RobotParams, q_arm: np.ndarray, yaw: float) -> np.ndarray:
    """The paper's J of eq. (6), shape (3, n + 2): r_a_dot = [p_c_dot; 0] + J u.

    Arm columns: R(phi) df/dtheta. Wheel columns: d g / d phi * d phi_dot / d w, with g = R(phi) f(theta).
    """
    return _paper_parts(params, q_arm, yaw)[1]


def arm_base_jacobian(params: RobotParams, yaw: float) -> np.ndarray:
    """d p_c_dot / d u, shape (2, n + 2): only the wheel columns are non-zero."""
    n = params.n_joints
    J = np.zeros((2, n + 2))
    J[:, n:] = _wheel_maps(params, math.cos(yaw), math.sin(yaw))[1]
    return J


def whole_body_jacobian(params: RobotParams, q_arm: np.ndarray, yaw: float) -> np.ndarray:
    """The whole-body Jacobian, shape (3, n + 2): r_a_dot = J_wb u (platform translation included)."""
    _, J, J_pc = _paper_parts(params, q_arm, yaw)
    J[:2] += J_pc
    return J


def integrate_unicycle(params: RobotParams, base_pose: np.ndarray, wheel_speeds: np.ndarray, dt: float) -> np.ndarray:
    """Exact no-slip unicycle motion of P_0 over `dt` with constant wheel speeds; returns (x, y, yaw)."""
    x, y, yaw = base_pose.tolist() if isinstance(base_pose, np.ndarray) else (float(v) for v in base_pose)
    v, w = platform_rates(params, wheel_speeds)
    if abs(w * dt) < 1e-9:
        # second-order series of the arc (exact to float precision for such small turns)
        mid = yaw + 0.5 * w * dt
        return np.array([x + v * dt * math.cos(mid), y + v * dt * math.sin(mid), yaw + w * dt])
    yaw1 = yaw + w * dt
    rho = v / w
    return np.array([x + rho * (math.sin(yaw1) - math.sin(yaw)), y - rho * (math.cos(yaw1) - math.cos(yaw)), yaw1])


def ee_jacobian_and_arm_base(
    params: RobotParams, q_arm: np.ndarray, base_pose: np.ndarray
) -> tuple[list[float], np.ndarray, np.ndarray, list[float]]:
    """r_a (3 floats), the whole-body Jacobian (3, n + 2), d p_c_dot / d u (2, n + 2) and p_c (2 floats) from one
    FK pass (the hot path of the kinematic simulation: the points stay floats, the Jacobians are arrays for the
    BLAS products J u)."""
    x, y, yaw = base_pose.tolist()
    g, J, J_pc = _paper_parts_floats(params, q_arm, yaw)
    # J[:2] += J_pc entry by entry (x + 0.0 as numpy adds it: -0.0 becomes 0.0)
    J[0] = [u + v for u, v in zip(J[0], J_pc[0])]
    J[1] = [u + v for u, v in zip(J[1], J_pc[1])]
    d = params.mount_offset
    g0, g1, g2 = g.tolist()
    pc0, pc1 = x + d * math.cos(yaw), y + d * math.sin(yaw)
    return [pc0 + g0, pc1 + g1, params.shoulder_height + g2], np.array(J), np.array(J_pc), [pc0, pc1]


def ee_and_jacobian(
    params: RobotParams, q_arm: np.ndarray, base_pose: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """r_a (3,), the whole-body Jacobian (3, n + 2) and d p_c_dot / d u (2, n + 2) from one FK pass."""
    ee, J, J_pc, _ = ee_jacobian_and_arm_base(params, q_arm, base_pose)
    return np.array(ee), J, J_pc

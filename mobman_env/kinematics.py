"""Kinematics of one wheeled mobile manipulator (any arm of `RobotParams`): the Python face of `mobman_env.engine`.

Every function here packs the robot into the engine's rows and calls its kernels, so the numbers are the env's own
(the same chain, the same operations: a controller or a metric that asks for a Jacobian here sees what the env
steps with). Nothing here computes kinematics of its own.

Frames and symbols (the paper's, section II):

* World frame O: z up. The platform pose is (x, y, yaw) of the axle centre P_0 on the ground plane; yaw is the
  heading phi (continuous, not wrapped).
* P_c, where the arm is mounted, lies `mount_offset` (d) ahead of P_0: p_c = P_0 + d [cos phi, sin phi].
* The arm's DH frame 0 sits at (p_c, h) rotated by phi about z; its x axis points along the heading.
* The end-effector point r_a is frame n's origin plus `tool` along z_n (n = `params.n_joints`).

Actuators, in this order everywhere: u = [theta_dot_1..n, wheel_left_dot, wheel_right_dot] (rad/s).
Platform: v = r/2 (w_l + w_r), phi_dot = r/(2b) (w_r - w_l) (eq. (5)).

`paper_jacobian` is the paper's J of eq. (6): r_a_dot = [p_c_dot; 0] + J u, so its wheel columns act only
through the yaw. `whole_body_jacobian` adds the platform's translation: r_a_dot = J_wb u.
"""

from __future__ import annotations

import numpy as np

from mobman_env import engine as E
from mobman_env.params import RobotParams

_ROW0 = np.zeros(1, dtype=np.intp)


def _rows(params: RobotParams) -> tuple[np.ndarray, np.ndarray]:
    return params.engine_rows


def arm_point_and_jacobian(params: RobotParams, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """f(theta) (3,) and d f / d theta (3, n) in the arm's frame 0, at the n arm angles q (extra entries, e.g.
    the wheels, are ignored). A last joint that turns about the tool axis has a zero column (the PUMA's joint 6)."""
    arm, prm = _rows(params)
    p = np.empty((1, 3))
    J = np.empty((1, 3, params.n_joints))
    E.arm_points(arm, prm, np.asarray(q, dtype=float).reshape(1, -1), p, J)
    return p[0], J[0]


def arm_point(params: RobotParams, q: np.ndarray) -> np.ndarray:
    """f(theta): the end-effector point in the arm's base frame 0 (m), shape (3,)."""
    return arm_point_and_jacobian(params, q)[0]


def arm_jacobian(params: RobotParams, q: np.ndarray) -> np.ndarray:
    """d f / d theta in frame 0, shape (3, n)."""
    return arm_point_and_jacobian(params, q)[1]


def ee_and_arm_base(params: RobotParams, q_arm: np.ndarray, base_pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """r_a (3,) and p_c (2,) in the world frame (m) from the n arm angles and the platform pose (x, y, yaw) of P_0."""
    arm, prm = _rows(params)
    ee, pc = np.empty((1, 3)), np.empty((1, 2))
    E.ee_points(arm, prm, np.asarray(q_arm, dtype=float).reshape(1, -1), np.asarray(base_pose, float)[None], ee, pc)
    return ee[0], pc[0]


def ee_position(params: RobotParams, q_arm: np.ndarray, base_pose: np.ndarray) -> np.ndarray:
    """r_a in the world frame (m) from the n arm angles and the platform pose (x, y, yaw) of P_0."""
    return ee_and_arm_base(params, q_arm, base_pose)[0]


def arm_base_xy(params: RobotParams, base_pose: np.ndarray) -> np.ndarray:
    """p_c = P_0 + d [cos phi, sin phi] (m), shape (2,)."""
    return ee_and_arm_base(params, np.zeros(params.n_joints), base_pose)[1]


def jacobian(params: RobotParams, q_arm: np.ndarray, yaw: float, full: bool) -> np.ndarray:
    """The whole-body Jacobian (full) or the paper's J, shape (3, n + 2), at the arm angles and the heading."""
    arm, prm = _rows(params)
    out = np.empty((1, 3, params.n_actuators))
    E.jacobians(arm, prm, _ROW0, np.asarray(q_arm, dtype=float).reshape(1, -1), np.array([float(yaw)]), full, out)
    return out[0]


def paper_jacobian(params: RobotParams, q_arm: np.ndarray, yaw: float) -> np.ndarray:
    """The paper's J of eq. (6), shape (3, n + 2): r_a_dot = [p_c_dot; 0] + J u.

    Arm columns: R(phi) df/dtheta. Wheel columns: d g / d phi * d phi_dot / d w, with g = R(phi) f(theta).
    """
    return jacobian(params, q_arm, yaw, False)


def whole_body_jacobian(params: RobotParams, q_arm: np.ndarray, yaw: float) -> np.ndarray:
    """The whole-body Jacobian, shape (3, n + 2): r_a_dot = J_wb u (platform translation included)."""
    return jacobian(params, q_arm, yaw, True)


def arm_base_jacobian(params: RobotParams, yaw: float) -> np.ndarray:
    """d p_c_dot / d u, shape (2, n + 2): only the wheel columns are non-zero."""
    arm, prm = _rows(params)
    out = np.zeros((1, 2, params.n_actuators))
    E.arm_base_jacobians(arm, prm, np.array([float(yaw)]), out)
    return out[0]


def platform_rates(params: RobotParams, wheel_speeds: np.ndarray) -> tuple[float, float]:
    """(v, phi_dot): forward speed of P_0 (m/s) and yaw rate (rad/s) of the unicycle, eq. (5)."""
    wl, wr = float(wheel_speeds[0]), float(wheel_speeds[1])
    r, b = params.wheel_radius, params.half_track
    return 0.5 * r * (wl + wr), 0.5 * r / b * (wr - wl)


def integrate_unicycle(params: RobotParams, base_pose: np.ndarray, wheel_speeds: np.ndarray, dt: float) -> np.ndarray:
    """Exact no-slip unicycle motion of P_0 over `dt` with constant wheel speeds; returns (x, y, yaw). The
    engine's step: the arc of the wheels' angle changes w dt."""
    x, y, yaw = (float(v) for v in base_pose)
    dl, dr = float(wheel_speeds[0]) * dt, float(wheel_speeds[1]) * dt
    r, b = params.wheel_radius, params.half_track
    return np.array(E.arc(x, y, yaw, 0.5 * r * (dl + dr), 0.5 * r / b * (dr - dl)))

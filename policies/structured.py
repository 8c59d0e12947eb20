"""The structured Jacobian estimator of `nnbc-plus` (`formulation="structured"`): the whole-body Jacobian of an arm
on a planar platform, composed from two estimates that slip cannot corrupt.

Why
---
The whole-body estimate learns y = J x with y the measured end-effector velocity. When the platform slips (its
wheels turn, the ground does not follow: on the 5 s physics circle 30-50 mm/s for about ten steps, see
`docs/results/nnbc-plus-v2/trace-circle5s.md`) y = J x does not hold, the filter learns the slip into every
column of J_hat, and the commands it then issues slip more. A known-model law (`qp-oracle`) slips as much and
tracks, because its J is not learnt.

What it estimates (numpy on 3 x (n - 2) and 3 x 2 arrays)
---------------------------------------------------------
The end-effector velocity of an arm on a platform moving in the plane is

    r_a_dot = [p_c_dot; 0] + omega z x (r_a - p_c) + R(phi) A(q) x_arm

with p_c the arm mount (`arm_base_pos`, its velocity `arm_base_vel`), phi the heading (`base_yaw`), omega its
rate and A(q) the arm's Jacobian in the platform's frame. Everything but A and the wheels' effect is measured:

1. **The arm**, A (3 x (n - 2)): a Kalman filter on [A | A_dot] (the same filter and gains as the whole-body
   estimate, `KalmanEstimator`) learns y_arm = R(-phi) (y - [p_c_dot; 0] - omega z x (r_a - p_c)) = A x_arm,
   with omega the heading's finite difference over the last step. Slip moves p_c and phi, both measured, so it
   never reaches A.
2. **The wheels**, M (3 x 2): the map from the wheel speeds to the platform's velocity in its own frame,
   [R(-phi) p_c_dot; omega] = M x_wheels, is a constant of the platform (no slip): a Kalman filter with a small
   process noise (`q_platform`) and a measurement noise of at least `platform_std` learns it. Slip is a
   short-lived error of a long average.

The control law's Jacobian is then J = [R(phi) A, [R(phi) M_p; 0] + z x (r_a - p_c) M_omega] (M_p the first
two rows of M, M_omega the third), and its rate J_dot the rate of A plus the heading's rotation of every
column. Nothing about the robot's geometry is assumed: only that it is an arm on a platform that moves in the
plane, whose mount position, velocity and heading are measured (the observations every mobman robot has).
"""

from __future__ import annotations

import math

import numpy as np

from policies.estimators import KalmanEstimator


class StructuredEstimator:
    """The whole-body J of an arm on a platform, from an arm Jacobian in the platform's frame and a learnt
    wheel map (see the module docstring). n actuators: n - 2 arm joints, then the left and right wheel.

    `observe(obs)` must be called at every control step before `update` (and during the probe, so the wheel
    map learns from it); `arm_kw` are the `KalmanEstimator` options of the arm's filter."""

    def __init__(self, n: int, dt: float, *, q_platform: float, platform_std: float, arm_kw: dict):
        self._n = n
        self._na = n - 2
        self._dt = dt
        self.arm = KalmanEstimator(self._na, dt, **arm_kw)
        # the wheel map: a plain Kalman filter (no innovation clip, R fixed at platform_std^2: its first
        # innovations are large, and the clip's running RMS would throttle them)
        plat_kw = dict(
            arm_kw,
            q_jacobian=q_platform,
            q_rate=0.0,
            p0_rate=0.0,
            meas_std=platform_std,
            innov_clip=0.0,
            noise_rate=0.0,
        )
        plat_kw.pop("sym_phase", None)
        self.platform = KalmanEstimator(2, dt, **plat_kw)
        self._J = np.zeros((3, n))
        self._Jdot = np.zeros((3, n))
        self._P = np.zeros((2 * n, 2 * n))
        self.reset()

    def reset(self) -> None:
        self.arm.reset()
        self.platform.reset()
        self._J[:] = 0.0
        self._Jdot[:] = 0.0
        self._yaw: float | None = None
        self.omega = 0.0  # rad/s, the heading's rate over the last step
        self._cs = (1.0, 0.0)
        self._lever = np.zeros(2)  # r_a - p_c (x, y), m
        self._lever_rate = np.zeros(2)
        self._base_vel = np.zeros(2)

    @property
    def J(self) -> np.ndarray:
        return self._J

    @property
    def Jdot(self) -> np.ndarray:
        return self._Jdot

    @property
    def P(self) -> np.ndarray:
        """2n x 2n: the arm filter's covariance of A's entries in the arm block and the wheel map's in the wheel
        block (per row; `info_dither` reads the J part)."""
        na, n = self._na, self._n
        P = self._P
        P[:na, :na] = self.arm.P[:na, :na]
        P[na:n, na:n] = self.platform.P[:2, :2]
        return P

    def observe(self, obs: dict) -> None:
        """This step's platform measurements: heading and its rate, the lever r_a - p_c, the wheel map's update
        (when the wheels turn), and J, J_dot composed for the control law."""
        yaw = float(obs["base_yaw"][0])
        if self._yaw is not None:
            self.omega = (yaw - self._yaw) / self._dt
        self._yaw = yaw
        c, s = math.cos(yaw), math.sin(yaw)
        self._cs = (c, s)
        ee, pc = obs["ee_pos"], obs["arm_base_pos"]
        self._lever = np.array([ee[0] - pc[0], ee[1] - pc[1]])
        v, pv = obs["ee_vel"], obs["arm_base_vel"]
        self._base_vel = np.array([pv[0], pv[1]])
        self._lever_rate = np.array([v[0] - pv[0], v[1] - pv[1]])
        wheels = obs["joint_vel"][self._na :]
        if float(wheels.dot(wheels)) > 0.0:
            body = np.array([c * pv[0] + s * pv[1], c * pv[1] - s * pv[0], self.omega])
            self.platform.update(wheels, body)
        self._compose()

    def init(self, J0: np.ndarray) -> None:
        """A(0) from the probe's whole-body fit: its arm columns in the platform's frame (A_dot(0) = 0)."""
        c, s = self._cs
        na = self._na
        self.arm.init(np.vstack([c * J0[0, :na] + s * J0[1, :na], c * J0[1, :na] - s * J0[0, :na], J0[2, :na]]))
        self._compose()

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        """Learn A from the arm's share of the measured end-effector velocity y (x: all n actuator speeds)."""
        c, s = self._cs
        w = self.omega
        lx, ly = self._lever
        bx, by = self._base_vel
        a0, a1 = y[0] - bx + w * ly, y[1] - by - w * lx
        self.arm.update(x[: self._na], np.array([c * a0 + s * a1, c * a1 - s * a0, y[2]]))
        self._compose()

    def _compose(self) -> None:
        """J and J_dot (world frame) from A, A_dot, M and this step's heading, rate and lever."""
        c, s = self._cs
        na = self._na
        w = self.omega
        A, Ad, M = self.arm.J, self.arm.Jdot, self.platform.J
        J, Jd = self._J, self._Jdot
        J[0, :na] = c * A[0] - s * A[1]
        J[1, :na] = s * A[0] + c * A[1]
        J[2, :na] = A[2]
        lx, ly = self._lever
        J[0, na:] = c * M[0] - s * M[1] - ly * M[2]
        J[1, na:] = s * M[0] + c * M[1] + lx * M[2]
        J[2, na:] = 0.0
        # the rate: A's, plus the heading turning every column (d/dt R = omega z x R), plus the lever's motion
        Jd[0, :na] = c * Ad[0] - s * Ad[1] - w * J[1, :na]
        Jd[1, :na] = s * Ad[0] + c * Ad[1] + w * J[0, :na]
        Jd[2, :na] = Ad[2]
        rx, ry = self._lever_rate
        Jd[0, na:] = -w * (s * M[0] + c * M[1]) - ry * M[2]
        Jd[1, na:] = w * (c * M[0] - s * M[1]) + rx * M[2]
        Jd[2, na:] = 0.0

"""The structured Jacobian estimator of `nnbc-plus` (`formulation="structured"`): the whole-body Jacobian of an arm
on a planar platform, composed from two estimates that slip cannot corrupt.

Why
---
The whole-body estimate learns y = J x with y the measured end-effector velocity. When the platform slips (its
wheels turn, the ground does not follow: on the 5 s physics circle 10-36 mm/s over steps 325-340 of development
seed 0, `docs/results/nnbc-plus-v2/trace-circle5s.md`) y = J x does not hold, the filter learns the slip into
every column of J_hat, and the commands it then issues slip more. A known-model law (`qp-oracle`) slips as much
(15-61 mm/s, `trace-circle5s-qp-oracle.md`) and tracks, because its J is not learnt.

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


def rotate_z(A: np.ndarray, cs: float, sn: float) -> np.ndarray:
    """A (3 x n) with its first two rows rotated about z by the angle whose cosine and sine are cs, sn (a copy)."""
    out = A.copy()
    out[0] = cs * A[0] - sn * A[1]
    out[1] = sn * A[0] + cs * A[1]
    return out


class WheelMap:
    """M (3 x 2): a Kalman filter on the constant map from the two wheel speeds to the platform's velocity in its
    own frame (forward, sideways, yaw rate), in plain floats: the three rows share one 2 x 2 covariance P;
    random-walk process noise q per entry and step, measurement noise r (fixed)."""

    def __init__(self, q: float, r: float, p0: float):
        self._q, self._r, self._p0 = q, r, p0
        self.reset()

    def reset(self) -> None:
        self.rows = [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]
        self.P = [[self._p0, 0.0], [0.0, self._p0]]

    def update(self, h0: float, h1: float, z: tuple[float, float, float]) -> None:
        (a, b), (_, d) = self.P
        a, d = a + self._q, d + self._q
        p0, p1 = a * h0 + b * h1, b * h0 + d * h1  # P h
        s = h0 * p0 + h1 * p1 + self._r
        k0, k1 = p0 / s, p1 / s
        for row, zi in zip(self.rows, z):
            e = zi - (row[0] * h0 + row[1] * h1)
            row[0] += k0 * e
            row[1] += k1 * e
        b = b - k0 * p1
        self.P = [[a - k0 * p0, b], [b, d - k1 * p1]]

    @property
    def M(self) -> np.ndarray:
        return np.array(self.rows)


class StructuredEstimator:
    """The whole-body J of an arm on a platform, from an arm Jacobian in the platform's frame and a learnt
    wheel map (see the module docstring). n actuators: n - 2 arm joints, then the left and right wheel.

    `observe(obs)` must be called at every control step before `update` (and during the probe, so the wheel
    map learns from it); `arm_kw` are the `KalmanEstimator` options of the arm's filter. J and J_dot are
    composed when read."""

    def __init__(
        self, n: int, dt: float, *, q_platform: float, platform_std: float, heading_filter: float, arm_kw: dict
    ):
        self._heading_filter = heading_filter
        self._n = n
        self._na = n - 2
        self._dt = dt
        self.arm = KalmanEstimator(self._na, dt, **arm_kw)
        # the wheel map: no innovation clip and R fixed at platform_std^2 (its first innovations are large, and
        # a clip's running RMS would throttle them)
        self.platform = WheelMap(q_platform, platform_std**2, arm_kw["p0_jacobian"])
        self._P = np.zeros((2 * n, 2 * n))
        self.reset()

    def reset(self) -> None:
        self.arm.reset()
        self.platform.reset()
        self._yaw: float | None = None  # the heading in use (filtered), rad
        self._yaw_measured = 0.0
        self.omega = 0.0  # rad/s, the heading's rate over the last step
        self._cs = (1.0, 0.0)
        self._lever = (0.0, 0.0)  # r_a - p_c (x, y), m
        self._lever_rate = (0.0, 0.0)
        self._base_vel = (0.0, 0.0)
        self._dirty = True
        self._J = np.zeros((3, self._n))
        self._Jdot = np.zeros((3, self._n))

    @property
    def J(self) -> np.ndarray:
        if self._dirty:
            self._compose()
        return self._J

    @property
    def Jdot(self) -> np.ndarray:
        if self._dirty:
            self._compose()
        return self._Jdot

    @property
    def P(self) -> np.ndarray:
        """2n x 2n: the arm filter's covariance of A's entries in the arm block and the wheel map's in the wheel
        block (per row; every other entry is zero)."""
        na, n = self._na, self._n
        P = self._P
        P[:na, :na] = self.arm.P[:na, :na]
        P[na:n, na:n] = self.platform.P
        return P

    def observe(self, obs: dict) -> None:
        """This step's platform measurements: heading and its rate, the lever r_a - p_c, and the wheel map's
        update (when the wheels turn)."""
        measured = float(obs["base_yaw"][0])
        w0, w1 = obs["joint_vel"][self._na :].tolist()
        yaw = measured
        omega_measured = 0.0  # the measured heading's finite difference (what the wheel map learns from)
        if self._yaw is not None:
            omega_measured = (measured - self._yaw_measured) / self._dt
            a = self._heading_filter
            if a < 1.0:  # the wheel map's rate, corrected towards the measured heading
                m0, m1 = self.platform.rows[2]
                predicted = self._yaw + self._dt * (m0 * w0 + m1 * w1)
                yaw = predicted + a * math.remainder(measured - predicted, 2.0 * math.pi)
            self.omega = (yaw - self._yaw) / self._dt
        self._yaw_measured = measured
        self._yaw = yaw
        c, s = math.cos(yaw), math.sin(yaw)
        self._cs = (c, s)
        e0, e1, _ = obs["ee_pos"].tolist()
        p0, p1 = obs["arm_base_pos"].tolist()
        v0, v1, _ = obs["ee_vel"].tolist()
        b0, b1 = obs["arm_base_vel"].tolist()
        self._lever = (e0 - p0, e1 - p1)
        self._base_vel = (b0, b1)
        self._lever_rate = (v0 - b0, v1 - b1)
        if w0 != 0.0 or w1 != 0.0:
            self.platform.update(w0, w1, (c * b0 + s * b1, c * b1 - s * b0, omega_measured))
        self._dirty = True

    def init(self, J0: np.ndarray) -> None:
        """A(0) from the probe's whole-body fit: its arm columns in the platform's frame (A_dot(0) = 0)."""
        c, s = self._cs
        self.arm.init(rotate_z(J0[:, : self._na], c, -s))
        self._dirty = True

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        """Learn A from the arm's share of the measured end-effector velocity y (x: all n actuator speeds)."""
        c, s = self._cs
        w = self.omega
        lx, ly = self._lever
        bx, by = self._base_vel
        y0, y1, y2 = y.tolist()
        a0, a1 = y0 - bx + w * ly, y1 - by - w * lx
        self.arm.update(x[: self._na], np.array([c * a0 + s * a1, c * a1 - s * a0, y2]))
        self._dirty = True

    def _compose(self) -> None:
        """J and J_dot (world frame) from A, A_dot, M and this step's heading, rate and lever."""
        c, s = self._cs
        w = self.omega
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        A = self.arm.J
        Ja = R.dot(A)
        (m0, n0), (m1, n1), (m2, n2) = self.platform.rows
        lx, ly = self._lever
        rx, ry = self._lever_rate
        f0, f1 = c * m0 - s * m1, c * n0 - s * n1  # R M_p, first row
        g0, g1 = s * m0 + c * m1, s * n0 + c * n1  # second row
        self._J = np.concatenate(
            (Ja, np.array([[f0 - ly * m2, f1 - ly * n2], [g0 + lx * m2, g1 + lx * n2], [0.0, 0.0]])), axis=1
        )
        # the rate: A's turned by R, plus the heading turning every column (d/dt R = omega z x R), plus the
        # lever's motion (d/dt (z x L) = z x L_dot)
        turn = np.array([[0.0, -w, 0.0], [w, 0.0, 0.0], [0.0, 0.0, 0.0]])
        Jda = R.dot(self.arm.Jdot) + turn.dot(Ja)
        Jdw = np.array([[-w * g0 - ry * m2, -w * g1 - ry * n2], [w * f0 + rx * m2, w * f1 + rx * n2], [0.0, 0.0]])
        self._Jdot = np.concatenate((Jda, Jdw), axis=1)
        self._dirty = False

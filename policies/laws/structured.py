"""The structured Jacobian estimator of `nnbc-plus` (`formulation="structured"`): the whole-body Jacobian of an arm
on a planar platform, composed from two estimates that slip cannot corrupt.

Why
---
The whole-body estimate learns y = J x with y the measured end-effector velocity. When the platform slips (its
wheels turn, the ground does not follow: on the 5 s physics circle 10-36 mm/s over steps 325-340 of development
seed 0, `docs/results/nnbc-plus-v2/trace-circle5s.md`) y = J x does not hold, the filter learns the slip into
every column of J_hat, and the commands it then issues slip more. A known-model law (`qp-oracle`) slips as much
(15-61 mm/s, `trace-circle5s-qp-oracle.md`) and tracks, because its J is not learnt.

What it estimates
-----------------
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


The arithmetic lives in `policies.kernels.model_free` (`est_observe`, the structured branch of `est_update`,
`_compose`: scalar numba code); `StructuredEstimator` and `WheelMap` (`policies.laws.estimators`) are its Python face,
re-exported here.
"""

from __future__ import annotations

from policies.laws.estimators import StructuredEstimator, WheelMap

__all__ = ["StructuredEstimator", "WheelMap"]

"""The named arms: PUMA 560, UR5 and Franka Panda, every number with its provenance and unit.

Sources (the DH numbers and limits are copied, not re-derived):

* PUMA 560: exactly today's `mobman_env.params.RobotParams` (Corke & Armstrong-Helouvry 1994 via the Robotics
  Toolbox `Puma560`; see that module), so that the PUMA ids can keep their behaviour bit for bit. A test compares
  every field.
* UR5: roboticstoolbox-python `src/roboticstoolbox/models/DH/UR5.py` (commit a9ed8d4, 2026-06-16): standard DH
  a, d, alpha, link masses and centres of mass (Universal Robots' "Parameters for calculations of kinematics and
  dynamics"; the file says "no inertia available"). `DH.UR5` has no joint or speed limits; we take them, and the
  torque limits, from the UR5 description shipped in the same repository,
  `rtb-data/rtbdata/xacro/ur_description/urdf/ur5.urdf.xacro` (ROS-Industrial `ur_description`, the variant
  without `joint_limited`): +-2 pi on every joint except the elbow (+-pi), 3.15 rad/s on joints 1-3 and 3.2
  rad/s on 4-6, 150 N m on joints 1-3 and 28 N m on 4-6.
* Panda: roboticstoolbox-python `src/roboticstoolbox/models/DH/Panda.py` (same commit): modified DH a, d, alpha,
  the 107 mm flange as d7, joint limits `qlim`, the 103 mm hand offset (`tool = transl(0, 0, 0.103) @
  trotz(-pi/4)`; the rotation does not move the point), link masses and inertia tensors (`I` in RTB's order Ixx,
  Iyy, Izz, Ixy, Iyz, Ixz), which are those identified by Gaz, Cognetti, Oliva, Robuffo Giordano and De Luca,
  "Dynamic identification of the Franka Emika Panda robot with retrieval of feasible parameters using
  penalty-based optimization", IEEE RA-L 4(4), 2019. `DH.Panda` has no centres of mass (they are Gaz et al.'s,
  as copied into RTB-MATLAB's `mdl_panda.m`, which sets link 1's z to 0: with joint 1 vertical it is not
  identifiable) and no speed limits (2.175 rad/s on joints 1-4, 2.61 rad/s on 5-7) or torque limits (87 N m on
  joints 1-4, 12 N m on 5-7): those are from `rtb-data/rtbdata/xacro/franka_description/robots/panda_arm.xacro`,
  the values of Franka's control-parameters page that `DH.Panda` cites.

Mount (ours, for every arm): DH frame 0 sits `mount_offset` = 0.1 m ahead of the axle centre like the PUMA's;
`base_height` puts it on the platform (the PUMA's 0.6 m includes its pedestal, d1 = 0 there).

May import: the standard library, `mobman_env.robots.description`.
"""

from __future__ import annotations

import math

from mobman_env.robots.description import ArmDescription, rod_inertia, standard_segment

__all__ = ["PANDA", "PUMA560", "ROBOTS", "UR5"]

DEG = math.pi / 180.0
PI = math.pi

#: PUMA 560: today's `RobotParams.nominal()` arm, number for number (the test checks each field).
PUMA560 = ArmDescription(
    name="puma560",
    convention="standard",
    # standard DH (Corke & Armstrong-Helouvry 1994 / RTB Puma560); d1 = 0: the pedestal is in base_height
    a=(0.0, 0.4318, 0.0203, 0.0, 0.0, 0.0),
    alpha=(PI / 2, 0.0, -PI / 2, PI / 2, -PI / 2, 0.0),
    d=(0.0, 0.0, 0.15005, 0.4318, 0.0, 0.0),
    theta_offset=(0.0,) * 6,
    # RTB Puma560, from Wang & Chen 1991
    joint_lower=(-160 * DEG, -45 * DEG, -225 * DEG, -110 * DEG, -100 * DEG, -266 * DEG),
    joint_upper=(160 * DEG, 225 * DEG, 45 * DEG, 170 * DEG, 100 * DEG, 266 * DEG),
    speed_limit=(3.0, 3.0, 3.0, 5.0, 5.0, 5.0),  # rad/s, ours (as RobotParams.arm_speed_limit)
    torque_limit=(300.0, 400.0, 150.0, 30.0, 30.0, 10.0),  # N m, ours: ~3x the worst static gravity load
    # links 2-6: Corke & Armstrong-Helouvry; link 1: none published, ours 5 kg on its axis (see RobotParams)
    masses=(5.0, 17.4, 4.8, 0.82, 0.34, 0.09),
    coms=(
        (0.0, 0.0, 0.0),
        (-0.3638, 0.006, 0.2275),
        (-0.0203, -0.0141, 0.070),
        (0.0, 0.019, 0.0),
        (0.0, 0.0, 0.0),
        (0.0, 0.0, 0.032),
    ),
    # principal moments on the DH frame axes (same table; link 1: 0.35 on all axes, ours; link 3: Izz raised
    # from the published 0.0125 to 0.020 for the triangle inequality, as in RobotParams)
    inertias=(
        (0.35, 0.35, 0.35, 0.0, 0.0, 0.0),
        (0.13, 0.524, 0.539, 0.0, 0.0, 0.0),
        (0.066, 0.086, 0.020, 0.0, 0.0, 0.0),
        (1.8e-3, 1.3e-3, 1.8e-3, 0.0, 0.0, 0.0),
        (0.3e-3, 0.4e-3, 0.3e-3, 0.0, 0.0, 0.0),
        (0.15e-3, 0.15e-3, 0.04e-3, 0.0, 0.0, 0.0),
    ),
    # ours: without a tool the wrist centre is the point and joints 4-6 cannot move it
    tool=0.2,
    base_height=0.6,  # m, RobotParams.shoulder_height (platform + pedestal)
    mount_offset=0.1,  # m, RobotParams.mount_offset
)

# UR5 link masses (RTB DH.UR5, from Universal Robots), kg
_UR5_MASSES = (3.7, 8.393, 2.33, 1.219, 1.219, 0.1897)
# UR5 inertias: none published by Universal Robots (RTB: "no inertia available"). Ours: each link a solid
# cylinder with the radius and length `ur_description` uses for it (ur5.urdf.xacro: radius 0.06 m, lengths
# 0.15, 0.56, 0.39225, 0.12, 0.12 m; wrist 3: radius 0.0375 m, length 0.0345 m), its axis along the link's DH
# segment (frame i-1's origin to frame i's, `standard_segment`): y1, x2, x3, y4, -y5, z6.
_UR5_A = (0.0, -0.425, -0.39225, 0.0, 0.0, 0.0)
_UR5_ALPHA = (PI / 2, 0.0, 0.0, PI / 2, -PI / 2, 0.0)
_UR5_D = (0.089459, 0.0, 0.0, 0.10915, 0.09465, 0.0823)
_UR5_CYLINDERS = ((0.06, 0.15), (0.06, 0.56), (0.06, 0.39225), (0.06, 0.12), (0.06, 0.12), (0.0375, 0.0345))

#: Universal Robots UR5 (CB3), standard DH, 6 joints.
UR5 = ArmDescription(
    name="ur5",
    convention="standard",
    # RTB DH.UR5
    a=_UR5_A,
    alpha=_UR5_ALPHA,
    d=_UR5_D,
    theta_offset=(0.0,) * 6,
    # ur_description (rtb-data) without joint_limited
    joint_lower=(-2 * PI, -2 * PI, -PI, -2 * PI, -2 * PI, -2 * PI),
    joint_upper=(2 * PI, 2 * PI, PI, 2 * PI, 2 * PI, 2 * PI),
    speed_limit=(3.15, 3.15, 3.15, 3.2, 3.2, 3.2),  # rad/s, ur_description
    torque_limit=(150.0, 150.0, 150.0, 28.0, 28.0, 28.0),  # N m, ur_description
    masses=_UR5_MASSES,
    # RTB DH.UR5 (Universal Robots), in DH frame i, m
    coms=(
        (0.0, -0.02561, 0.00193),
        (0.2125, 0.0, 0.11336),
        (0.15, 0.0, 0.0265),
        (0.0, -0.0018, 0.01634),
        (0.0, -0.0018, 0.01634),
        (0.0, 0.0, -0.001159),
    ),
    inertias=tuple(
        rod_inertia(m, r, length, standard_segment(a, al, d))
        for m, (r, length), a, al, d in zip(_UR5_MASSES, _UR5_CYLINDERS, _UR5_A, _UR5_ALPHA, _UR5_D)
    ),
    # ours: 0.15 m past the flange, a gripper-sized tool. Joint 5 then moves the point with a lever of
    # d6 + tool = 0.23 m (0.08 m with the bare flange), so the wrist matters as the PUMA's does; joint 6 turns
    # about the tool axis and never moves it
    tool=0.15,
    base_height=0.51,  # m, ours: a pedestal that puts the shoulder axis (d1 = 0.0895 m up) 0.6 m up, as the PUMA's
    mount_offset=0.1,  # m, as the PUMA
)

#: Franka Emika Panda, modified DH, 7 joints (9 actuators with the wheels).
PANDA = ArmDescription(
    name="panda",
    convention="modified",
    # RTB DH.Panda (RevoluteMDH rows: a and alpha are Craig's a_{i-1}, alpha_{i-1}); d7 = the 107 mm flange
    a=(0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088),
    alpha=(0.0, -PI / 2, PI / 2, PI / 2, -PI / 2, PI / 2, PI / 2),
    d=(0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.107),
    theta_offset=(0.0,) * 7,
    # RTB DH.Panda qlim, rad
    joint_lower=(-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973),
    joint_upper=(2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973),
    speed_limit=(2.175, 2.175, 2.175, 2.175, 2.61, 2.61, 2.61),  # rad/s, panda_arm.xacro (Franka)
    torque_limit=(87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0),  # N m, panda_arm.xacro (Franka)
    # Gaz et al. 2019 via RTB DH.Panda, kg
    masses=(4.970684, 0.646926, 3.228604, 3.587895, 1.225946, 1.666555, 0.735522),
    # Gaz et al. 2019 via RTB-MATLAB mdl_panda.m, in DH frame i, m (link 1's z: 0, not identifiable)
    coms=(
        (3.875e-03, 2.081e-03, 0.0),
        (-3.141e-03, -2.872e-02, 3.495e-03),
        (2.7518e-02, 3.9252e-02, -6.6502e-02),
        (-5.317e-02, 1.04419e-01, 2.7454e-02),
        (-1.1953e-02, 4.1065e-02, -3.8437e-02),
        (6.0149e-02, -1.4117e-02, -1.0517e-02),
        (1.0517e-02, -4.252e-03, 6.1597e-02),
    ),
    # Gaz et al. 2019 via RTB DH.Panda, reordered from RTB's (Ixx, Iyy, Izz, Ixy, Iyz, Ixz) to ours
    # (ixx, iyy, izz, ixy, ixz, iyz), kg m^2
    inertias=(
        (7.03370e-01, 7.06610e-01, 9.11700e-03, -1.39000e-04, 6.77200e-03, 1.91690e-02),
        (7.96200e-03, 2.81100e-02, 2.59950e-02, -3.92500e-03, 1.02540e-02, 7.04000e-04),
        (3.72420e-02, 3.61550e-02, 1.08300e-02, -4.76100e-03, -1.13960e-02, -1.28050e-02),
        (2.58530e-02, 1.95520e-02, 2.83230e-02, 7.79600e-03, -1.33200e-03, 8.64100e-03),
        (3.55490e-02, 2.94740e-02, 8.62700e-03, -2.11700e-03, -4.03700e-03, 2.29000e-04),
        (1.96400e-03, 4.35400e-03, 5.43300e-03, 1.09000e-04, -1.15800e-03, 3.41000e-04),
        (1.25160e-02, 1.00270e-02, 4.81500e-03, -4.28000e-04, -1.19600e-03, -7.41000e-04),
    ),
    # RTB DH.Panda's hand: 0.103 m along z7 past the flange. The point lies on joint 7's axis (joint 7 never
    # moves it); joint 6 moves it with a lever of hypot(a7, d7 + tool) = hypot(0.088, 0.21) = 0.23 m, and joint 5
    # with up to that much, depending on q6
    tool=0.103,
    base_height=0.32,  # m, ours: on the deck top (DECK_BOTTOM + deck height in mobman_env.urdf), no pedestal
    mount_offset=0.1,  # m, as the PUMA
)

#: name -> description of every named arm.
ROBOTS = {arm.name: arm for arm in (PUMA560, UR5, PANDA)}

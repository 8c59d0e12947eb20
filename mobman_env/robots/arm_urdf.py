"""The URDF of an `ArmDescription` alone (fixed base = DH frame 0): the frame mapping the integrated writer needs.

This is the prototype of the package docstring's design note, kept small and tested against PyBullet so the
mapping is known to be right before `mobman_env.urdf` takes it over (the platform, wheels, casters and visuals
stay there). Layout: `arm_base` (DH frame 0), `link1..linkn` on revolute joints `joint1..jointn` about their
z axes, a massless `ee` link whose frame origin is the end-effector point.

* standard DH: joint i's origin is row i-1's fixed part Tz(d) Tx(a) Rx(alpha) (identity for joint 1); link i's
  frame is DH frame i-1 turned by theta_i, so link i's inertial frame sits at (a_i, 0, d_i) + Rx(alpha_i) c_i,
  turned by Rx(alpha_i) (its axes are DH frame i's, in which the tensor is given).
* modified DH: joint i's origin is Rx(alpha_i) Tx(a_i) Tz(d_i) (Rz(theta) and Tz(d) commute); link i's frame is
  DH frame i, so centres of mass and tensors go in unchanged.
* `theta_offset`: Rz(offset_i) is appended to joint i's origin (it commutes with the joint's own rotation), so a
  joint angle q in PyBullet is the description's q.

May import: numpy, the standard library, `mobman_env.robots.description`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from mobman_env.robots.description import ArmDescription

__all__ = ["EE_LINK", "arm_urdf_string", "rpy"]

EE_LINK = "ee"


def _rx(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rz(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF's (roll, pitch, yaw) of a rotation matrix: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    roll = math.atan2(R[2, 1], R[2, 2])
    pitch = math.atan2(-R[2, 0], math.hypot(R[2, 1], R[2, 2]))
    yaw = math.atan2(R[1, 0], R[0, 0])
    return roll, pitch, yaw


def _f(values: Iterable[float]) -> str:
    return " ".join(f"{float(v):.17g}" for v in values)


def _origin(xyz: Iterable[float], R: np.ndarray) -> str:
    return f'<origin xyz="{_f(xyz)}" rpy="{_f(rpy(R))}"/>'


def arm_urdf_string(arm: ArmDescription) -> str:
    """The URDF text of `arm` on a fixed base whose frame is DH frame 0."""
    n = arm.n_joints
    parts = [
        '<?xml version="1.0"?>',
        f'<robot name="{arm.name}">',
        # the fixed base's inertia is irrelevant (it never moves); the platform replaces it in the integration
        '<link name="arm_base"><inertial><mass value="1"/>'
        '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>',
    ]
    parent = "arm_base"
    for i in range(n):
        a, d, al, off = arm.a[i], arm.d[i], arm.alpha[i], arm.theta_offset[i]
        if arm.modified:
            xyz = _rx(al) @ np.array([a, 0.0, d])
            R = _rx(al) @ _rz(off)
            com, R_in = np.array(arm.coms[i]), np.eye(3)
        else:
            if i == 0:
                xyz, R_fixed = np.zeros(3), np.eye(3)
            else:
                pa, pd, pal = arm.a[i - 1], arm.d[i - 1], arm.alpha[i - 1]
                xyz, R_fixed = np.array([pa, 0.0, pd]), _rx(pal)
            R = R_fixed @ _rz(off)
            com = np.array([a, 0.0, d]) + _rx(al) @ np.array(arm.coms[i])
            R_in = _rx(al)
        ixx, iyy, izz, ixy, ixz, iyz = arm.inertias[i]
        parts += [
            f'<link name="link{i + 1}"><inertial>{_origin(com, R_in)}<mass value="{arm.masses[i]:.17g}"/>'
            f'<inertia ixx="{ixx:.17g}" iyy="{iyy:.17g}" izz="{izz:.17g}" ixy="{ixy:.17g}" ixz="{ixz:.17g}" '
            f'iyz="{iyz:.17g}"/></inertial></link>',
            f'<joint name="joint{i + 1}" type="revolute"><parent link="{parent}"/><child link="link{i + 1}"/>'
            f'{_origin(xyz, R)}<axis xyz="0 0 1"/><limit lower="{arm.joint_lower[i]:.17g}" '
            f'upper="{arm.joint_upper[i]:.17g}" effort="{arm.torque_limit[i]:.17g}" '
            f'velocity="{arm.speed_limit[i]:.17g}"/></joint>',
        ]
        parent = f"link{i + 1}"
    if arm.modified:
        ee_xyz = np.array([0.0, 0.0, arm.tool])
        ee_R = np.eye(3)
    else:
        a, d, al = arm.a[-1], arm.d[-1], arm.alpha[-1]
        ee_xyz = np.array([a, 0.0, d]) + _rx(al) @ np.array([0.0, 0.0, arm.tool])
        ee_R = _rx(al)
    parts += [
        # massless, with an explicit inertial: without one PyBullet gives the link 1 kg
        f'<link name="{EE_LINK}"><inertial><mass value="0"/>'
        '<inertia ixx="0" iyy="0" izz="0" ixy="0" ixz="0" iyz="0"/></inertial></link>',
        f'<joint name="ee_joint" type="fixed"><parent link="{parent}"/><child link="{EE_LINK}"/>'
        f"{_origin(ee_xyz, ee_R)}</joint>",
        "</robot>",
    ]
    return "\n".join(parts)

"""Write the URDF of the wheeled mobile manipulator from `RobotParams` (any arm: n joints, standard or modified
DH), so the simulation and `kinematics.py` share one source of numbers (a test checks PyBullet's end-effector
against the numpy FK for every robot).

Layout (link names are looked up by name in `sim.py`):

* `base_link`: the platform. Its frame is the axle centre P_0 at wheel-axle height r, x along the heading; its
  inertial origin is its link origin (PyBullet reports base poses at the inertial frame). Visual: the deck and
  the pedestal up to the shoulder.
* `wheel_left` (+y) and `wheel_right` (-y): driven wheels on continuous joints about y at +-b.
* `caster_front`, `caster_rear`: passive casters, modelled as fixed spheres whose contact is made
  frictionless in `sim.py` (lateral friction 0), so they carry weight but never resist motion.
* `link1`..`linkn` on `joint1`..`jointn`: the arm, its mount frame DH frame 0 at (`mount_offset`, 0,
  `shoulder_height` - r) in `base_link`. Standard DH puts the joint rotation first (A_i = Rz(theta) Tz(d) Tx(a)
  Rx(alpha)), URDF puts a fixed transform first, so joint i's origin is the fixed part (Tz Tx Rx) of link i-1
  and link i's frame is DH frame i-1 turned by theta_i (centres of mass and inertias, given in DH frame i, are
  moved into it). Modified DH (A_i = Rx(alpha) Tx(a) Rz(theta) Tz(d)) is URDF's order: joint i's origin is
  Rx(alpha_i) Tx(a_i) Tz(d_i) and link i's frame is DH frame i. A theta offset is appended to joint i's origin as
  Rz(offset_i) (it commutes with the joint's rotation), so PyBullet's joint angle is q. This is the mapping of
  `mobman_env.robots.arm_urdf`, with the platform and the visuals.
* `ee`: massless, at `tool` along z_n; its inertial origin is its link origin, so `getLinkState(...)[0]` is the
  end-effector point.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from mobman_env.params import RobotParams
from mobman_env.robots.arm_urdf import rpy


def arm_joints(n: int) -> tuple[str, ...]:
    """The names of the n arm joints: joint1 .. jointn."""
    return tuple(f"joint{i}" for i in range(1, n + 1))


#: the PUMA's six arm joints (release 0.1's constant; `arm_joints(n)` for any arm)
ARM_JOINTS = arm_joints(6)
WHEEL_JOINTS = ("wheel_left_joint", "wheel_right_joint")
EE_LINK = "ee"
CASTER_LINKS = ("caster_front", "caster_rear")

CASTER_RADIUS = 0.05  # m, ours
CASTER_X = 0.35  # m, ahead of and behind P_0, ours
DECK = (0.9, 0.5, 0.2)  # m, platform box length, width, height (ours; inside the wheels at b = 0.32)
DECK_BOTTOM = 0.12  # m above the ground, ours
WHEEL_WIDTH = 0.06  # m, ours
ARM_RADIUS = 0.045  # m, drawn radius of the arm links (visual only)


def _f(values) -> str:
    return " ".join(f"{float(v):.10g}" for v in values)


def _inertial(mass: float, xyz=(0, 0, 0), rpy=(0, 0, 0), diag=(0, 0, 0)) -> str:
    """An inertial block; `diag` is (ixx, iyy, izz) or the full (ixx, iyy, izz, ixy, ixz, iyz), kg m^2."""
    ixx, iyy, izz, ixy, ixz, iyz = (*diag, 0.0, 0.0, 0.0)[:6]
    return (
        f'<inertial><origin xyz="{_f(xyz)}" rpy="{_f(rpy)}"/><mass value="{mass:.10g}"/>'
        f'<inertia ixx="{ixx:.10g}" iyy="{iyy:.10g}" izz="{izz:.10g}" ixy="{ixy:.10g}" ixz="{ixz:.10g}" '
        f'iyz="{iyz:.10g}"/></inertial>'
    )


def _segment(p0, p1, radius: float, material: str) -> str:
    """A visual cylinder from p0 to p1 (link frame); nothing when they coincide."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    v = p1 - p0
    L = float(np.linalg.norm(v))
    if L < 1e-6:
        return ""
    u = v / L
    # rotate z onto u: pitch about y then yaw about z (rpy = roll, pitch, yaw)
    pitch = math.acos(max(-1.0, min(1.0, u[2])))
    yaw = math.atan2(u[1], u[0])
    mid = 0.5 * (p0 + p1)
    return (
        f'<visual><origin xyz="{_f(mid)}" rpy="0 {pitch:.10g} {yaw:.10g}"/>'
        f'<geometry><cylinder radius="{radius}" length="{L:.10g}"/></geometry><material name="{material}"/></visual>'
    )


def _dh_fixed(a: float, d: float, alpha: float) -> tuple[tuple, tuple]:
    """xyz and rpy of Tz(d) Tx(a) Rx(alpha)."""
    return (a, 0.0, d), (alpha, 0.0, 0.0)


def urdf_string(params: RobotParams) -> str:
    """The URDF text of the robot with these parameters: the platform (deck, two driven wheels, two passive
    casters), the n arm links from the DH table, and the massless end-effector link."""
    arm, ee_xyz, ee_rpy = _arm(params)
    parts = [
        '<?xml version="1.0"?>',
        f'<robot name="wheeled_{params.arm.name}">',
        *MATERIALS,
        *_base_link(params),
        *_wheels(params),
        *_casters(params),
        *arm,
        # end-effector: the point `tool` along z_n, oriented like DH frame n
        f'<link name="{EE_LINK}">',
        _inertial(0.0),
        '<visual><geometry><sphere radius="0.02"/></geometry><material name="tool"/></visual>',
        "</link>",
        f'<joint name="ee_joint" type="fixed"><parent link="link{params.n_joints}"/><child link="{EE_LINK}"/>'
        f'<origin xyz="{_f(ee_xyz)}" rpy="{_f(ee_rpy)}"/></joint>',
        "</robot>",
    ]
    return "\n".join(p for p in parts if p)


#: the colours the links use
MATERIALS = (
    '<material name="deck"><color rgba="0.25 0.3 0.35 1"/></material>',
    '<material name="arm"><color rgba="0.85 0.85 0.8 1"/></material>',
    '<material name="joint"><color rgba="0.9 0.5 0.1 1"/></material>',
    '<material name="tire"><color rgba="0.1 0.1 0.1 1"/></material>',
    '<material name="tool"><color rgba="0.8 0.1 0.1 1"/></material>',
)


def _base_link(params: RobotParams) -> list[str]:
    """The platform's deck (a box, its inertial origin at the link origin: the axle centre) and the pedestal."""
    r, h = params.wheel_radius, params.shoulder_height
    dl, dw, dh = DECK
    deck_z = DECK_BOTTOM - r + dh / 2  # deck centre relative to the axle
    top = DECK_BOTTOM + dh - r  # deck top relative to the axle
    m = params.platform_mass
    deck_inertia = (m / 12 * (dw**2 + dh**2), m / 12 * (dl**2 + dh**2), m / 12 * (dl**2 + dw**2))
    return [
        '<link name="base_link">',
        _inertial(m, diag=deck_inertia),
        f'<visual><origin xyz="0 0 {deck_z:.10g}"/><geometry><box size="{_f(DECK)}"/></geometry>'
        '<material name="deck"/></visual>',
        _segment((params.mount_offset, 0, top), (params.mount_offset, 0, h - r), 0.08, "deck"),
        _first_link(params),
        f'<collision><origin xyz="0 0 {deck_z:.10g}"/><geometry><box size="{_f(DECK)}"/></geometry></collision>',
        "</link>",
    ]


def _first_link(params: RobotParams) -> str:
    """Modified DH only: the arm from the mount (DH frame 0) to joint 1, drawn on the platform. In modified DH,
    joint 1 sits at Rx(alpha_0) Tx(a_0) Tz(d_0) from frame 0 (the Panda: 0.333 m up), a length no arm link
    carries (standard DH draws d_1 in link 1); without it the arm floats above its pedestal. Visual only."""
    if not params.arm.modified:
        return ""
    mount = np.array([params.mount_offset, 0.0, params.shoulder_height - params.wheel_radius])
    a, d, alpha = params.dh_a[0], params.dh_d[0], params.dh_alpha[0]
    return _segment(mount, mount + _rx(alpha) @ np.array([a, 0.0, d]), ARM_RADIUS, "arm")


def _wheels(params: RobotParams) -> list[str]:
    """The two driven wheels on continuous joints, half a track either side of the axle centre."""
    r, b = params.wheel_radius, params.half_track
    parts: list[str] = []
    for name, side in (("wheel_left", 1.0), ("wheel_right", -1.0)):
        wheel_inertia = (
            params.wheel_mass / 12 * (3 * r * r + WHEEL_WIDTH**2),
            params.wheel_mass / 2 * r * r,
            params.wheel_mass / 12 * (3 * r * r + WHEEL_WIDTH**2),
        )
        geom = f'<geometry><cylinder radius="{r:.10g}" length="{WHEEL_WIDTH}"/></geometry>'
        # collision: a sphere of the wheel's radius, so the contact is one point right under the hub (a
        # cylinder touches at both rims, which widens the track and makes the turn rate differ from eq. (5))
        ball = f'<geometry><sphere radius="{r:.10g}"/></geometry>'
        parts += [
            f'<link name="{name}">',
            _inertial(params.wheel_mass, diag=wheel_inertia),
            f'<visual><origin rpy="{math.pi / 2:.10g} 0 0"/>{geom}<material name="tire"/></visual>',
            f"<collision>{ball}</collision>",
            "</link>",
            f'<joint name="{name}_joint" type="continuous"><parent link="base_link"/><child link="{name}"/>'
            f'<origin xyz="0 {side * b:.10g} 0"/><axis xyz="0 1 0"/>'
            f'<limit effort="{params.wheel_torque_limit}" velocity="{params.wheel_speed_limit}"/></joint>',
        ]
    return parts


def _casters(params: RobotParams) -> list[str]:
    """The passive casters: fixed frictionless spheres touching the ground ahead of and behind the axle."""
    parts: list[str] = []
    for name, x in zip(CASTER_LINKS, (CASTER_X, -CASTER_X)):
        geom = f'<geometry><sphere radius="{CASTER_RADIUS}"/></geometry>'
        parts += [
            f'<link name="{name}">',
            _inertial(0.5, diag=(1e-4, 1e-4, 1e-4)),
            f'<visual>{geom}<material name="tire"/></visual><collision>{geom}</collision>',
            '<contact><lateral_friction value="0"/><rolling_friction value="0"/><spinning_friction value="0"/>'
            "</contact>",
            "</link>",
            f'<joint name="{name}_joint" type="fixed"><parent link="base_link"/><child link="{name}"/>'
            f'<origin xyz="{x} 0 {CASTER_RADIUS - params.wheel_radius:.10g}"/></joint>',
        ]
    return parts


def _rx(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _with_offset(frpy: tuple, alpha: float, offset: float) -> tuple:
    """rpy of Rx(alpha) Rz(offset): a joint origin with its theta offset appended (`frpy` when offset = 0)."""
    if offset == 0.0:
        return frpy
    c, s = math.cos(offset), math.sin(offset)
    return rpy(_rx(alpha) @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))


def _arm(params: RobotParams) -> tuple[list[str], np.ndarray, tuple[float, float, float]]:
    """The n arm links and revolute joints from the DH table; the mount frame is DH frame 0 (at P_c, shoulder
    height, x along the heading). Returns the parts and the end-effector's origin in link n (xyz, rpy)."""
    arm = params.arm
    n = arm.n_joints
    a, d, alpha = params.dh_a, params.dh_d, params.dh_alpha
    mount = np.array([params.mount_offset, 0.0, params.shoulder_height - params.wheel_radius])
    parts: list[str] = []
    parent = "base_link"
    origin_xyz: tuple | np.ndarray = tuple(mount)
    origin_alpha = 0.0
    ee_xyz = np.zeros(3)
    ee_rpy: tuple = (0.0, 0.0, 0.0)
    joint_ball = f'<visual><geometry><sphere radius="{ARM_RADIUS * 1.3}"/></geometry><material name="joint"/></visual>'
    for i in range(n):
        name = f"link{i + 1}"
        if arm.modified:
            # joint i's origin: Rx(alpha_i) Tx(a_i) Tz(d_i) from link i-1 (the mount for joint 1); link i = frame i
            origin_xyz = (mount if i == 0 else np.zeros(3)) + _rx(alpha[i]) @ np.array([a[i], 0.0, d[i]])
            origin_alpha = alpha[i]
            com, frpy = np.asarray(arm.coms[i]), (0.0, 0.0, 0.0)
            if i + 1 < n:
                end = _rx(alpha[i + 1]) @ np.array([a[i + 1], 0.0, d[i + 1]])
                visuals = _segment((0, 0, 0), end, ARM_RADIUS, "arm")
            else:
                ee_xyz = np.array([0.0, 0.0, params.tool])
                visuals = _segment((0, 0, 0), ee_xyz, ARM_RADIUS * 0.5, "tool")
            inertial = _inertial(params.arm.masses[i], com, frpy, arm.inertias[i])
        else:
            fx, frpy = _dh_fixed(a[i], d[i], alpha[i])
            # this link's frame: DH frame i-1 turned by theta_i; DH frame i is Tz(d) Tx(a) Rx(alpha) from it
            com_i = np.asarray(arm.coms[i])
            Rx = _rx(alpha[i])
            com = np.asarray(fx) + Rx @ com_i
            end = np.asarray(fx)
            visuals = _segment((0, 0, 0), (0, 0, d[i]), ARM_RADIUS, "arm") + _segment(
                (0, 0, d[i]), end, ARM_RADIUS, "arm"
            )
            if i == n - 1:  # link n carries the tool: frame n plus `tool` along z_n
                ee_xyz = np.asarray(fx) + Rx @ np.array([0.0, 0.0, params.tool])
                ee_rpy = frpy
                visuals += _segment(end, ee_xyz, ARM_RADIUS * 0.5, "tool")
            inertial = _inertial(arm.masses[i], com, frpy, arm.inertias[i])
        joint_rpy = _with_offset((origin_alpha, 0.0, 0.0), origin_alpha, arm.theta_offset[i])
        parts += [
            f'<link name="{name}">',
            inertial,
            joint_ball,
            visuals,
            "</link>",
            f'<joint name="joint{i + 1}" type="revolute"><parent link="{parent}"/><child link="{name}"/>'
            f'<origin xyz="{_f(origin_xyz)}" rpy="{_f(joint_rpy)}"/><axis xyz="0 0 1"/>'
            f'<limit lower="{arm.joint_lower[i]:.10g}" upper="{arm.joint_upper[i]:.10g}" '
            f'effort="{arm.torque_limit[i]}" velocity="{arm.speed_limit[i]}"/></joint>',
        ]
        if not arm.modified:
            parent, origin_xyz, origin_alpha = name, fx, alpha[i]
        else:
            parent = name
    return parts, ee_xyz, ee_rpy


def write_urdf(params: RobotParams, path: str | Path) -> Path:
    """Write the URDF of `params` to `path` and return it."""
    path = Path(path)
    path.write_text(urdf_string(params))
    return path


NOMINAL_URDF = Path(__file__).parent / "assets" / "wheeled_puma560.urdf"

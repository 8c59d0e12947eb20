"""`ArmDescription`: one frozen record of a serial arm from which its kinematics, URDF and spaces are derived.

A description holds the Denavit-Hartenberg convention and table, the limits, the inertial data per link, the
tool offset and the mount on the platform; nothing else about the robot (wheels, deck) lives here. Every number
is validated once, in `__post_init__`, so a description that exists is usable by the kinematics, by PyBullet
(positive-definite inertias that satisfy the triangle inequality) and by the action scaling.

Conventions (both as in roboticstoolbox-python, `DHLink.A`):

* `"standard"`: link i's transform is A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i); joint i turns about
  z_{i-1} through the origin of frame i-1; frame i sits at the distal end of link i.
* `"modified"` (Craig): A_i = Rx(alpha_i) Tx(a_i) Rz(theta_i) Tz(d_i), with `a[i]`, `alpha[i]` the numbers
  written in row i of the table (Craig's a_{i-1}, alpha_{i-1}); joint i turns about z_i through the origin of
  frame i.

In both, theta_i = q_i + `theta_offset[i]`, frame 0 is the arm's base frame, and the end-effector point is the
origin of frame n plus `tool` along z_n. Centres of mass and inertia tensors of link i are expressed in DH frame
i (the frame that moves with joint i, in either convention).

May import: numpy, the standard library, `mobman_env.validation`.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env.validation import number

__all__ = ["CONVENTIONS", "ArmDescription", "rod_inertia", "standard_segment"]

#: The accepted DH conventions.
CONVENTIONS = ("standard", "modified")

Vec3 = tuple[float, float, float]
#: An inertia tensor about the centre of mass: (ixx, iyy, izz, ixy, ixz, iyz), kg m^2, axes of DH frame i.
Inertia = tuple[float, float, float, float, float, float]


def _floats(name: str, values: Any, n: int, *, low: float | None = None, open_low: bool = False) -> tuple:
    try:
        items: tuple[Any, ...] = tuple(values)
    except TypeError:
        raise ValueError(f"{name} must be a sequence of {n} numbers, got {values!r}") from None
    if len(items) != n:
        raise ValueError(f"{name} must have one entry per joint ({n}), got {len(items)}: {values!r}")
    return tuple(number(f"{name}[{i}]", v, low=low, open_low=open_low) for i, v in enumerate(items))


def _inertia_matrix(t: Inertia) -> np.ndarray:
    ixx, iyy, izz, ixy, ixz, iyz = t
    return np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])


def rod_inertia(mass: float, radius: float, length: float, axis: Vec3) -> Inertia:
    """Inertia about the centre of a solid cylinder (mass kg, radius and length m) whose axis is the direction
    `axis` (any non-zero 3-vector), as the 6-tuple (ixx, iyy, izz, ixy, ixz, iyz) in kg m^2."""
    u = np.asarray(axis, dtype=float)
    u = u / np.linalg.norm(u)
    i_axial = 0.5 * mass * radius * radius
    i_perp = mass * (3.0 * radius * radius + length * length) / 12.0
    m = i_perp * (np.eye(3) - np.outer(u, u)) + i_axial * np.outer(u, u)
    return (float(m[0, 0]), float(m[1, 1]), float(m[2, 2]), float(m[0, 1]), float(m[0, 2]), float(m[1, 2]))


def standard_segment(a: float, alpha: float, d: float) -> Vec3:
    """The vector from o_{i-1} to o_i in frame i coordinates for a standard-DH row (a, alpha, d), m:
    Rx(-alpha) (a, 0, d) = (a, d sin alpha, d cos alpha). It does not depend on theta_i."""
    return (a, d * math.sin(alpha), d * math.cos(alpha))


@dataclass(frozen=True)
class ArmDescription:
    """A serial arm of n revolute joints on the wheeled platform: DH table, limits, inertia, tool and mount.

    All tuples have one entry per joint, in joint order. Units: m, rad, rad/s, N m, kg, kg m^2.
    """

    name: str  #: a short label, e.g. "puma560"
    convention: str  #: "standard" or "modified" DH (see the module docstring)
    a: tuple[float, ...]  #: DH a of each row, m
    alpha: tuple[float, ...]  #: DH alpha of each row, rad
    d: tuple[float, ...]  #: DH d of each row, m
    theta_offset: tuple[float, ...]  #: added to the joint angle q_i to give the DH theta_i, rad
    joint_lower: tuple[float, ...]  #: joint limits, rad (lower < upper)
    joint_upper: tuple[float, ...]
    speed_limit: tuple[float, ...]  #: maximum joint speed, rad/s (> 0): the action scale
    torque_limit: tuple[float, ...]  #: maximum joint torque in physics mode, N m (> 0)
    masses: tuple[float, ...]  #: link masses, kg (> 0: PyBullet treats a massless link as fixed)
    coms: tuple[Vec3, ...]  #: centre of mass of link i in DH frame i, m
    inertias: tuple[Inertia, ...]  #: (ixx, iyy, izz, ixy, ixz, iyz) about the centre of mass, DH frame i axes
    tool: float  #: end-effector point: this far along z_n from the origin of frame n, m (>= 0)
    base_height: float  #: height of DH frame 0 above the ground, m (plays `RobotParams.shoulder_height`'s role)
    mount_offset: float  #: DH frame 0 lies this far ahead of the axle centre P_0 along the heading, m

    def __post_init__(self) -> None:
        if self.convention not in CONVENTIONS:
            raise ValueError(
                f"convention must be one of {', '.join(map(repr, CONVENTIONS))}, got {self.convention!r} "
                f"(standard: A = Rz Tz Tx Rx; modified, Craig: A = Rx Tx Rz Tz)"
            )
        per_joint = (
            "a",
            "alpha",
            "d",
            "theta_offset",
            "joint_lower",
            "joint_upper",
            "speed_limit",
            "torque_limit",
            "masses",
            "coms",
            "inertias",
        )
        sizes = {}
        for name in per_joint:
            try:
                sizes[name] = len(getattr(self, name))
            except TypeError:
                raise ValueError(
                    f"{name} must be a sequence with one entry per joint, got {getattr(self, name)!r}"
                ) from None
        n = sizes["a"]
        if n < 1:
            raise ValueError("an arm needs at least one joint: a, alpha, d, ... are empty")
        if len(set(sizes.values())) > 1:
            raise ValueError(
                f"every per-joint field needs one entry per joint, but their lengths differ: {sizes}; "
                f"give each of {', '.join(per_joint)} the same number of entries"
            )
        fix = object.__setattr__  # frozen: normalise once, here
        for name in ("a", "alpha", "d", "theta_offset", "joint_lower", "joint_upper"):
            fix(self, name, _floats(name, getattr(self, name), n))
        for name in ("speed_limit", "torque_limit", "masses"):
            fix(self, name, _floats(name, getattr(self, name), n, low=0.0, open_low=True))
        lo, hi = self.joint_lower, self.joint_upper
        bad = [i for i in range(n) if not lo[i] < hi[i]]
        if bad:
            raise ValueError(
                f"joint limits must satisfy lower < upper; joint(s) {[i + 1 for i in bad]} have "
                f"lower {[lo[i] for i in bad]}, upper {[hi[i] for i in bad]} (rad)"
            )
        if len(self.coms) != n or len(self.inertias) != n:
            raise ValueError(
                f"coms and inertias need one entry per joint ({n}), got {len(self.coms)}, {len(self.inertias)}"
            )
        fix(self, "coms", tuple(_floats(f"coms[{i}]", c, 3) for i, c in enumerate(self.coms)))
        fix(self, "inertias", tuple(_floats(f"inertias[{i}]", t, 6) for i, t in enumerate(self.inertias)))
        for i, t in enumerate(self.inertias):
            p = np.linalg.eigvalsh(_inertia_matrix(t))
            if p[0] <= 0.0 or p[0] + p[1] < p[2] * (1.0 - 1e-9):
                raise ValueError(
                    f"inertias[{i}] (link {i + 1}) = {t} is not physical: its principal moments {p.tolist()} must be "
                    f"> 0 and satisfy the triangle inequality I1 + I2 >= I3 (PyBullet zeroes such a tensor)"
                )
        fix(self, "tool", number("tool", self.tool, low=0.0))
        fix(self, "base_height", number("base_height", self.base_height, low=0.0, open_low=True))
        fix(self, "mount_offset", number("mount_offset", self.mount_offset))

    # --- derived ---------------------------------------------------------------------------------------
    @property
    def n_joints(self) -> int:
        """n, the number of arm joints."""
        return len(self.a)

    @property
    def n_actuators(self) -> int:
        """n + 2: the arm joints, then the left and right wheel (the action's length)."""
        return self.n_joints + 2

    @property
    def modified(self) -> bool:
        """True for the modified (Craig) convention."""
        return self.convention == "modified"

    @functools.cached_property
    def dh_constants(self) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """(a, d, cos alpha, sin alpha) as tuples of floats, computed once (the kinematics' hot path)."""
        return self.a, self.d, tuple(math.cos(x) for x in self.alpha), tuple(math.sin(x) for x in self.alpha)

    @property
    def limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) joint limits as arrays, rad."""
        return np.array(self.joint_lower), np.array(self.joint_upper)

    def inertia_matrix(self, i: int) -> np.ndarray:
        """The 3 x 3 inertia tensor of link i (0-based) about its centre of mass, DH frame i axes, kg m^2."""
        return _inertia_matrix(self.inertias[i])

    @functools.cached_property
    def length_slots(self) -> tuple[tuple[str, int], ...]:
        """The kinematic lengths a "worn" copy changes, in draw order: every non-zero `a` (row order), every
        non-zero `d`, then `tool` (index -1). For the PUMA: a2, a3, d3, d4, tool, today's `PERTURBED_FIELDS`
        order (the platform's r, b, d follow them there)."""
        slots = [("a", i) for i, v in enumerate(self.a) if v != 0.0]
        slots += [("d", i) for i, v in enumerate(self.d) if v != 0.0]
        return (*slots, ("tool", -1))

    def scaled_lengths(self, factors: Any, mount_factor: float = 1.0) -> ArmDescription:
        """A copy with the lengths of `length_slots` multiplied by `factors` (one per slot, in that order) and the
        mount offset by `mount_factor`, each product computed as `float(value * factor)` like
        `RobotParams.perturbed`, so equal factors give equal bits. Masses, inertias and limits are unchanged.

        The factors are checked (finite, > 0), and then the copy is made without running the description's full
        validation again: the products of checked lengths and checked factors keep every check true (finite, zero
        where they were zero, tool >= 0), and that validation (a hundred number checks, an eigendecomposition
        per link: about 0.2 ms) would otherwise be paid at every step of an env with wear drift."""
        f = [number(f"factors[{i}]", x, low=0.0, open_low=True) for i, x in enumerate(factors)]
        fm = number("mount_factor", mount_factor, low=0.0, open_low=True)
        slots = self.length_slots
        if len(f) != len(slots):
            raise ValueError(f"{self.name} has {len(slots)} perturbable lengths {slots}, got {len(f)} factors")
        a, d = list(self.a), list(self.d)
        tool = self.tool
        for (name, i), k in zip(slots, f):
            if name == "a":
                a[i] = float(a[i] * k)
            elif name == "d":
                d[i] = float(d[i] * k)
            else:
                tool = float(tool * k)
        mount = float(self.mount_offset * fm)
        if not all(math.isfinite(x) for x in (*a, *d, tool, mount)):
            raise ValueError(f"{self.name}: scaling by {f} (mount {fm}) overflows a length; use factors near 1")
        new = copy.copy(self)
        for cached in ("dh_constants", "length_slots"):  # functools.cached_property values of self
            new.__dict__.pop(cached, None)
        fix = object.__setattr__
        fix(new, "a", tuple(a))
        fix(new, "d", tuple(d))
        fix(new, "tool", tool)
        fix(new, "mount_offset", mount)
        return new

    def replace(self, **changes: object) -> ArmDescription:
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)  # type: ignore[arg-type]

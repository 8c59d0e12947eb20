"""Robot parameters of a wheeled mobile manipulator: one arm description on the two-wheel platform.

`RobotParams` joins an arm (`mobman_env.robots.ArmDescription`: DH convention and table, joint, speed and torque
limits, masses, tool, mount) and the differential-drive platform (wheel radius, half track, masses, wheel
limits). It is the one robot record from which `kinematics`, `urdf`, `sim` and the env's spaces are derived, for
an arm of any number n of joints; the default arm is the PUMA 560 (`mobman_env.robots.PUMA560`, release 0.1's
robot number for number).

`RobotParams.nominal(arm)` is the catalogue robot a model-based method may know. `RobotParams.perturbed(rng,
rel_std)` draws a "worn" robot whose kinematic lengths differ from the catalogue (the paper's unknown is
kinematic, so masses are left alone): the arm's `length_slots` (every non-zero DH a in row order, every non-zero
d, the tool), then the wheel radius r, the half track b and the mount offset d, one standard normal each, in that
order. For the PUMA these are a2, a3, d3, d4, tool, r, b, d, release 0.1's order, and each product is computed
as it was (`float(length * (1 + rel_std z))`), so the PUMA's worn robots are bit for bit those of release 0.1.
`RobotParams.scaled(factor)` multiplies the same lengths by one factor (the env's `wear_rate` drift).

A length is read by its slot name too: `params.a2`, `params.d4` (DH a or d of row k, 1-based), `params.tool`.

Imports numpy, `mobman_env.validation`, `mobman_env.engine` (to pack a robot into its rows) and
`mobman_env.robots` (description and catalogue) only.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env import engine
from mobman_env.robots.catalogue import PUMA560
from mobman_env.robots.description import ArmDescription
from mobman_env.validation import number

DEG = math.pi / 180.0

#: The platform lengths that `perturbed()` and `scaled()` change after the arm's `length_slots`.
PLATFORM_LENGTHS = ("wheel_radius", "half_track", "mount_offset")
#: `perturbed()` clips each factor to 1 +- CLIP * rel_std (CLIP standard deviations).
CLIP = 3.0
#: rel_std must stay below this (1 / CLIP = 1/3): at 1/3 a factor 1 - CLIP * rel_std reaches 0, i.e. a length
#: (a link, the wheel radius, the half track) could become zero or, beyond, negative.
MAX_REL_STD = 1.0 / CLIP
#: The smallest factor of a worn length: a true length is at least this fraction of its nominal one. The clip
#: 1 - CLIP * rel_std reaches it at rel_std = 0.3; from there to 1/3 the lower bound stays here (a link of 1e-18 m
#: would otherwise load silently in PyBullet and make the arm singular). No robot with rel_std <= 0.3 changes.
MIN_LENGTH_FACTOR = 0.1
_SLOT_NAME = re.compile(r"^([ad])([1-9][0-9]*)$")


def slot_name(slot: tuple[str, int]) -> str:
    """The name of an `ArmDescription.length_slots` entry: ("a", 1) -> "a2", ("tool", -1) -> "tool"."""
    kind, i = slot
    return kind if kind == "tool" else f"{kind}{i + 1}"


@dataclass(frozen=True)
class RobotParams:
    """Geometry, inertia and limits of an arm (`arm`, default the PUMA 560) on a two-wheel differential-drive
    platform.

    Arm: see `mobman_env.robots.catalogue` for the provenance of each arm's numbers. Platform numbers from the
    public code of the group that wrote the paper, for a similar platform.
    """

    arm: ArmDescription = PUMA560  # the arm: DH table, limits, masses, tool (m), mount (m)

    # --- platform (public code of the paper's group, similar platform) ---------------------------------
    wheel_radius: float = 0.2  # m, r
    half_track: float = 0.32  # m, b: distance from P_0 to each wheel
    platform_mass: float = 60.0  # kg, ours: heavy enough that the arm's swing does not tip it
    wheel_mass: float = 2.0  # kg, ours
    wheel_speed_limit: float = 10.0  # rad/s, each wheel (2 m/s at r = 0.2 m)
    wheel_torque_limit: float = 200.0  # N m per wheel

    @classmethod
    def nominal(cls, arm: ArmDescription = PUMA560) -> RobotParams:
        """The catalogue robot with this arm (default the PUMA 560)."""
        return cls(arm=arm)

    # --- the arm's numbers, by name ----------------------------------------------------------------------
    def __getattr__(self, name: str) -> float:
        # only called for names that are not attributes: the DH lengths by slot name (a2, d4, ...)
        m = _SLOT_NAME.match(name)
        arm = self.__dict__.get("arm")
        if m is None or arm is None:
            raise AttributeError(f"{type(self).__name__!s} has no attribute {name!r}")
        i = int(m.group(2)) - 1
        values = arm.a if m.group(1) == "a" else arm.d
        if i >= len(values):
            raise AttributeError(f"{arm.name} has {len(values)} joints: no DH length {name!r}")
        return values[i]

    @property
    def n_joints(self) -> int:
        """n, the arm's joints."""
        return self.arm.n_joints

    @property
    def n_actuators(self) -> int:
        """n + 2: the arm joints, the left and the right wheel (the action's length)."""
        return self.arm.n_actuators

    @property
    def tool(self) -> float:
        """m, the end-effector point's offset along the last joint's z axis (`ArmDescription.tool`)."""
        return self.arm.tool

    @property
    def mount_offset(self) -> float:
        """m, d: the arm mount P_c (DH frame 0) lies this far ahead of the axle centre P_0 along the heading."""
        return self.arm.mount_offset

    @property
    def shoulder_height(self) -> float:
        """m, h: DH frame 0 above the ground (`ArmDescription.base_height`)."""
        return self.arm.base_height

    @property
    def joint_lower(self) -> tuple[float, ...]:
        """rad, the arm's lower joint limits."""
        return self.arm.joint_lower

    @property
    def joint_upper(self) -> tuple[float, ...]:
        """rad, the arm's upper joint limits."""
        return self.arm.joint_upper

    @property
    def arm_speed_limit(self) -> tuple[float, ...]:
        """rad/s, the arm joints' speed limits."""
        return self.arm.speed_limit

    @property
    def arm_torque_limit(self) -> tuple[float, ...]:
        """N m, the arm joints' torque limits in physics mode."""
        return self.arm.torque_limit

    @property
    def perturbed_fields(self) -> tuple[str, ...]:
        """The names of the lengths `perturbed()` and `scaled()` change, in draw order."""
        return (*(slot_name(s) for s in self.arm.length_slots), *PLATFORM_LENGTHS)

    # --- worn copies -------------------------------------------------------------------------------------
    def _with_factors(self, factors: Any) -> RobotParams:
        k = len(self.arm.length_slots)
        fr, fb, fd = factors[k], factors[k + 1], factors[k + 2]
        arm = self.arm.scaled_lengths(factors[:k], mount_factor=fd)
        return dataclasses.replace(
            self, arm=arm, wheel_radius=float(self.wheel_radius * fr), half_track=float(self.half_track * fb)
        )

    def perturbed(self, rng: np.random.Generator, rel_std: float) -> RobotParams:
        """A "worn" robot: each of `perturbed_fields` (the arm's non-zero a and d, the tool, r, b and d)
        multiplied by (1 + rel_std N(0, 1)), the factor clipped to 1 +- 3 rel_std, independently, and never
        below `MIN_LENGTH_FACTOR` (0.1: a worn length is at least a tenth of its nominal one). Masses and
        limits are unchanged.

        `rel_std` must be in [0, 1/3) (factors in [max(0.1, 1 - 3 rel_std), 1 + 3 rel_std]; at rel_std = 0.3
        exactly [0.1, 1.9], and up to 1/3 the lower bound stays 0.1). `rel_std = 0` returns an equal copy and
        draws nothing from `rng`.
        """
        rel_std = number(
            "rel_std",
            rel_std,
            low=0.0,
            high=MAX_REL_STD,
            open_high=True,
            hint="lengths are multiplied by factors in [max(0.1, 1 - 3 rel_std), 1 + 3 rel_std]",
        )
        if rel_std == 0.0:
            return dataclasses.replace(self)
        z = np.clip(rng.standard_normal(len(self.perturbed_fields)), -CLIP, CLIP)
        return self._with_factors([max(1.0 + rel_std * zi, MIN_LENGTH_FACTOR) for zi in z])

    def scaled(self, factor: float) -> RobotParams:
        """This robot with each of `perturbed_fields` multiplied by `factor` (> 0), e.g. the linear wear drift
        1 + wear_rate * t of the env. `factor = 1` returns an equal copy."""
        factor = number("factor", factor, low=0.0, open_low=True)
        return self._with_factors([factor] * len(self.perturbed_fields))

    # --- derived ---------------------------------------------------------------------------------------
    @property
    def dh_a(self) -> np.ndarray:
        """DH a_i, m."""
        return np.array(self.arm.a)

    @property
    def dh_d(self) -> np.ndarray:
        """DH d_i, m."""
        return np.array(self.arm.d)

    @property
    def dh_alpha(self) -> np.ndarray:
        """DH alpha_i, rad."""
        return np.array(self.arm.alpha)

    @functools.cached_property
    def engine_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """This robot packed as one row of `mobman_env.engine`'s (`arm`, `prm`) arrays (computed once per robot;
        `mobman_env.kinematics` evaluates its kernels on them)."""
        return engine.packed([self])

    @functools.cached_property
    def theta_offset(self) -> np.ndarray | None:
        """The DH theta offsets (rad) as an array, or None when all are zero (then q is theta, untouched)."""
        off = self.arm.theta_offset
        return np.array(off) if any(v != 0.0 for v in off) else None

    @property
    def action_scale(self) -> np.ndarray:
        """Speed limits of the n + 2 actuators (n arm joints, left wheel, right wheel), rad/s."""
        return np.array([*self.arm.speed_limit, self.wheel_speed_limit, self.wheel_speed_limit], dtype=np.float64)

    def to_dict(self) -> dict:
        """Every number of the robot, flat: the arm's lengths by slot name (a2, d4, tool), masses, centres of
        mass, inertias (a diagonal tensor as its three moments), limits, the platform's numbers, and under "dh"
        the arm's convention, twists, offsets and full a and d. "dh" is left out for an arm with the PUMA 560's
        geometry (convention, twists, offsets, non-zero slots), so the PUMA's dict, and `hash()`, are release
        0.1's."""
        arm = self.arm
        lengths = {slot_name(s): (arm.tool if s[0] == "tool" else getattr(arm, s[0])[s[1]]) for s in arm.length_slots}
        out: dict[str, Any] = {
            **lengths,
            "masses": arm.masses,
            "coms": arm.coms,
            "inertias": tuple(t[:3] if not any(t[3:]) else t for t in arm.inertias),
            "joint_lower": arm.joint_lower,
            "joint_upper": arm.joint_upper,
            "wheel_radius": self.wheel_radius,
            "half_track": self.half_track,
            "mount_offset": arm.mount_offset,
            "shoulder_height": arm.base_height,
            "platform_mass": self.platform_mass,
            "wheel_mass": self.wheel_mass,
            "arm_speed_limit": arm.speed_limit,
            "wheel_speed_limit": self.wheel_speed_limit,
            "arm_torque_limit": arm.torque_limit,
            "wheel_torque_limit": self.wheel_torque_limit,
        }
        if _geometry(arm) != _geometry(PUMA560):
            out["dh"] = {
                "name": arm.name,
                "convention": arm.convention,
                "a": arm.a,
                "alpha": arm.alpha,
                "d": arm.d,
                "theta_offset": arm.theta_offset,
            }
        return out

    def hash(self) -> str:
        """A short stable digest (e.g. to show that two episodes faced the same true robot)."""
        text = json.dumps(self.to_dict(), sort_keys=True, default=float)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _geometry(arm: ArmDescription) -> tuple:
    """What `to_dict` does not spell out by slot name: convention, twists, offsets and which lengths are set."""
    return (arm.name, arm.convention, arm.alpha, arm.theta_offset, arm.length_slots)


#: The PUMA 560's perturbed lengths in draw order (release 0.1's constant): a2, a3, d3, d4, tool, r, b, d.
PERTURBED_FIELDS = RobotParams().perturbed_fields

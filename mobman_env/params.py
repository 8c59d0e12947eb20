"""Robot parameters of the wheeled PUMA 560: every number with its provenance and unit.

`RobotParams.nominal()` is the catalogue robot a model-based method may know. `RobotParams.perturbed(rng,
rel_std)` draws a "worn" robot whose kinematic lengths differ from the catalogue (the paper's unknown is
kinematic, so masses are left alone); `RobotParams.scaled(factor)` multiplies the same lengths by one factor
(the env's `wear_rate` drift). Imports numpy and `mobman_env.validation` only.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env.validation import number

DEG = math.pi / 180.0

#: The lengths that `perturbed()` and `scaled()` change: the kinematic unknowns of the paper.
PERTURBED_FIELDS = ("a2", "a3", "d3", "d4", "tool", "wheel_radius", "half_track", "mount_offset")
#: `perturbed()` clips each factor to 1 +- CLIP * rel_std (CLIP standard deviations).
CLIP = 3.0
#: rel_std must stay below this (1 / CLIP = 1/3): at 1/3 a factor 1 - CLIP * rel_std reaches 0, i.e. a length
#: (a link, the wheel radius, the half track) could become zero or, beyond, negative.
MAX_REL_STD = 1.0 / CLIP


@dataclass(frozen=True)
class RobotParams:
    """Geometry, inertia and limits of a PUMA 560 on a two-wheel differential-drive platform.

    Arm: standard Denavit-Hartenberg table of the PUMA 560 as in Corke & Armstrong-Helouvry, "A search for
    consensus among model parameters reported for the PUMA 560 robot", ICRA 1994, in the form of the Robotics
    Toolbox `Puma560` model (d1 = 0 here: the pedestal is part of `shoulder_height`). Joint limits from the same
    file (Wang & Chen 1991). Platform numbers from the public code of the group that wrote the paper, for a
    similar platform.
    """

    # --- arm, standard DH (Corke & Armstrong-Helouvry 1994 / RTB Puma560) --------------------------------
    a2: float = 0.4318  # m, upper-arm length (a of link 2)
    a3: float = 0.0203  # m, elbow offset (a of link 3)
    d3: float = 0.15005  # m, shoulder offset (d of link 3; RTB changed it to 150.05 mm in 1995)
    d4: float = 0.4318  # m, forearm length (d of link 4)
    tool: float = 0.2  # m, tool length along the approach axis z6 (ours: makes joints 4-5 move the point)
    # link masses, kg (links 2-6: Corke & Armstrong-Helouvry; link 1: none published, m1 = 0 in the table.
    # We choose 5 kg on the joint axis so PyBullet treats the link as a dynamic body; it cannot change any
    # end-effector position, only the torque joint 1 needs.)
    masses: tuple[float, ...] = (5.0, 17.4, 4.8, 0.82, 0.34, 0.09)
    # centres of mass in each DH link frame, m (same table; link 1: ours, on the axis)
    coms: tuple[tuple[float, float, float], ...] = (
        (0.0, 0.0, 0.0),
        (-0.3638, 0.006, 0.2275),
        (-0.0203, -0.0141, 0.070),
        (0.0, 0.019, 0.0),
        (0.0, 0.0, 0.0),
        (0.0, 0.0, 0.032),
    )
    # principal inertias about the centre of mass, kg m^2 (same table; link 1: Iyy = 0.35 published, we use
    # 0.35 on all three axes; link 3: the published (0.066, 0.086, 0.0125) breaks the triangle inequality
    # Ixx + Izz >= Iyy, which PyBullet rejects (it zeroes the tensor), so we raise Izz to 0.020)
    inertias: tuple[tuple[float, float, float], ...] = (
        (0.35, 0.35, 0.35),
        (0.13, 0.524, 0.539),
        (0.066, 0.086, 0.020),
        (1.8e-3, 1.3e-3, 1.8e-3),
        (0.3e-3, 0.4e-3, 0.3e-3),
        (0.15e-3, 0.15e-3, 0.04e-3),
    )
    # joint limits, rad (RTB Puma560, from Wang & Chen 1991)
    joint_lower: tuple[float, ...] = (-160 * DEG, -45 * DEG, -225 * DEG, -110 * DEG, -100 * DEG, -266 * DEG)
    joint_upper: tuple[float, ...] = (160 * DEG, 225 * DEG, 45 * DEG, 170 * DEG, 100 * DEG, 266 * DEG)

    # --- platform (public code of the paper's group, similar platform) ---------------------------------
    wheel_radius: float = 0.2  # m, r
    half_track: float = 0.32  # m, b: distance from P_0 to each wheel
    mount_offset: float = 0.1  # m, d: arm mount P_c ahead of the axle centre P_0 along the heading
    shoulder_height: float = 0.6  # m, h: shoulder axis above the ground (platform + pedestal)
    platform_mass: float = 60.0  # kg, ours: heavy enough that the arm's swing does not tip it
    wheel_mass: float = 2.0  # kg, ours

    # --- speed limits: the action scale --------------------------------------------------------------
    arm_speed_limit: tuple[float, ...] = (3.0, 3.0, 3.0, 5.0, 5.0, 5.0)  # rad/s, joints 1-6
    wheel_speed_limit: float = 10.0  # rad/s, each wheel (2 m/s at r = 0.2 m)
    # torque limits for physics mode, N m: joint 2 holds 17.4 kg at 0.43 m plus the forearm and the tool
    # (about 110 N m static); we give every joint a margin of about 3x its worst static gravity load.
    arm_torque_limit: tuple[float, ...] = (300.0, 400.0, 150.0, 30.0, 30.0, 10.0)
    wheel_torque_limit: float = 200.0  # N m per wheel

    @classmethod
    def nominal(cls) -> RobotParams:
        """The catalogue robot."""
        return cls()

    def perturbed(self, rng: np.random.Generator, rel_std: float) -> RobotParams:
        """A "worn" robot: each of a2, a3, d3, d4, tool, r, b and d multiplied by (1 + rel_std N(0, 1)),
        the factor clipped to 1 +- 3 rel_std, independently. Masses and limits are unchanged.

        `rel_std` must be in [0, 1/3): the smallest factor, 1 - 3 rel_std, must stay above 0 so that no length
        can reach zero (0.3 is allowed: factors in [0.1, 1.9]). `rel_std = 0` returns an equal copy and draws
        nothing from `rng`.
        """
        rel_std = number(
            "rel_std",
            rel_std,
            low=0.0,
            high=MAX_REL_STD,
            open_high=True,
            hint="lengths are multiplied by factors in [1 - 3 rel_std, 1 + 3 rel_std]; at 1/3 a length can reach 0",
        )
        if rel_std == 0.0:
            return dataclasses.replace(self)
        z = np.clip(rng.standard_normal(len(PERTURBED_FIELDS)), -CLIP, CLIP)
        changes: dict[str, Any] = {
            name: float(getattr(self, name) * (1.0 + rel_std * zi)) for name, zi in zip(PERTURBED_FIELDS, z)
        }
        return dataclasses.replace(self, **changes)

    def scaled(self, factor: float) -> RobotParams:
        """This robot with each of a2, a3, d3, d4, tool, r, b and d multiplied by `factor` (> 0), e.g. the
        linear wear drift 1 + wear_rate * t of the env. `factor = 1` returns an equal copy."""
        factor = number("factor", factor, low=0.0, open_low=True)
        changes: dict[str, Any] = {name: getattr(self, name) * factor for name in PERTURBED_FIELDS}
        return dataclasses.replace(self, **changes)

    # --- derived ---------------------------------------------------------------------------------------
    @property
    def dh_a(self) -> np.ndarray:
        """DH a_i, m."""
        return np.array([0.0, self.a2, self.a3, 0.0, 0.0, 0.0])

    @property
    def dh_d(self) -> np.ndarray:
        """DH d_i, m (d1 = 0: the pedestal is in `shoulder_height`)."""
        return np.array([0.0, 0.0, self.d3, self.d4, 0.0, 0.0])

    @property
    def dh_alpha(self) -> np.ndarray:
        """DH alpha_i, rad."""
        return np.array([math.pi / 2, 0.0, -math.pi / 2, math.pi / 2, -math.pi / 2, 0.0])

    @functools.cached_property
    def dh_constants(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(a, d, cos alpha, sin alpha) of the DH table, computed once per robot (kinematics' hot path)."""
        alpha = self.dh_alpha
        return self.dh_a, self.dh_d, np.cos(alpha), np.sin(alpha)

    @property
    def action_scale(self) -> np.ndarray:
        """Speed limits of the 8 actuators (6 arm joints, left wheel, right wheel), rad/s."""
        return np.array([*self.arm_speed_limit, self.wheel_speed_limit, self.wheel_speed_limit], dtype=np.float64)

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    def hash(self) -> str:
        """A short stable digest (e.g. to show that two episodes faced the same true robot)."""
        text = json.dumps(self.to_dict(), sort_keys=True, default=float)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

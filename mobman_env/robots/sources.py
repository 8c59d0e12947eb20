"""Where an env's robot comes from: one `RobotSource` per robot name, so the env has no per-robot branch.

A source gives the robot a model-based method may know (`nominal`, before the first reset) and, at every reset,
the episode's nominal robot and start configuration drawn from the env's generator (`draw(rng)`):

| name | robot | start | draws from the env's generator |
|---|---|---|---|
| `puma560` | `PUMA560` on the platform (release 0.1's robot) | the paper's theta(0) (`STARTS`) | nothing |
| `ur5` | `UR5` | `STARTS["ur5"]` | nothing |
| `panda` | `PANDA` | `STARTS["panda"]` | nothing |
| `random` | a new arm of `random_arm`'s family per reset | the draw's start | the design, its start and redraws |
| `random-scaled` | a new arm of `random_scaled_arm`'s family per reset: a family arm with every length times one factor in [0.7, 1.4]; its catalogue (nominal robot) is the design before scaling | the draw's start | the factor, the design, its start and redraws |

Every start has heading pi (`mobman_env.env.PAPER_BASE_POSE`); `mobman_env.robots.starts` says how the named
starts were chosen. A random arm is accepted when it passes the start rule of `random_arms` and the kinematic
known-model ceiling `starts.kinematic_ceiling` (whole-body damped least squares on the drawn, nominal design
tracks the paper's circle within 1 mm without meeting a joint limit; the measured acceptance is in
`random_arms`' docstring: about 58% of the draws that pass the start rule, 3.9 draws per arm). It is checked on
the circle for every task: the check costs about 0.2 s per candidate (2000 steps of numpy), the four tasks would
cost four times that per reset. Before its first reset a `random` env's nominal robot is the first draw of
`default_rng(0)` without the ceiling check (the spaces only need n and the speed limits, the same for the whole
family).

May import: numpy, the standard library, `mobman_env.params`, `mobman_env.robots.*`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env.params import RobotParams
from mobman_env.robots.catalogue import ROBOTS
from mobman_env.robots.description import ArmDescription
from mobman_env.robots.random_arms import random_arm, random_scaled_arm
from mobman_env.robots.starts import STARTS, kinematic_ceiling

__all__ = ["ROBOT_NAMES", "RobotSource", "robot_source"]

#: the memo of `RobotSource.draw`: (family, generator state) -> (nominal robot, start, built robot, generator state
#: after)
_DRAWS: dict[tuple[str, str], tuple[RobotParams, tuple[float, ...], RobotParams, Any]] = {}
#: draws kept (least recently used dropped first)
MAX_MEMO = 1024
#: The drawn families: `robot` name -> the function drawing (arm, start) from the env's generator.
FAMILIES = {"random": random_arm, "random-scaled": random_scaled_arm}
#: The accepted values of the env's `robot` argument.
ROBOT_NAMES = (*ROBOTS, *FAMILIES)


@dataclass(frozen=True)
class RobotSource:
    """The robot of an env: a fixed catalogue arm (`arm` set) or the random family (`arm` None)."""

    name: str
    arm: ArmDescription | None

    @property
    def start_is_drawn(self) -> bool:
        """True when every reset draws the start with the arm (then `arm_joint_pos` cannot be given)."""
        return self.arm is None

    @property
    def nominal(self) -> RobotParams:
        """The nominal robot before the first reset (for the random family: a placeholder of the family)."""
        if self.arm is not None:
            return RobotParams.nominal(self.arm)
        draw = FAMILIES[self.name](np.random.default_rng(0))
        return RobotParams.nominal(draw.design or draw.arm)

    @property
    def default_start(self) -> tuple[float, ...] | None:
        """The start configuration (rad, n angles) of a fixed arm; None for the random family."""
        return STARTS[self.name].q0 if self.arm is not None else None

    def draw(self, rng: np.random.Generator) -> tuple[RobotParams, tuple[float, ...], RobotParams] | None:
        """The episode's nominal robot, its start (rad) and the robot built (before wear: the nominal one, except
        for the scaled family, whose catalogue is the design before scaling) drawn from `rng`; None for a fixed arm
        (nothing is drawn: the constructor's nominal robot and start hold).

        A draw is a pure function of the generator's state (its candidates and their ceiling checks, about 0.2 s
        each, use `rng` only), so it is memoised on that state: the same state gives the same arm and leaves the
        generator where the draw left it, without drawing again (a bench resets the same seeds for every
        controller and condition: one draw per seed per process, `_DRAWS`)."""
        if self.arm is not None:
            return None
        key = (self.name, json.dumps(rng.bit_generator.state, sort_keys=True, default=str))
        hit = _DRAWS.get(key)
        if hit is None:
            draw = FAMILIES[self.name](rng, kinematic_ceiling)
            built = RobotParams.nominal(draw.arm)
            catalogue = built if draw.design is None else RobotParams.nominal(draw.design)
            hit = (catalogue, draw.q0, built, rng.bit_generator.state)
            _DRAWS[key] = hit
            while len(_DRAWS) > MAX_MEMO:
                _DRAWS.pop(next(iter(_DRAWS)))
        else:
            _DRAWS[key] = _DRAWS.pop(key)  # most recently used last
            rng.bit_generator.state = hit[3]
        return hit[0], hit[1], hit[2]


def robot_source(name: str) -> RobotSource:
    """The source of robot `name` (one of `ROBOT_NAMES`)."""
    if not isinstance(name, str) or name not in ROBOT_NAMES:
        raise ValueError(
            f"unknown robot {name!r}; accepted: {', '.join(map(repr, ROBOT_NAMES))} (e.g. robot='ur5', or the "
            f"registered ids Wheeled{{Puma,UR5,Panda,RandomArm}}-<task>-v0)"
        )
    return RobotSource(name, ROBOTS.get(name))

"""mobman_env: PyBullet wheeled mobile manipulators for end-effector path tracking (Gymnasium).

Importing this package registers twenty ids (only those not yet registered, so importing twice is silent):
`Wheeled<Robot>-<Task>-v0` for the robots

| robot | `robot=` | arm |
|---|---|---|
| `Puma` | "puma560" | PUMA 560, 6 joints (release 0.1's ids, unchanged) |
| `UR5` | "ur5" | Universal Robots UR5, 6 joints |
| `Panda` | "panda" | Franka Emika Panda, 7 joints (9 actuators) |
| `RandomArm` | "random" | a new random 6-joint arm every reset |
| `ScaledArm` | "random-scaled" | a new random arm with every length scaled by one factor in [0.7, 1.4] every reset (kinematic mode: the masses are the unscaled design's) |

and the tasks

| task | path |
|---|---|
| `Circle` | the paper's circle: radius 0.4 m, tilt pi/6, 20 s |
| `Line` | a 3 m straight line along the heading, 20 s (the platform must drive) |
| `Lemniscate` | a figure eight 0.6 m x 0.3 m, 20 s |
| `Random` | a random smooth path per seed, each axis within 0.3 m, 20 s |

`gym.make("mobman_env:WheeledPuma-Circle-v0")` works without importing this package first. A `robot` argument
that contradicts the id (`gym.make("WheeledUR5-Circle-v0", robot="panda")`) is refused (`RobotEntry`).
`gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", dynamics="kinematic")` returns the native
numpy vector env `mobman_env.vector.WheeledPumaVectorEnv` (physics mode: a `SyncVectorEnv` of single envs).
"""

from __future__ import annotations

import importlib
import inspect
import sys
from typing import Any

from gymnasium.envs.registration import register, registry

from mobman_env.env import OBS_KEYS, PAPER_ARM_JOINT_POS, PAPER_BASE_POSE, PAPER_CIRCLE, WheeledPumaEnv
from mobman_env.params import RobotParams
from mobman_env.paths import TASK_SPECS

__all__ = [
    "ENV_IDS",
    "OBS_KEYS",
    "PAPER_ARM_JOINT_POS",
    "PAPER_BASE_POSE",
    "PAPER_CIRCLE",
    "ROBOT_IDS",
    "ROBOT_TASKS",
    "RobotEntry",
    "RobotParams",
    "WheeledPumaEnv",
    "env_ids",
    "register_envs",
]
#: The one source of mobman's version (pyproject.toml reads it; Semantic Versioning, CHANGELOG.md).
__version__ = "0.4.0.dev0"

#: id -> path spec of each PUMA task (all start at the paper's theta(0), heading pi).
TASKS = {f"WheeledPuma-{name.title()}-v0": spec for name, spec in TASK_SPECS.items()}
#: id prefix -> the env's `robot` argument (the PUMA ids pass none: the default, as in release 0.1).
ROBOT_IDS = {
    "WheeledPuma": "puma560",
    "WheeledUR5": "ur5",
    "WheeledPanda": "panda",
    "WheeledRandomArm": "random",
    "WheeledScaledArm": "random-scaled",
}
#: id -> (robot, path spec) of every registered id, PUMA ids first.
ROBOT_TASKS = {
    env_id.replace("WheeledPuma", prefix, 1): (robot, spec)
    for prefix, robot in ROBOT_IDS.items()
    for env_id, spec in TASKS.items()
}
ENV_IDS = tuple(ROBOT_TASKS)


def env_ids(robot: str) -> tuple[str, ...]:
    """The four task ids of one robot (`robot=` value, e.g. "ur5"), in `TASKS` order."""
    ids = tuple(env_id for env_id, (r, _) in ROBOT_TASKS.items() if r == robot)
    if not ids:
        raise ValueError(f"unknown robot {robot!r}; accepted: {', '.join(map(repr, ROBOT_IDS.values()))}")
    return ids


class RobotEntry:
    """The entry point of the ids of one robot (`entry_point` and `vector_entry_point` of `register_envs`):
    calls `target` ("module:attr": the env class, or the vector env factory) with the id's arguments, but
    refuses a `robot` argument that contradicts the id, so `gym.make("WheeledUR5-Circle-v0", robot="panda")`
    never runs a Panda labelled UR5. Picklable (async vector envs send it to their workers); `metadata` and the
    signature are the env class's, so Gymnasium and `inspect` see the env's arguments."""

    def __init__(self, prefix: str, robot: str, target: str):
        self.prefix, self.robot, self.target = prefix, robot, target
        self.metadata = WheeledPumaEnv.metadata
        self.__signature__ = inspect.signature(WheeledPumaEnv)

    def __reduce__(self) -> tuple:
        # pickled by the class this module holds now, so an entry registered before `importlib.reload(mobman_env)`
        # still pickles (pickle refuses a class that is no longer the module's attribute)
        return (sys.modules[__name__].RobotEntry, (self.prefix, self.robot, self.target))

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        given = kwargs.get("robot", "puma560")
        if given != self.robot:
            other = next((p for p, r in ROBOT_IDS.items() if r == given), None)
            fix = f"use the {other}-* id of the task" if other else f"accepted here: robot={self.robot!r}"
            raise ValueError(
                f"robot={given!r} contradicts the id: {self.prefix}-* ids are the {self.robot!r} robot "
                f"(every record and scorecard names the robot by its id); {fix}, or leave robot unset"
            )
        module, _, attr = self.target.partition(":")
        return getattr(importlib.import_module(module), attr)(*args, **kwargs)


def register_envs() -> None:
    """Register the ids that are not registered yet (harmless and silent when called again)."""
    for env_id, (robot, spec) in ROBOT_TASKS.items():
        if env_id not in registry:
            kwargs: dict = {"path": dict(spec)}
            if robot != "puma560":
                kwargs["robot"] = robot
            prefix = env_id.split("-", 1)[0]
            register(
                id=env_id,
                entry_point=RobotEntry(prefix, robot, "mobman_env.env:WheeledPumaEnv"),
                vector_entry_point=RobotEntry(prefix, robot, "mobman_env.vector:make_vector_env"),
                kwargs=kwargs,
            )


register_envs()

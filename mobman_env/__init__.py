"""mobman_env: a PyBullet wheeled PUMA 560 for end-effector path tracking (Gymnasium).

Importing this package registers four ids (only those not yet registered, so importing twice is silent):

| id | path |
|---|---|
| `WheeledPuma-Circle-v0` | the paper's circle: radius 0.4 m, tilt pi/6, 20 s |
| `WheeledPuma-Line-v0` | a 3 m straight line along the heading, 20 s (the platform must drive) |
| `WheeledPuma-Lemniscate-v0` | a figure eight 0.6 m x 0.3 m, 20 s |
| `WheeledPuma-Random-v0` | a random smooth path per seed, each axis within 0.3 m, 20 s |

`gym.make("mobman_env:WheeledPuma-Circle-v0")` works without importing this package first.
`gym.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point", dynamics="kinematic")` returns the native
numpy vector env `mobman_env.vector.WheeledPumaVectorEnv` (physics mode: a `SyncVectorEnv` of single envs).
"""

from __future__ import annotations

import math

from gymnasium.envs.registration import register, registry

from mobman_env.env import OBS_KEYS, PAPER_ARM_JOINT_POS, PAPER_BASE_POSE, PAPER_CIRCLE, WheeledPumaEnv
from mobman_env.params import RobotParams

__all__ = [
    "ENV_IDS",
    "OBS_KEYS",
    "PAPER_ARM_JOINT_POS",
    "PAPER_BASE_POSE",
    "PAPER_CIRCLE",
    "RobotParams",
    "WheeledPumaEnv",
    "register_envs",
]
#: The one source of mobman's version (pyproject.toml reads it; Semantic Versioning, CHANGELOG.md).
__version__ = "0.2.0.dev0"

#: id -> path spec of each registered task (all start at the paper's theta(0), heading pi).
TASKS = {
    "WheeledPuma-Circle-v0": PAPER_CIRCLE,
    "WheeledPuma-Line-v0": {"type": "line", "length": 3.0, "direction": [-1.0, 0.0, 0.0], "duration": 20.0},
    "WheeledPuma-Lemniscate-v0": {
        "type": "lemniscate",
        "width": 0.6,
        "height": 0.3,
        "tilt": math.pi / 6,
        "yaw": math.pi,
        "duration": 20.0,
    },
    "WheeledPuma-Random-v0": {"type": "random", "size": 0.3, "n_terms": 3, "duration": 20.0},
}
ENV_IDS = tuple(TASKS)


def register_envs() -> None:
    """Register the ids that are not registered yet (harmless and silent when called again)."""
    for env_id, spec in TASKS.items():
        if env_id not in registry:
            register(
                id=env_id,
                entry_point="mobman_env.env:WheeledPumaEnv",
                vector_entry_point="mobman_env.vector:make_vector_env",
                kwargs={"path": dict(spec)},
            )


register_envs()

"""The agent's interface: one observation and one action layout for every robot of the benchmark, with no clock.

Why: an agent trained on one robot must be able to act on another (the dev track has 6- and 7-joint arms), and a
policy that sees the episode's time can memorise one path instead of learning to track (release 0.3's
`sb3:ppo-circle` did: it tracks only its training task). So the agent sees the task as the controllers do, as
an error to remove, and nothing that identifies when in which episode it is.

Action (`N_ACTIONS` = 9, normalised speeds in [-1, 1]): slots 0-6 are arm joints 1-7, slots 7 and 8 the left and
right wheel. A robot with n < 7 arm joints uses slots 0..n-1 and the wheels; slots n..6 are ignored
(`env_action`). The Panda (n = 7) uses all nine; the PUMA, UR5 and the random arms (n = 6) use eight.

Observation (`AGENT_OBS_KEYS`, a dict of float32 arrays; positions in m, velocities in m/s and rad/s). Vectors
of the task are expressed in the platform's heading frame (x forward, y left, z up: rotated by -base_yaw about
z), so the same error asks for the same correction whatever the platform's heading; the heading itself is
given as (cos, sin) (a continuous yaw grows without bound):

| key | shape | meaning |
|---|---|---|
| pos_error | (3,) | target_pos - ee_pos, heading frame, m |
| vel_error | (3,) | target_vel - ee_vel, heading frame, m/s |
| target_vel | (3,) | desired velocity, heading frame, m/s |
| arm_pos | (7,) | arm joint angles, rad; 0 in unused slots |
| joint_vel | (9,) | arm joint speeds (slots 0-6) and wheel speeds (7, 8), rad/s; 0 in unused slots |
| heading | (2,) | cos, sin of base_yaw |
| mask | (9,) | 1 for an actuator the robot has, 0 for a padded slot (the same layout as the action) |

Left out on purpose: `time` (identifies the path), absolute positions (`ee_pos`, `target_pos`, `arm_base_pos`:
the path is fixed in the world, so they too identify where on one path the robot is) and the wheel angles (a
wheel's angle does not change the kinematics).

`agent_observation` and `env_action` are pure numpy functions of batched (N, k) arrays (or unbatched (k,)),
the one definition used by training (`train.vec_env.AgentVecEnv`, which `mobman-train` puts on every training
env) and by running a trained agent (`policies.agents.sb3.SB3Policy`, when the run's config.json lists the `"agent"`
observation wrapper). It lives in `policies` because inference needs it and `policies` may not import `train`.
Imports numpy and gymnasium only.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

#: the largest arm of the benchmark (the Panda)
MAX_ARM_JOINTS = 7
#: 7 arm joint slots + left and right wheel
N_ACTIONS = MAX_ARM_JOINTS + 2
AGENT_OBS_KEYS = ("pos_error", "vel_error", "target_vel", "arm_pos", "joint_vel", "heading", "mask")
_SIZES = {"pos_error": 3, "vel_error": 3, "target_vel": 3, "arm_pos": MAX_ARM_JOINTS, "joint_vel": N_ACTIONS}
_SIZES.update(heading=2, mask=N_ACTIONS, base_action=N_ACTIONS)
#: the training env whose observation is already this interface's (`train.dev_env`); an agent trained on it runs
#: on every registered id (no "trained on another id" warning)
DEV_TRACK_ID = "MobMan-DevTrack-v0"
#: a residual agent's extra observation key: its base controller's action this step, in the 9 slots
BASE_ACTION = "base_action"
#: the env arguments of a residual training run (`train.dev_env`), recorded in the run's config.json, which
#: `policies.agents.sb3.SB3Policy` reads to rebuild the base: a built-in spec, and the residual's share of the limits
RESIDUAL_BASE, RESIDUAL_SCALE = "residual_base", "residual_scale"
DEFAULT_RESIDUAL_SCALE = 0.05
#: the raw env observation keys the agent's observation is computed from
ENV_KEYS = ("ee_pos", "ee_vel", "target_pos", "target_vel", "joint_pos", "joint_vel", "base_yaw")


def observation_space(residual: bool = False) -> spaces.Dict:
    """The agent's observation space (the same for every robot); a residual agent's has `BASE_ACTION` too."""
    big = np.float32(1e4)
    keys = (*AGENT_OBS_KEYS, BASE_ACTION) if residual else AGENT_OBS_KEYS
    return spaces.Dict({k: spaces.Box(-big, big, (_SIZES[k],), np.float32) for k in keys})


def base_action(base: Any, observation: Any, episode_start: Any = None) -> np.ndarray:
    """A residual agent's base controller's action on `observation` (batched or not), in the 9 slots: what the
    agent sees as `BASE_ACTION` and adds its residual to (`residual_action`); the one call of training
    (`train.dev_env`, `train.agent`) and inference (`policies.agents.sb3`)."""
    return agent_action(base.predict(observation, None, episode_start, True)[0])


def residual_action(base: Any, residual: Any, scale: float) -> np.ndarray:
    """A residual agent's command in the 9 slots: its base's action plus `scale` x its own (the env clips the sum
    to the limits); the one formula of training (`train.dev_env`) and inference (`policies.agents.sb3`)."""
    return (np.asarray(base, np.float32) + np.float32(scale) * np.asarray(residual, np.float32)).astype(np.float32)


def action_space() -> spaces.Box:
    """The agent's action space: `N_ACTIONS` normalised speeds (the env clips to [-1, 1] as always)."""
    return spaces.Box(-1.0, 1.0, (N_ACTIONS,), np.float32)


def arm_joints(n_actuators: int) -> int:
    """n, the arm joints of a robot with `n_actuators` = n + 2 actuators; refuses arms larger than the layout."""
    n = int(n_actuators) - 2
    if not 1 <= n <= MAX_ARM_JOINTS:
        raise ValueError(
            f"the agent interface holds arms of 1-{MAX_ARM_JOINTS} joints (+ 2 wheels), got {n_actuators} actuators"
        )
    return n


def _heading_frame(v: np.ndarray, c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """World vectors (..., 3) rotated by -yaw about z (c, s: cos and sin of yaw, shape (..., 1))."""
    x, y = v[..., 0:1], v[..., 1:2]
    return np.concatenate([c * x + s * y, -s * x + c * y, v[..., 2:3]], axis=-1)


def agent_observation(obs: dict[str, Any]) -> dict[str, np.ndarray]:
    """The agent's observation (`AGENT_OBS_KEYS`) from the env's raw observation dict, batched (N, k) or not; an
    observation that is the agent's already (`DEV_TRACK_ID` hands it out) is returned as it is (float32)."""
    if "mask" in obs and "ee_pos" not in obs:
        return {k: np.asarray(v, dtype=np.float32) for k, v in obs.items()}
    missing = [k for k in ENV_KEYS if k not in obs]
    if missing:
        raise KeyError(f"the agent's observation needs the env keys {missing}; the observation has {sorted(obs)}")
    o = {k: np.asarray(obs[k], dtype=np.float32) for k in ENV_KEYS}
    lead = o["ee_pos"].shape[:-1]
    n = arm_joints(o["joint_pos"].shape[-1])
    yaw = o["base_yaw"][..., 0:1]
    c, s = np.cos(yaw), np.sin(yaw)
    arm_pos = np.zeros((*lead, MAX_ARM_JOINTS), np.float32)
    arm_pos[..., :n] = o["joint_pos"][..., :n]
    joint_vel = np.zeros((*lead, N_ACTIONS), np.float32)
    joint_vel[..., :n] = o["joint_vel"][..., :n]
    joint_vel[..., MAX_ARM_JOINTS:] = o["joint_vel"][..., n : n + 2]
    mask = np.zeros((*lead, N_ACTIONS), np.float32)
    mask[..., :n] = 1.0
    mask[..., MAX_ARM_JOINTS:] = 1.0
    out = {
        "pos_error": _heading_frame(o["target_pos"] - o["ee_pos"], c, s),
        "vel_error": _heading_frame(o["target_vel"] - o["ee_vel"], c, s),
        "target_vel": _heading_frame(o["target_vel"], c, s),
        "arm_pos": arm_pos,
        "joint_vel": joint_vel,
        "heading": np.concatenate([c, s], axis=-1),
        "mask": mask,
    }
    if BASE_ACTION in obs:  # a residual agent's base action, already in the slots
        out[BASE_ACTION] = np.asarray(obs[BASE_ACTION], dtype=np.float32)
    return out


def env_action(action: Any, n_actuators: int) -> np.ndarray:
    """The env's action (..., n + 2) from the agent's (..., `N_ACTIONS`): arm slots 0..n-1 and the two wheel
    slots; the padded slots n..6 are dropped."""
    a = np.asarray(action, dtype=np.float32)
    if a.shape[-1] != N_ACTIONS:
        raise ValueError(f"the agent's action has {N_ACTIONS} entries (7 arm slots, 2 wheels), got shape {a.shape}")
    n = arm_joints(n_actuators)
    return np.concatenate([a[..., :n], a[..., MAX_ARM_JOINTS:]], axis=-1)


def agent_action(env_act: Any) -> np.ndarray:
    """The inverse of `env_action` (zeros in the padded slots): the agent's action that commands `env_act`."""
    e = np.asarray(env_act, dtype=np.float32)
    n = arm_joints(e.shape[-1])
    a = np.zeros((*e.shape[:-1], N_ACTIONS), np.float32)
    a[..., :n] = e[..., :n]
    a[..., MAX_ARM_JOINTS:] = e[..., n:]
    return a

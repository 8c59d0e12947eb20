"""Small env wrappers used for training, and the pure observation transform an agent needs at test time.

Observation processing (recorded in the run's `config.json`, so `policies.agents.sb3.SB3Policy` can rebuild it from
the raw env observation):

1. each name in `config["wrappers"]` (in order) adds derived keys to the observation dict — `OBS_WRAPPERS`:
   * `"pos_error"`: adds `pos_error` = target_pos - ee_pos (3, m, world frame), the tracking error vector the
     controllers of the paper feed back. The agent could compute it from the two positions, but after
     per-key normalisation a millimetre is 1e-3 of the positions' spread; given explicitly it is learned
     from in a fraction of the steps.
   * `"agent"` (the default of `mobman-train`): the robot-independent, clock-free interface of
     `policies.agents.agent_interface` (errors in the heading frame, arms padded to 7 joints with a mask; its 9-slot
     action is mapped back to the robot's n + 2 by `train.vec_env.AgentVecEnv` in training and by
     `policies.agents.sb3.SB3Policy` at inference). It replaces the observation: `obs_keys` select among its keys.
2. the dict is reduced to `config["obs_keys"]`, in that order;
3. VecNormalize's running mean / std (`vecnormalize.pkl`) normalise each key.

`transform_observation(obs, wrappers, obs_keys)` does steps 1-2 on an unbatched or batched dict.

Training-only wrappers (not needed to run the agent, so not in `config["wrappers"]`): `AliveBonus` adds a
constant per step, so that with `error_bound` ending episodes early is a loss, not an escape from negative
rewards.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, SupportsFloat

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from policies.agents import agent_interface
from policies.agents.sb3 import AGENT_WRAPPER
from policies.agents.sb3 import OBS_WRAPPERS as AGENT_OBS_TRANSFORMS


def _pos_error_space(space: spaces.Dict) -> spaces.Dict:
    new = dict(space.spaces)
    new["pos_error"] = spaces.Box(-2000.0, 2000.0, (3,), np.float32)
    return spaces.Dict(new)


#: name -> (obs transform, observation-space transform). The transforms are `policies.agents.sb3`'s, the one
#: definition that `SB3Policy` also applies at test time.
OBS_WRAPPERS: dict[str, tuple[Callable[[dict], dict], Callable[[spaces.Dict], spaces.Dict]]] = {
    "pos_error": (AGENT_OBS_TRANSFORMS["pos_error"][0], _pos_error_space),
    # (the dev-track env's space is the agent's already, with a residual agent's base action)
    AGENT_WRAPPER: (
        AGENT_OBS_TRANSFORMS[AGENT_WRAPPER][0],
        lambda space: space if "mask" in space.spaces else agent_interface.observation_space(),
    ),
}


def check_wrappers(names: Sequence[str]) -> None:
    unknown = [n for n in names if n not in OBS_WRAPPERS]
    if unknown:
        raise ValueError(f"unknown observation wrapper(s) {unknown}; known: {', '.join(OBS_WRAPPERS)}")


def transform_observation(obs: dict, wrappers: Sequence[str], obs_keys: Sequence[str]) -> dict:
    """Apply the named observation wrappers, then keep `obs_keys` in that order (works batched or not)."""
    for name in wrappers:
        obs = OBS_WRAPPERS[name][0](obs)
    missing = [k for k in obs_keys if k not in obs]
    if missing:
        raise KeyError(f"observation has no key(s) {missing}; it has {sorted(obs)}")
    return {k: obs[k] for k in obs_keys}


def transform_space(space: spaces.Dict, wrappers: Sequence[str], obs_keys: Sequence[str]) -> spaces.Dict:
    for name in wrappers:
        space = OBS_WRAPPERS[name][1](space)
    missing = [k for k in obs_keys if k not in space.spaces]
    if missing:
        raise ValueError(f"obs_keys {missing} are not in the observation; available: {list(space.spaces)}")
    return spaces.Dict({k: space.spaces[k] for k in obs_keys})


class AgentObservation(gym.ObservationWrapper):
    """The agent's view of one env: named observation wrappers, then the `obs_keys` subset; with the `"agent"`
    wrapper also its 9-slot action (`policies.agents.agent_interface`), mapped to the robot's n + 2 in `step`. (Training
    applies the same view to the whole VecEnv, `train.vec_env.AgentVecEnv`; this is the per-env form for
    rl-baselines3-zoo's `env_wrapper` and for checks.)"""

    def __init__(self, env: gym.Env, wrappers: Sequence[str], obs_keys: Sequence[str]):
        super().__init__(env)
        check_wrappers(wrappers)
        self.wrappers = tuple(wrappers)
        self.obs_keys = tuple(obs_keys)
        if not isinstance(env.observation_space, spaces.Dict):
            raise ValueError(f"AgentObservation needs a Dict observation space, got {env.observation_space}")
        self.observation_space = transform_space(env.observation_space, self.wrappers, self.obs_keys)
        self.n_actuators = int(np.prod(env.action_space.shape or (0,)))
        if AGENT_WRAPPER in self.wrappers:
            agent_interface.arm_joints(self.n_actuators)
            self.action_space = agent_interface.action_space()

    def observation(self, observation: dict) -> dict:
        return transform_observation(observation, self.wrappers, self.obs_keys)

    def step(self, action: Any) -> Any:
        if AGENT_WRAPPER in self.wrappers:
            action = agent_interface.env_action(action, self.n_actuators)
        return super().step(action)


class AliveBonus(gym.RewardWrapper):
    """reward + bonus on every step (training only; `info["reward_terms"]` is left as the env reported it)."""

    def __init__(self, env: gym.Env, bonus: float):
        super().__init__(env)
        self.bonus = float(bonus)

    def reward(self, reward: SupportsFloat) -> SupportsFloat:
        return float(reward) + self.bonus

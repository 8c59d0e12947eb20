"""`Agent`: a trained SB3 model plus its observation processing, behind the project's `Policy` contract.

It is the in-process twin of `policies.agents.sb3.SB3Policy` (which rebuilds the same thing from a run folder): the
raw env observation goes through the named observation wrappers, is reduced to `obs_keys`, normalised with
VecNormalize's statistics (never updated here) and handed to `model.predict`. Used for the periodic
evaluation while training, where the live model and normaliser are evaluated without a round trip to disk.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from policies.agents.agent_interface import BASE_ACTION, base_action, env_action, residual_action
from policies.agents.sb3 import AGENT_WRAPPER
from train.wrappers import transform_observation


class Agent:
    """Policy protocol over an SB3 model. `normalizer`: a VecNormalize (its `normalize_obs` is used) or None."""

    def __init__(
        self,
        model: Any,
        normalizer: Any,
        wrappers: Sequence[str],
        obs_keys: Sequence[str],
        residual: tuple[str, float] | None = None,
    ):
        self.model = model
        self.normalizer = normalizer
        self.wrappers = tuple(wrappers)
        self.obs_keys = tuple(obs_keys)
        #: a residual agent's (base spec, scale) (`train.dev_env`); `bind(env)` builds the base for an env
        self.residual = residual
        self.base: Any = None

    def bind(self, env: Any) -> None:
        """Build a residual agent's base controller for `env` (`train.evaluation.evaluate` calls it)."""
        if self.residual is not None:
            import policies

            self.base = policies.make(self.residual[0], env)

    def reset(self, obs: dict, info: dict | None = None, *, seed: int | None = None) -> None:
        """Stateless agent (MLP policies); a residual agent resets its base."""
        if self.base is not None:
            self.base.reset(obs, info, seed=seed)

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        base_slots = None
        if self.residual is not None:
            if self.base is None:
                raise RuntimeError("a residual agent needs bind(env) before predict (its base controller)")
            base_slots = base_action(self.base, observation, episode_start)
            observation = {**observation, BASE_ACTION: base_slots}
        obs = transform_observation(observation, self.wrappers, self.obs_keys)
        batched = np.asarray(obs[self.obs_keys[0]]).ndim == 2
        obs = {k: np.asarray(v, dtype=np.float32) for k, v in obs.items()}
        if self.normalizer is not None:
            obs = self.normalizer.normalize_obs(obs)
        action, _ = self.model.predict(obs, deterministic=deterministic)
        action = np.asarray(action, dtype=np.float32)
        if batched and action.ndim == 1:
            action = action[None]
        if base_slots is not None and self.residual is not None:
            action = residual_action(base_slots, action, self.residual[1])
        if AGENT_WRAPPER in self.wrappers:  # the interface's 9 slots -> the robot's n + 2 actuators
            action = env_action(action, np.shape(observation["joint_pos"])[-1])
        return action, state

"""`SB3VecEnv`: the native mobman vector env as a Stable-Baselines3 `VecEnv`, so SB3 trains on N robots at once.

```python
import gymnasium as gym, mobman_env
from stable_baselines3 import PPO
from train.vec_env import SB3VecEnv
venv = SB3VecEnv(gym.make_vec("WheeledPuma-Circle-v0", num_envs=64, vectorization_mode="vector_entry_point",
                              dynamics="kinematic", autoreset_mode="SameStep"))
PPO("MultiInputPolicy", venv).learn(10_000)
```

SB3 takes a `stable_baselines3.common.vec_env.VecEnv`, not a `gymnasium.vector.VectorEnv`; its conventions differ:
`reset()` returns only the observation (seeds come from `seed()`, as SB3 sets them: robot i of seed S is a
single env reset with S + i); `step_wait()` returns `dones = terminated | truncated` and, for a robot whose
episode ended, the first observation of its next episode, with the last one in
`infos[i]["terminal_observation"]` and `infos[i]["TimeLimit.truncated"]` (truncated and not terminated). The
adapter therefore needs the Gymnasium env in `AutoresetMode.SAME_STEP` (it raises otherwise, naming the fix).
`infos[i]` also holds `tracking_error` (m, noise-free). Observations are dicts of (N, k) float32 arrays.

Imports Stable-Baselines3 (and so torch) at import time: `policies/__init__.py` does not import this module.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any, cast

import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvWrapper

from policies.agents import agent_interface as interface
from policies.agents.sb3 import AGENT_WRAPPER


class SB3VecEnv(VecEnv):
    """A `VecEnv` view of a `mobman_env.vector.WheeledPumaVectorEnv` in `AutoresetMode.SAME_STEP`."""

    def __init__(self, vector_env: Any):
        mode = getattr(vector_env, "metadata", {}).get("autoreset_mode")
        if mode != AutoresetMode.SAME_STEP:
            raise ValueError(
                f"SB3VecEnv needs a vector env in AutoresetMode.SAME_STEP (SB3 resets a finished env inside the same "
                f"step), got {mode!r}; make it with autoreset_mode='SameStep' (gym.make_vec(..., "
                "autoreset_mode='SameStep'))"
            )
        self.venv = vector_env
        super().__init__(vector_env.num_envs, vector_env.single_observation_space, vector_env.single_action_space)
        self._actions: np.ndarray | None = None

    def reset(self) -> dict[str, np.ndarray]:
        seeds = self._seeds
        seed = None if all(s is None for s in seeds) else list(seeds)
        obs, _ = self.venv.reset(seed=seed, options=self._options[0] if self._options and self._options[0] else None)
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, list[dict]]:
        if self._actions is None:
            raise RuntimeError("step_wait() needs step_async(actions) first")
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        self._actions = None
        dones = terminated | truncated
        err = info["tracking_error"]
        infos: list[dict] = [{"tracking_error": float(e)} for e in err]
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = info["final_obs"][i]
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, rewards.astype(np.float32), dones, infos

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Robot i gets seed + i at the next `reset()` (SB3's rule, and the vector env's)."""
        if seed is None:
            self._seeds = [None] * self.num_envs
        else:
            self._seeds = [seed + i for i in range(self.num_envs)]
        return self._seeds

    def close(self) -> None:
        self.venv.close()

    def _indices(self, indices: int | Iterable[int] | None) -> list[int]:
        if indices is None:
            return list(range(self.num_envs))
        if isinstance(indices, int):
            return [indices]
        return list(indices)

    def get_attr(self, attr_name: str, indices: int | Iterable[int] | None = None) -> list[Any]:
        """The vector env's attribute, once per requested robot (the robots share their constants: dt,
        action_scale, nominal_params, spaces; `true_params` is the robot's own)."""
        if attr_name == "true_params":
            return [self.venv.true_params(i) for i in self._indices(indices)]
        if attr_name in ("observation_space", "action_space"):
            value = getattr(self.venv, "single_" + attr_name)
        else:
            value = getattr(self.venv, attr_name)
        return [value for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: int | Iterable[int] | None = None) -> None:
        raise AttributeError(
            f"SB3VecEnv cannot set {attr_name!r}: the robots of a vector env share one configuration; make a new "
            "vector env with the value as a constructor argument"
        )

    def env_method(self, method_name: str, *args: Any, indices: int | Iterable[int] | None = None, **kwargs: Any):
        raise AttributeError(
            f"SB3VecEnv has no per-robot methods ({method_name!r}): the robots are rows of one numpy env; call the "
            "vector env (SB3VecEnv.venv) directly"
        )

    def env_is_wrapped(self, wrapper_class: type, indices: int | Iterable[int] | None = None) -> list[bool]:
        return [False for _ in self._indices(indices)]


class AgentVecEnv(VecEnvWrapper):
    """The agent's view of a mobman `VecEnv`: the named observation wrappers (`train.wrappers.OBS_WRAPPERS`),
    then the `obs_keys` subset, applied to the batch and to every `terminal_observation` (so SB3's bootstrap of a
    truncated episode sees the same layout). With the `"agent"` wrapper (`policies.agents.agent_interface`) the agent
    acts in the interface's `N_ACTIONS` = 9 slots and the robot's own n + 2 are passed on (padded slots
    dropped); otherwise the env's action space is the agent's.

    One wrapper for every base: `SB3VecEnv` over the native vector env (kinematic) and SB3's `DummyVecEnv` /
    `SubprocVecEnv` of single envs (physics) alike."""

    def __init__(self, venv: VecEnv, wrappers: Sequence[str], obs_keys: Sequence[str]):
        from train.wrappers import check_wrappers, transform_space

        check_wrappers(wrappers)
        self.wrappers, self.obs_keys = tuple(wrappers), tuple(obs_keys)
        self.padded = AGENT_WRAPPER in self.wrappers
        shape = venv.action_space.shape
        self.n_actuators = int(shape[0]) if shape else 0
        action_space = venv.action_space
        if self.padded:
            interface.arm_joints(self.n_actuators)
            action_space = interface.action_space()
        space = transform_space(cast(Any, venv.observation_space), self.wrappers, self.obs_keys)
        super().__init__(venv, observation_space=space, action_space=action_space)

    def _view(self, obs: Any) -> dict[str, np.ndarray]:
        from train.wrappers import transform_observation

        return transform_observation(obs, self.wrappers, self.obs_keys)

    def reset(self) -> dict[str, np.ndarray]:
        return self._view(self.venv.reset())

    def step_async(self, actions: np.ndarray) -> None:
        self.venv.step_async(interface.env_action(actions, self.n_actuators) if self.padded else actions)

    def step_wait(self) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, list[dict]]:
        obs, rewards, dones, infos = self.venv.step_wait()
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = self._view(infos[i]["terminal_observation"])
        return self._view(obs), rewards, dones, infos


class VecAliveBonus(VecEnvWrapper):
    """reward + `bonus` on every step (training only; see `TrainConfig.alive_bonus`)."""

    def __init__(self, venv: VecEnv, bonus: float):
        super().__init__(venv)
        self.bonus = np.float32(bonus)

    def reset(self) -> Any:
        return self.venv.reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        return obs, rewards + self.bonus, dones, infos

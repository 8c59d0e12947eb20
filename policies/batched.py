"""`BatchedPolicy`: one policy object for the N robots of a vector env, speaking SB3's batched `predict`.

```python
venv = gym.make_vec("WheeledPuma-Circle-v0", num_envs=64, vectorization_mode="vector_entry_point",
                    dynamics="kinematic")
policy = policies.make("clik", venv)             # a BatchedPolicy
obs, info = venv.reset(seed=10_000)
policy.reset(obs, info, seed=10_000)             # row i: policy_seed(10_000 + i), as a single env's policy
actions, _ = policy.predict(obs)                 # (64, 8) float32
actions, _ = policy.predict(obs, episode_start=mask)   # re-initialise the rows of mask only
```

Rows. Row i is the single-env policy of the same spec, built for robot i (`_RobotView`: the vector env's dt,
action scale, single observation space and nominal robot; the oracle's true robot is robot i's, read at each of
its episode starts) and fed row i of each batched observation (float32 rows, as a single env hands them out).
So robot i's actions are those of a single policy reset with `policy_seed(S + i)` on the same observations, bit
for bit, for every law: the law is written once, in its single-env class, and this class loops it over the rows
(STYLE 14's "the batched one loops the single kernel"). `zero` needs no loop and is one array. The other laws
loop in Python (their cost per robot-step is that of one single `predict`: `mobman-eval speed` measures it); a
vectorised kernel for a law can replace its loop here without changing this interface.

`reset(obs, info=None, *, seed=None)`: `seed` is the vector env's reset seed S (row i gets `policy_seed(S + i)`,
the documented rule of `policies.base.policy_seed`), or a list of N policy seeds (None entries: no reseed).
`episode_start` (N,) re-initialises the rows where it is True from their observation, as a single policy's
`episode_start` does (its generator continues). `jacobian_estimates()` returns each row's `jacobian_estimate`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from policies.base import policy_seed


def is_vector_env(env: Any) -> bool:
    """Whether `env` is a Gymnasium vector env (it has `num_envs` and `single_observation_space`)."""
    return hasattr(env, "num_envs") and hasattr(env, "single_observation_space")


class _RobotView:
    """What a single-env policy may read of robot i of a vector env (the attributes `policies.make` reads)."""

    def __init__(self, venv: Any, i: int):
        self._venv = venv
        self._i = i
        self.observation_space = venv.single_observation_space
        self.action_space = venv.single_action_space
        self.unwrapped = self

    @property
    def dt(self) -> float:
        return float(self._venv.dt)

    @property
    def action_scale(self) -> np.ndarray:
        return np.asarray(self._venv.action_scale, dtype=float)

    @property
    def nominal_params(self) -> Any:
        return self._venv.nominal_params

    @property
    def true_params(self) -> Any:
        """Robot i's current true robot (the oracle's provider reads it at each episode start)."""
        return self._venv.true_params(self._i)


class BatchedPolicy:
    """N single-env policies as one batched policy (see the module docstring)."""

    def __init__(self, spec: str, rows: Sequence[Any]):
        self.spec = spec
        self.rows = list(rows)
        self.num_envs = len(self.rows)
        self._zero = spec.split(":", 1)[0] == "zero"
        if self._zero:
            self._zero_action = np.zeros((self.num_envs, len(self.rows[0]._scale)), dtype=np.float32)

    @classmethod
    def for_vector_env(cls, spec: str, venv: Any, build: Callable[[str, Any], Any]) -> BatchedPolicy:
        """Build row i with `build(spec, view of robot i)` (`policies.make` passes itself)."""
        if not is_vector_env(venv):
            raise TypeError(f"expected a gymnasium vector env (num_envs, single_observation_space), got {venv!r}")
        return cls(spec, [build(spec, _RobotView(venv, i)) for i in range(venv.num_envs)])

    def reset(self, obs: dict, info: dict | None = None, *, seed: int | Sequence[int | None] | None = None) -> None:
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [policy_seed(int(seed) + i) for i in range(n)]
        else:
            seeds = list(seed)  # type: ignore[arg-type]
            if len(seeds) != n:
                raise ValueError(
                    f"reset(seed=...) needs the vector reset seed S or a list of {n} seeds, got {len(seeds)}"
                )
        for i, row in enumerate(self.rows):
            row.reset(_row(obs, i), None, seed=seeds[i])

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        n = self.num_envs
        first = np.asarray(next(iter(observation.values())))
        if first.ndim != 2 or first.shape[0] != n:
            raise ValueError(
                f"a batched policy of {n} rows needs observations with a leading axis of {n}, got shape {first.shape}"
            )
        starts = np.zeros(n, dtype=bool) if episode_start is None else np.asarray(episode_start, dtype=bool).reshape(n)
        if self._zero:
            for j in np.flatnonzero(starts).tolist():
                self.rows[j]._start(None)
            return self._zero_action.copy(), state
        out = np.empty((n, len(self.rows[0]._scale)), dtype=np.float32)
        for i, row in enumerate(self.rows):
            out[i] = row.predict(_row(observation, i), None, starts[i : i + 1], deterministic)[0]
        return out, state

    def jacobian_estimates(self) -> list[np.ndarray | None]:
        """Each row's current `jacobian_estimate` (None where a row has none)."""
        return [getattr(row, "jacobian_estimate", None) for row in self.rows]


def _row(observation: dict, i: int) -> dict:
    return {k: v[i] for k, v in observation.items()}

"""Several controllers on one vector env: `StackedPolicy` holds one batched policy per consecutive block of rows,
each built with `policies.make(spec, VectorEnvRows(venv, rows))` (row j of the block is robot rows.start + j),
and is itself a `policies.batched.BatchedPolicy`. `eval` steps the kinematic episodes of every built-in
controller of a condition through one vector env this way (`eval.execution.batches`): the vector env's cost per
step is mostly fixed, so one env of 7 x 20 robots costs less than 7 of 20.

```python
venv = gym.make_vec("WheeledPuma-Circle-v0", num_envs=6, vectorization_mode="vector_entry_point",
                    dynamics="kinematic")
rows = (slice(0, 3), slice(3, 6))
policy = StackedPolicy([(policies.make(spec, VectorEnvRows(venv, r)), r) for spec, r in zip(("clik", "nnbc"), rows)])
obs, info = venv.reset(seed=[10_000, 10_001, 10_002, 10_000, 10_001, 10_002])
policy.reset(obs, info, seed=[policy_seed(s) for s in (10_000, 10_001, 10_002) * 2])
actions, _ = policy.predict(obs)   # rows 0-2: clik's, rows 3-5: nnbc's, each bit for bit its own batched policy
```

Imports numpy, the standard library and `policies.batched`.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from policies.batched import BatchedPolicy, _VectorEnvPart, check_vector_env, info_rows


class VectorEnvRows(_VectorEnvPart):
    """The robots `rows` (a slice) of a vector env, seen as a vector env of their own for `policies.make`: row j
    is robot rows.start + j (its true robot too); spaces, dt, action scale and nominal robot are the env's.
    `StackedPolicy` builds its parts on these views."""

    def __init__(self, venv: Any, rows: slice):
        check_vector_env(venv)
        self._venv = venv
        self._start = rows.start or 0
        self.num_envs = len(range(venv.num_envs)[rows])
        self.single_observation_space = venv.single_observation_space
        self.single_action_space = venv.single_action_space
        self.unwrapped = self

    def true_params(self, j: int) -> Any:
        """Row j's current true robot: robot rows.start + j of the underlying vector env."""
        return self._venv.true_params(self._start + j)

    def true_actuator_tau(self, j: int) -> float:
        """Row j's actuator lag this episode, s: robot rows.start + j's."""
        return float(self._venv.true_actuator_tau(self._start + j))

    def nominal_params_of(self, j: int) -> Any:
        """Row j's nominal robot: robot rows.start + j's of the underlying vector env."""
        from policies.registry import nominal_of

        return nominal_of(self._venv, self._start + j)


class StackedPolicy(BatchedPolicy):
    """Several batched policies over consecutive blocks of rows of one vector env, as one batched policy: each
    part acts on its rows' observations (`parts`: (policy, slice) in row order, covering 0 .. N - 1), so
    episodes of several controllers step through one vector env. Row i's actions are those of its part's row,
    bit for bit. `row_us` holds, after each `predict`, every row's share of its part's wall time (us): the
    part's call time divided by its rows, what eval records as `predict_us`."""

    def __init__(self, parts: Sequence[tuple[Any, slice]]):
        self.parts = list(parts)
        self.spec = "+".join(dict.fromkeys(str(getattr(pol, "spec", "?")) for pol, _ in self.parts))
        end = 0
        for _, sl in self.parts:
            if sl.start != end or sl.stop <= sl.start:
                raise ValueError(
                    f"StackedPolicy parts must be consecutive non-empty row slices from row 0, got "
                    f"{[(r.start, r.stop) for _, r in self.parts]}"
                )
            end = sl.stop
        self.num_envs = end
        self.row_us = np.zeros(self.num_envs)

    @property
    def rows(self) -> list[Any]:  # type: ignore[override]
        return [row for pol, _ in self.parts for row in pol.rows]

    def reset(self, obs: dict, info: dict | None = None, *, seed: int | Sequence[int | None] | None = None) -> None:
        seeds = self._seeds(seed)
        for pol, sl in self.parts:
            pol.reset({k: v[sl] for k, v in obs.items()}, info_rows(info, sl), seed=seeds[sl])

    def predict(self, observation: dict, state: Any = None, episode_start: Any = None, deterministic: bool = True):
        self._check(observation)
        starts = self._starts(episode_start)
        out: np.ndarray | None = None
        clock = time.perf_counter
        for pol, sl in self.parts:
            t0 = clock()
            part_starts = None if starts is None else starts[sl]
            actions, _ = pol.predict({k: v[sl] for k, v in observation.items()}, None, part_starts, deterministic)
            self.row_us[sl] = (clock() - t0) * 1e6 / (sl.stop - sl.start)
            if out is None:
                out = np.empty((self.num_envs, np.shape(actions)[1]), dtype=np.float32)
            out[sl] = actions
        return out, state

    def jacobian_estimates(self) -> list[np.ndarray | None]:
        return [J for pol, _ in self.parts for J in pol.jacobian_estimates()]

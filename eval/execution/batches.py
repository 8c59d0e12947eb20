"""Batches: the kinematic episodes that can share one vector env run together, through `eval.rollout.rollout_batch`.

`plan_units(config, user, tasks)` cuts the task list into *units*, each run by one process (or Ray
task) with `UnitRunner.run`: a batch of N episodes stepped together through one native vector env
(`mobman_env.vector.WheeledPumaVectorEnv`) and one batched policy (`policies.make(spec, vector_env)`; for the
episodes of several controllers, one per controller over its block of rows, stacked:
`policies.stacked.StackedPolicy`), or a single episode on the single path (`eval.execution.tasks.Executor`, the
one rollout loop of `eval.rollout`).

**Which tasks batch.** `config.batch_size` > 1 and:

* dynamics "kinematic" (physics mode has a PyBullet world per robot: nothing to batch);
* a built-in policy spec: a name of `policies.KNOWN_POLICIES`, with or without options (`nnbc:gamma=20`).
  The user's policy objects (`eval.run(..., policies={...})`) and `module:attr` specs stay single: a batched
  policy would build one object per robot from a view of the vector env (a factory may expect the real env,
  or hand back one shared object) and would not pass a recurrent `state` back. `sb3:` agents batch: one
  predict for the N rows where the agent's deterministic action is computed row by row
  (`policies.batched.BatchedAgent`, `policies.agents.sb3_actor`: PPO and A2C MLPs), else a loop of the agent per
  robot (SAC, TD3: the single path's bits, at its cost).
* an env whose vector env is native: ids whose `gym.make_vec(..., vectorization_mode="vector_entry_point")` is
  not a `WheeledPumaVectorEnv` (`robot="random"`, which falls back to a `SyncVectorEnv`, or another package's
  env) or cannot be built run single; that is found out once per condition, when its first batch is built.

Tasks of the same env id and condition (`Task.env_key`: env id, dynamics, model error, sensor noise and the
condition's name, which means one set of env arguments within a grid), whatever their built-in policy spec, form
a group: the vector env's cost per step is mostly fixed (about 0.3 ms
at N = 20 against 2-3 us per robot more), so `mobman-eval paper`'s seven controllers x 20 seeds share 2-3 vector
envs instead of taking seven. A group is cut in order (the tasks are policy-major, so each controller's
episodes are consecutive rows) into the fewest batches of `unit_size` episodes at most (`config.batch_size`,
and with `config.workers` > 1 no more than ceil(batchable episodes / workers), so that every worker gets batches),
their sizes differing by one at most. A batch smaller than `MIN_BATCH` (4) runs as single episodes: the vector
env's fixed cost per step makes small batches slower than the single path (see `MIN_BATCH`). Units keep the
order of the tasks' first appearance; local workers are dealt units round-robin.

**Seeds.** A batch takes any N seeds: `venv.reset(seed=[s_0, ...])` (robot i bit-identical to a single env
reset with seed s_i, as Gymnasium's vector envs take a list) and the batched policy's rows reseeded with
`policy_seed(s_i)`, so a sweep's seed list batches as well as `run`'s consecutive seeds.

**Same results.** Every record and array of a batched episode equals the single path's, timing fields
(`wall_s`, `predict_us_*`) and `pid` excepted (`tests/test_eval_batching.py`): the vector env and the batched
policy's rows are bit-identical to their single counterparts, for chaotic controllers too. `wall_s` of a batched
episode is the batch's wall time / N, `predict_us_*` the batched call's time / robots served.

**Failure isolation.** If a batch raises (`rollout_batch` then fails all its records) or its vector env or
batched policy cannot be built, each of its episodes runs again on the single path, so only the episodes that
really fail are recorded failed, each with its own traceback. The failed batch's env and policy are dropped.

**Interruption.** Ctrl-C (KeyboardInterrupt) is never caught here: the episodes of the batch that was running
are lost (the runner records them "interrupted"), those of finished units are kept. `UnitRunner.run` is a
generator, so the episodes of a single unit or of a fallback reach the caller (progress bar, sweep journal) as
each ends; a batch's all at once, when it ends.

Imports `eval.config`, `eval.rollout`, `eval.execution.tasks`, `policies` (its registry
names) and `mobman_env.vector`.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from typing import Any

from eval.config import EvalConfig
from eval.execution.tasks import Executor, Task
from eval.rollout import make_policy, make_vector_env, rollout_batch

#: The smallest batch worth a vector env. Below it the vector env's fixed cost per step (about 0.3 ms, the
#: `mobman-eval speed` figure at N = 1) outweighs what it saves over N single env steps (about 80 us each) while the
#: laws still loop per robot (`policies.batched`). Measured with `rollout_batch` vs `rollout`, CPU time per 5 s
#: episode, at load average 9 on 2 cores: batch of 2: 0.66x (nnbc), 0.77x (clik), 0.88x (zero) the speed of single
#: episodes; 4: 1.02x, 1.10x, 1.65x; 8: 1.35x, 1.47x, 3.19x; 16: 1.64x, 2.20x, 5.93x.
MIN_BATCH = 4


def batch_key(config: EvalConfig, user: dict, task: Task) -> tuple | None:
    """The key of the tasks that can share a vector env and batched policy with `task`; None: run it single."""
    if config.batch_size <= 1 or task.dynamics != "kinematic" or task.policy in user:
        return None
    from policies import KNOWN_POLICIES

    name = task.policy.partition(":")[0]
    if name not in KNOWN_POLICIES and name != "sb3":  # module:attr
        return None
    return task.env_key()


def unit_size(config: EvalConfig, n_batchable: int, workers: int) -> int:
    """The largest batch: `config.batch_size`, and with `workers` > 1 at most ceil(n_batchable / workers)."""
    if workers <= 1:
        return config.batch_size
    return max(1, min(config.batch_size, math.ceil(n_batchable / workers)))


def plan_units(config: EvalConfig, user: dict, tasks: list[Task]) -> list[list[Task]]:
    """The tasks cut into units (batches, and single tasks as units of one) for `config.workers` processes; see
    the module docstring."""
    groups: dict[Any, list[Task]] = {}
    n_batchable = 0
    for task in tasks:
        key = batch_key(config, user, task)
        if key is None:
            key = ("single", task.index)
        else:
            n_batchable += 1
        groups.setdefault(key, []).append(task)
    size = unit_size(config, n_batchable, config.workers)
    units: list[list[Task]] = []
    for group in groups.values():
        n = len(group)
        k = math.ceil(n / size)  # the fewest batches of at most `size`, balanced
        for a, b in zip([i * n // k for i in range(k)], [(i + 1) * n // k for i in range(k)]):
            chunk = group[a:b]
            if len(chunk) >= MIN_BATCH:
                units.append(chunk)
            else:
                units.extend([t] for t in chunk)
    return units


class UnitRunner:
    """Runs units in one process: batches through cached vector envs (the `Executor.MAX_ENVS` most recently used
    kept) and batched policies built per batch, single episodes and fallbacks through an `Executor`."""

    def __init__(self, config: EvalConfig, user: dict):
        self.config = config
        self.user = user
        self.single = Executor(config, user)
        self._batched: dict[tuple, Any] = {}  # (key, n) -> vector env; LRU order
        self._unbatchable: set[tuple] = set()  # keys whose vector env is not native or cannot be built

    def run(self, unit: list[Task]) -> Iterator[tuple[Task, dict, dict | None]]:
        """Yield (task, record, arrays) for every task of `unit`, as each ends (a batch's when the batch ends)."""
        if len(unit) > 1:
            done = self._run_batch(unit)
            if done is not None:
                yield from done
                return
        for task in unit:
            rec, arrays = self.single.run(task)
            yield task, rec, arrays

    def _run_batch(self, unit: list[Task]) -> list[tuple[Task, dict, dict | None]] | None:
        """The batch's results, or None when it must run on the single path (see the module docstring)."""
        key = batch_key(self.config, self.user, unit[0])
        if key is None or key in self._unbatchable:
            return None
        venv = self._vector_env(key, unit[0], len(unit))
        if venv is None:
            return None
        policy = self._policy(venv, unit)
        if policy is None:
            return None
        meta = [
            {"env": t.env, "policy": t.policy, "condition": t.condition_of(self.config), "episode": t.episode}
            for t in unit
        ]
        try:
            results = rollout_batch(
                venv,
                policy,
                [t.seed for t in unit],
                tolerance=self.config.tolerance,
                settle_time=self.config.settle_time,
                meta=meta,
            )
        except KeyboardInterrupt:
            raise
        except BaseException:  # outside its episode loop (it records what fails inside): run the episodes singly
            results = []
        if not results or any(rec["status"] != "ok" for rec, _ in results):
            self._batched.pop((key, len(unit)), None)
            venv.close()
            return None
        return [(t, rec, arrays) for t, (rec, arrays) in zip(unit, results)]

    def _vector_env(self, key: tuple, task: Task, n: int) -> Any:
        """The cached vector env of `key` for `n` robots; None (and `key` remembered) if the env's vector env is
        not native or cannot be built."""
        from mobman_env.vector import WheeledPumaVectorEnv

        if (key, n) in self._batched:
            self._batched[(key, n)] = self._batched.pop((key, n))  # most recently used last
            return self._batched[(key, n)]
        venv = None
        try:
            venv = make_vector_env(
                task.env, n, task.dynamics, task.model_error, task.obs_noise, task.kwargs(self.config)
            )
            if not isinstance(venv.unwrapped, WheeledPumaVectorEnv):
                raise TypeError(f"{task.env}: not a native vector env")
        except KeyboardInterrupt:
            raise
        except BaseException:  # the single path builds it again and records its error per episode
            if venv is not None:
                venv.close()
            self._unbatchable.add(key)
            return None
        while len(self._batched) >= Executor.MAX_ENVS:
            self._batched.pop(next(iter(self._batched))).close()
        self._batched[(key, n)] = venv
        return venv

    def _policy(self, venv: Any, unit: list[Task]) -> Any:
        """One batched policy for the unit's rows: the spec's for one controller, else one per run of equal specs
        stacked (`policies.stacked.StackedPolicy`); None if one cannot be built (the episodes then run singly, each
        recording its own error)."""
        from policies.stacked import StackedPolicy, VectorEnvRows

        runs: list[tuple[str, slice]] = []
        start = 0
        for spec, group in itertools.groupby(task.policy for task in unit):
            end = start + len(list(group))
            runs.append((spec, slice(start, end)))
            start = end
        try:
            if len(runs) == 1:
                return make_policy(runs[0][0], venv, self.config.seed)
            return StackedPolicy(
                [(make_policy(spec, VectorEnvRows(venv, rows), self.config.seed), rows) for spec, rows in runs]
            )
        except KeyboardInterrupt:
            raise
        except BaseException:
            return None

    def close(self) -> None:
        for venv in self._batched.values():
            venv.close()
        self._batched.clear()
        self.single.close()

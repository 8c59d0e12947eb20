"""Tasks: one `Task` describes one episode completely; an `Executor` runs tasks in this process.

A `Task` describes one episode completely (env id, dynamics, policy, seed, model error, sensor noise); `run`
fills them from its config, a sweep (`eval.sweep`) gives every task its own condition. Each process builds
each env (per id, dynamics, model error and noise) and each policy (per env) once and reuses them (the
`Executor.MAX_ENVS` most recently used envs are kept); every episode starts from `env.reset(seed)` and
`policy.reset(..., seed=policy_seed(seed))`, so results do not depend on which process runs an episode or what it ran before
(physics mode included: tested bit-identical). A worker that dies marks its unfinished episodes failed.
`config.backend == "ray"` hands the tasks to `eval.execution.ray_backend` instead (`eval.execution.dispatch.execute` chooses).
Kinematic episodes of built-in specs are batched by `eval.execution.batches`, which falls back on `Executor.run`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from eval.config import EvalConfig
from eval.rollout import make_env, make_policy, rollout


@dataclass(frozen=True)
class Task:
    """One episode, completely (a frozen record rather than a NamedTuple: its field `index` would hide
    `tuple.index`)."""

    index: int
    """Position in results["episodes"]."""
    env: str
    """Env id."""
    dynamics: str
    """Dynamics mode."""
    policy: str
    """Policy spec (or the name of a user's policy object)."""
    episode: int
    """k: the k-th seed of the run (run: seed S + k)."""
    seed: int
    """`env.reset(seed=seed)` and `policy.reset(..., seed=policy_seed(seed))`."""
    model_error: float | None
    """Env argument; None: the env's default."""
    obs_noise: float | None
    """Env argument; None: the env's default."""
    condition: str = ""
    """The name of the episode's condition (`eval.conditions`), which its record carries; "": named from the env
    arguments (`eval.conditions.condition_name`)."""
    env_kwargs: Mapping[str, Any] | None = None
    """The further env arguments of this episode (a bench's condition's); None: the run's (`EvalConfig.env_kwargs`).
    Within one grid a condition name means one set of them."""

    def kwargs(self, config: EvalConfig) -> dict[str, Any]:
        """The further env arguments this episode's env is built with."""
        return dict(config.env_kwargs if self.env_kwargs is None else self.env_kwargs)

    def condition_of(self, config: EvalConfig) -> str:
        """The name of this episode's condition (its own, or the one its env arguments make)."""
        if self.condition:
            return self.condition
        from eval.conditions import condition_name

        axes = {"dynamics": self.dynamics, "model_error": self.model_error, "obs_noise": self.obs_noise}
        return condition_name({**self.kwargs(config), **axes})

    def env_key(self) -> tuple:
        """What identifies this episode's env within a grid (a condition name means one set of env arguments)."""
        return (self.env, self.dynamics, self.model_error, self.obs_noise, self.condition)


class Executor:
    """Runs tasks in one process, building each env (per id, dynamics, model error and noise) and policy (per
    env) once; beyond `MAX_ENVS` envs the least recently used one is closed with its policies."""

    #: envs kept open per process: each holds a PyBullet client (about 25 MB); a sweep visits its conditions
    #: one after the other, so a few suffice
    MAX_ENVS = 8

    def __init__(self, config: EvalConfig, user: dict):
        self.config = config
        self.user = user
        self._envs: dict[tuple, Any] = {}  # insertion order = least recently used first
        self._policies: dict[tuple, Any] = {}

    def env(self, task: Task):
        key = task.env_key()
        if key in self._envs:
            self._envs[key] = self._envs.pop(key)  # most recently used last
        else:
            while len(self._envs) >= self.MAX_ENVS:
                old = next(iter(self._envs))
                self._envs.pop(old).close()
                self._policies = {k: v for k, v in self._policies.items() if k[0] != old}
            self._envs[key] = make_env(
                task.env, task.dynamics, task.model_error, task.obs_noise, task.kwargs(self.config)
            )
        return self._envs[key]

    def policy(self, task: Task):
        if task.policy in self.user:
            return self.user[task.policy]
        env = self.env(task)
        key = (task.env_key(), task.policy)
        if key not in self._policies:
            self._policies[key] = make_policy(task.policy, env, self.config.seed)
        return self._policies[key]

    def run(self, task: Task) -> tuple[dict, dict | None]:
        meta = {
            "env": task.env,
            "policy": task.policy,
            "condition": task.condition_of(self.config),
            "episode": task.episode,
        }
        try:
            env = self.env(task)
            pol = self.policy(task)
        except KeyboardInterrupt:
            raise
        except BaseException:  # SystemExit from a user's constructor too: a failed episode, not a stopped run
            import traceback

            rec = {
                **meta,
                "seed": task.seed,
                "dynamics": task.dynamics,
                "model_error": task.model_error,
                "obs_noise": task.obs_noise,
                "status": "failed",
                "error": traceback.format_exc(),
                "success": False,
                "wall_s": 0.0,
                "pid": os.getpid(),
            }
            return rec, None
        return rollout(
            env, pol, task.seed, tolerance=self.config.tolerance, settle_time=self.config.settle_time, meta=meta
        )

    def close(self) -> None:
        for env in self._envs.values():
            env.close()
        self._envs.clear()
        self._policies.clear()


def keep_arrays(config: EvalConfig, task: Task) -> bool:
    """Episode 0 of every condition is kept for the plots; all of them with save_arrays="all"; none when
    nothing uses them (save_arrays="none" and no plots)."""
    if config.save_arrays == "none" and not config.plots:
        return False
    return task.episode == 0 or config.save_arrays == "all"


def failed_record(task: Task, message: str, status: str = "failed") -> dict:
    """The record of an episode that produced no result (its worker process died, its Ray task failed; with
    status "interrupted": it never ran because the run was stopped)."""
    return {
        "env": task.env,
        "policy": task.policy,
        "condition": task.condition or None,
        "episode": task.episode,
        "seed": task.seed,
        "dynamics": task.dynamics,
        "model_error": task.model_error,
        "obs_noise": task.obs_noise,
        "status": status,
        "error": message,
        "success": False,
        "wall_s": None,
        "pid": None,
    }


#: The error text of an episode that did not finish because the run was interrupted.
INTERRUPTED_TEXT = "not run: the run was interrupted (Ctrl-C) before this episode finished"


def interrupted_record(task: Task) -> dict:
    """The record of an episode cut short or never started by Ctrl-C (status "interrupted")."""
    return failed_record(task, INTERRUPTED_TEXT, status="interrupted")


class ExecutionInterrupted(KeyboardInterrupt):
    """Ctrl-C while tasks ran; `records` and `arrays` ({index: ...}) hold the episodes that finished, and the
    worker processes are already stopped."""

    def __init__(self, records: dict[int, dict], arrays: dict[int, dict]):
        super().__init__("interrupted")
        self.records = records
        self.arrays = arrays


def make_tasks(config: EvalConfig, names: list[str]) -> list[Task]:
    """The episodes of a `run`: env, dynamics, policy, seed; each dynamics mode is one condition, named from the
    run's env arguments (`eval.conditions.condition_name`)."""
    tasks: list[Task] = []
    for env_id in config.envs:
        for dyn in config.dynamics:
            cond = Task(0, env_id, dyn, "", 0, 0, config.model_error, config.obs_noise).condition_of(config)
            for name in names:
                for k in range(config.episodes):
                    tasks.append(
                        Task(
                            len(tasks),
                            env_id,
                            dyn,
                            name,
                            k,
                            config.seed + k,
                            config.model_error,
                            config.obs_noise,
                            cond,
                        )
                    )
    return tasks

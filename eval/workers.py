"""Running episodes: in this process, dealt round-robin to N spawned worker processes, or as Ray tasks.

A `Task` describes one episode completely (env id, dynamics, policy, seed, model error, sensor noise); `run`
fills them from its config, a sweep (`eval.sweep`) gives every task its own condition. Each process builds
each env (per id, dynamics, model error and noise) and each policy (per env) once and reuses them (the
`Executor.MAX_ENVS` most recently used envs are kept); every episode starts from `env.reset(seed)` and
`policy.reset(..., seed=seed)`, so results do not depend on which process runs an episode or what it ran before
(physics mode included: tested bit-identical). A worker that dies marks its unfinished episodes failed.
`config.backend == "ray"` hands the tasks to `eval.ray_backend` instead.
"""

from __future__ import annotations

import os
import pickle
from typing import Any, NamedTuple

from eval.checks import make_policy
from eval.config import EvalConfig
from eval.rollout import make_env, rollout


class Task(NamedTuple):
    index: int  # position in results["episodes"]
    env: str
    dynamics: str
    policy: str
    episode: int  # k: the k-th seed of the run (run: seed S + k)
    seed: int  # env.reset(seed=seed) and policy.reset(..., seed=seed)
    model_error: float | None  # env argument; None: the env's default
    obs_noise: float | None  # env argument; None: the env's default


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
        key = (task.env, task.dynamics, task.model_error, task.obs_noise)
        if key in self._envs:
            self._envs[key] = self._envs.pop(key)  # most recently used last
        else:
            while len(self._envs) >= self.MAX_ENVS:
                old = next(iter(self._envs))
                self._envs.pop(old).close()
                self._policies = {k: v for k, v in self._policies.items() if k[0] != old}
            self._envs[key] = make_env(
                task.env, task.dynamics, task.model_error, task.obs_noise, self.config.env_kwargs
            )
        return self._envs[key]

    def policy(self, task: Task):
        if task.policy in self.user:
            return self.user[task.policy]
        env = self.env(task)
        key = ((task.env, task.dynamics, task.model_error, task.obs_noise), task.policy)
        if key not in self._policies:
            self._policies[key] = make_policy(task.policy, env, self.config.seed)
        return self._policies[key]

    def run(self, task: Task) -> tuple[dict, dict | None]:
        meta = {"env": task.env, "policy": task.policy, "episode": task.episode}
        try:
            env = self.env(task)
            pol = self.policy(task)
        except Exception:
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
        return rollout(env, pol, task.seed, tolerance=self.config.tolerance, meta=meta)

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


def _worker_main(wid: int, config: EvalConfig, user_bytes: bytes | None, tasks: list[Task], out) -> None:
    """Entry point of one worker process: run `tasks` in order, send each result through the pipe `out`."""
    user = pickle.loads(user_bytes) if user_bytes else {}
    ex = Executor(config, user)
    try:
        for task in tasks:
            rec, arrays = ex.run(task)
            out.send(("result", task.index, rec, arrays if keep_arrays(config, task) else None))
    finally:
        ex.close()
        out.send(("done", wid, None, None))
        out.close()


def failed_record(task: Task, message: str) -> dict:
    """The record of an episode that produced no result (its worker process died, its Ray task failed)."""
    return {
        "env": task.env,
        "policy": task.policy,
        "episode": task.episode,
        "seed": task.seed,
        "dynamics": task.dynamics,
        "model_error": task.model_error,
        "obs_noise": task.obs_noise,
        "status": "failed",
        "error": message,
        "success": False,
        "wall_s": None,
        "pid": None,
    }


def execute(
    config: EvalConfig, user: dict, tasks: list[Task], user_bytes: bytes | None = None, on_result=None
) -> tuple[dict[int, dict], dict[int, dict]]:
    """Run `tasks`; returns ({index: record}, {index: arrays}). `on_result(record)` is called as each ends."""
    if config.backend == "ray":
        from eval.ray_backend import execute_ray

        return execute_ray(config, user, tasks, on_result)
    records: dict[int, dict] = {}
    arrays: dict[int, dict] = {}

    def take(index, rec, arr):
        records[index] = rec
        if arr is not None:
            arrays[index] = arr
        if on_result is not None:
            on_result(rec)

    n_workers = min(config.workers, len(tasks))
    if n_workers <= 1:
        ex = Executor(config, user)
        try:
            for task in tasks:
                rec, arr = ex.run(task)
                take(task.index, rec, arr if keep_arrays(config, task) else None)
        finally:
            ex.close()
        return records, arrays

    import multiprocessing as mp
    from multiprocessing.connection import wait

    # one pipe per worker: send() is synchronous, so a result sent before a crash is never lost
    ctx = mp.get_context("spawn")
    shares = [tasks[i::n_workers] for i in range(n_workers)]
    readers, procs = [], []
    with _single_threaded_children():
        for i in range(n_workers):
            r, w = ctx.Pipe(duplex=False)
            p = ctx.Process(
                target=_worker_main,
                args=(i, config, user_bytes, shares[i], w),
                daemon=True,
                name=f"mobman-eval-worker-{i}",
            )
            p.start()
            w.close()  # the parent keeps only the read end: EOF when the worker is gone
            readers.append(r)
            procs.append(p)
    active = set(range(n_workers))
    try:
        while active:
            wait([readers[i] for i in active] + [procs[i].sentinel for i in active])
            for i in sorted(active):
                if _read_available(readers[i], take):
                    active.discard(i)  # said "done"
                elif not procs[i].is_alive():
                    _read_available(readers[i], take)
                    procs[i].join()
                    active.discard(i)
                    for t in shares[i]:
                        if t.index not in records:
                            take(
                                t.index,
                                failed_record(
                                    t,
                                    (
                                        f"worker process {procs[i].pid} died with exit code {procs[i].exitcode} (its error "
                                        f"is on stderr; a script that calls eval.run with workers > 1 needs an "
                                        f"`if __name__ == '__main__':` guard)"
                                    ),
                                ),
                                None,
                            )
    finally:
        for p in procs:
            p.join(timeout=10)
            if p.is_alive():
                p.terminate()
        for r in readers:
            r.close()
    for t in tasks:  # a worker that stopped early (it reports its own error on stderr)
        if t.index not in records:
            take(t.index, failed_record(t, "the worker process stopped before running this episode"), None)
    return records, arrays


#: Thread-pool sizes for worker processes: one process per core is the parallelism; BLAS / OpenMP thread pools
#: on top of it would only oversubscribe the cores.
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


class _single_threaded_children:
    """Set the thread-pool variables to 1 (unless the user set them) while worker processes are spawned."""

    def __enter__(self):
        self._saved = {k: os.environ.get(k) for k in _THREAD_VARS}
        for k in _THREAD_VARS:
            os.environ.setdefault(k, "1")

    def __exit__(self, *exc):
        for k, v in self._saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _read_available(conn, take) -> bool:
    """Take every message waiting on `conn`; True once the worker said "done" (or its pipe is closed)."""
    try:
        while conn.poll():
            kind, a, rec, arr = conn.recv()
            if kind == "done":
                return True
            take(a, rec, arr)
    except (EOFError, OSError):
        return False
    return False


def make_tasks(config: EvalConfig, names: list[str]) -> list[Task]:
    tasks = []
    for env_id in config.envs:
        for dyn in config.dynamics:
            for name in names:
                for k in range(config.episodes):
                    tasks.append(
                        Task(len(tasks), env_id, dyn, name, k, config.seed + k, config.model_error, config.obs_noise)
                    )
    return tasks

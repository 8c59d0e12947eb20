"""The rollout loop of `eval.rollout` for N episodes at once: one vector env, one batched policy.

```
obs, info = venv.reset(seed=S)                 # robot i: the single env's episode of seed S + i
policy.reset(obs, info, seed=S)                # row i: policy_seed(S + i), as rollout() seeds a policy
repeat: actions, _ = policy.predict(obs)       # one call for every robot still running
        obs, reward, terminated, truncated, info = venv.step(actions)
```

`seed` may also be a list of N seeds, one per robot, in any order (robot i: the single env's episode of
`seed[i]`; `venv.reset(seed=[...])` and `policy.reset(..., seed=[policy_seed(s) ...])`, as Gymnasium's vector
envs take a list), which is how `eval.execution` batches a sweep's arbitrary seeds; `meta` may likewise be one
dict per robot (the `episode` field differs between them).

`rollout_batch` returns, for each robot i, the (record, arrays) that `eval.rollout.rollout` returns for the
episode of seed S + i (or `seed[i]`) with the same policy spec: the vector env (`mobman_env.vector`) is
bit-identical to the single env, and a batched policy's row i acts bit for bit as the single-env policy (a
vectorised law of `policies.kernels` whose single-env class is its N = 1 case, or the single law looped per row:
`policies.batched`), so every array and metric is equal, for chaotic controllers too
(`tests/test_batch_rollout.py`). What differs is the timing: `predict_us` of
a row is the batched call's wall time divided by the robots it served (for a `policies.stacked.StackedPolicy`
of several controllers, its part's call time divided by the part's rows), and `wall_s` is the batch's wall time
divided by N. A robot whose episode ended stays out of the statistics (the vector env autoresets it; its later
rows are ignored). An exception fails the whole batch: every record gets status "failed" and the traceback.

Layer 3 (above `rollout`, whose helpers it reuses): imports `eval.metrics`, `eval.rollout`, `policies.base`,
gymnasium (`make_vector_env`) and numpy.
"""

from __future__ import annotations

import os
import time
import traceback
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from eval import metrics as M
from eval.rollout import _empty_record, _finish, _JacobianRecorder, _metrics_none
from policies.base import policy_seed


class _RobotBase:
    """What `rollout`'s helpers read of `env.unwrapped`, for robot i of a vector env."""

    def __init__(self, venv: Any, i: int):
        tpl = venv.unwrapped._template
        self._venv, self._i = venv.unwrapped, i
        self.dt, self.action_scale = tpl.dt, tpl.action_scale
        self.dynamics, self.model_error, self.obs_noise = tpl.dynamics, tpl.model_error, tpl.obs_noise
        self.control_freq = tpl.control_freq

    @property
    def true_params(self) -> Any:
        return self._venv.true_params(self._i)


def make_vector_env(
    env_id: str,
    num_envs: int,
    dynamics: str | None = None,
    model_error: float | None = None,
    obs_noise: float | None = None,
    env_kwargs: dict | None = None,
) -> Any:
    """`gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point", **kwargs)` with the eval flags
    (None: the env's default) and extra constructor kwargs, as `eval.rollout.make_env` builds a single env.
    Kinematic mode of a fixed arm gives the native `mobman_env.vector.WheeledPumaVectorEnv`."""
    import mobman_env  # noqa: F401  (registers the ids)

    kwargs = dict(env_kwargs or {})
    for name, value in (("dynamics", dynamics), ("model_error", model_error), ("obs_noise", obs_noise)):
        if value is not None:
            kwargs[name] = value
    return gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", **kwargs)


def _row_info(info: dict, i: int) -> dict:
    return {
        "ee_pos_true": info["ee_pos_true"][i],
        "tracking_error": float(info["tracking_error"][i]),
        "joint_limit_hits": int(info["joint_limit_hits"][i]),
        "n_clipped": int(info["n_clipped"][i]),
        "tipped_over": bool(info["tipped_over"][i]) if "tipped_over" in info else False,
    }


def rollout_batch(
    venv: Any,
    policy: Any,
    seed: int | Sequence[int],
    *,
    tolerance: float = M.DEFAULT_TOLERANCE,
    settle_time: float = M.DEFAULT_SETTLE_TIME,
    meta: dict | Sequence[dict] | None = None,
) -> list[tuple[dict, dict | None]]:
    """Run the N episodes of seeds `seed` .. `seed + N - 1` (or the N seeds of the list `seed`) of `policy` (a
    `policies.batched.BatchedPolicy` for `venv`) on the vector env `venv`; returns each robot's (record, arrays)
    as `eval.rollout.rollout` would. `meta`: the caller's record fields, one dict for all or one per robot."""
    n = venv.num_envs
    bases = [_RobotBase(venv, i) for i in range(n)]
    if isinstance(seed, (int, np.integer)):
        seeds = [int(seed) + i for i in range(n)]
        env_seed: int | list[int] = int(seed)
        policy_seeds: int | list[int] = int(seed)  # the batched policy derives policy_seed(S + i) itself
    else:
        seeds = env_seed = [int(s) for s in seed]
        policy_seeds = [policy_seed(s) for s in seeds]
    metas = list(meta) if isinstance(meta, Sequence) else [meta] * n
    if len(seeds) != n or len(metas) != n:
        raise ValueError(
            f"rollout_batch on {n} robots needs one seed (or a list of {n}) and one meta dict (or a list of {n}), "
            f"got {len(seeds)} seeds and {len(metas)} meta dicts"
        )
    recs = [_empty_record(bases[i], seeds[i], metas[i]) for i in range(n)]
    wall0 = time.perf_counter()
    steps_run = np.zeros(n, dtype=int)
    arr: dict[str, np.ndarray] = {}
    try:
        obs, info = venv.reset(seed=env_seed)
        n_steps = np.asarray(info["task"]["n_steps"], dtype=int)
        m = int(n_steps.max())
        n_act = len(np.asarray(bases[0].action_scale))
        # the per-step arrays of all robots, step-major (rows of the single rollout's _Buffers, one per robot)
        arr = {
            "r_d": np.empty((m + 1, n, 3)),
            "r_a": np.empty((m + 1, n, 3)),
            "p_c": np.empty((m + 1, n, 2)),
            "error": np.empty((m + 1, n)),
            "action": np.empty((m, n, n_act)),
            "predict_us": np.empty((m, n)),
        }
        _observe(arr, 0, obs, info)
        for i, rec in enumerate(recs):
            rec.update(
                path=_path(info, i), start=info["task"]["start"][i], true_params_hash=info["true_params_hash"][i]
            )
        policy.reset(obs, info, seed=policy_seeds)
        rows = getattr(policy, "rows", [policy] * n)
        jacs = [
            _JacobianRecorder(rows[i], bases[i], int(n_steps[i]))
            if getattr(rows[i], "jacobian_kind", None) is not None
            else None
            for i in range(n)
        ]
        watched = [i for i in range(n) if jacs[i] is not None]
        running = np.ones(n, dtype=bool)
        k = 0
        clock = time.perf_counter
        while running.any():
            t0 = clock()
            actions, _ = policy.predict(obs, episode_start=None, deterministic=True)
            row_us = getattr(policy, "row_us", None)  # a StackedPolicy times each of its parts
            arr["predict_us"][k] = (clock() - t0) * 1e6 / running.sum() if row_us is None else row_us
            act = np.asarray(actions, dtype=np.float32)
            for i in watched:
                if running[i]:
                    jacs[i].record(k, {"joint_pos": obs["joint_pos"][i], "base_yaw": obs["base_yaw"][i]})
            obs, _, term, trunc, info = venv.step(act)
            arr["action"][k] = np.clip(act, -1.0, 1.0)
            k += 1
            _observe(arr, k, obs, info)
            ended = running & (term | trunc | (k >= n_steps))
            for i in np.flatnonzero(ended).tolist():
                running[i] = False
                steps_run[i] = k
                arrays = _arrays(arr, i, k, bases[i].dt)
                recs[i]["_arrays"] = _finish(
                    recs[i], arrays, _row_info(info, i), k, bases[i], tolerance, settle_time, jacs[i]
                )
                recs[i]["terminated"] = bool(term[i])
        out = [(rec, rec.pop("_arrays")) for rec in recs]
    except KeyboardInterrupt:
        raise
    except BaseException:
        tb = traceback.format_exc()
        out = []
        for i, rec in enumerate(recs):
            rec.pop("_arrays", None)
            rec.update(status="failed", error=tb, n_steps=int(steps_run[i]), **_metrics_none())
            out.append((rec, _arrays(arr, i, int(steps_run[i]), bases[i].dt) if arr else None))
    wall = (time.perf_counter() - wall0) / n
    for rec, _ in out:
        rec["wall_s"] = wall
        rec["pid"] = os.getpid()
    return out


def _path(info: dict, i: int) -> dict:
    """Row i of the batched `task["path"]` info (a nested dict of arrays) as the single env's spec dict."""
    spec = info["task"]["path"]
    row = {}
    for key, value in spec.items():
        if key.startswith("_") or not spec["_" + key][i]:
            continue
        v = value[i]
        row[key] = v.item() if isinstance(v, np.generic) else v
    return row


def _observe(arr: dict, k: int, obs: dict, info: dict) -> None:
    """The state after step k of every robot (k = 0: after the reset), as `_Buffers.observe` stores it."""
    arr["r_d"][k], arr["r_a"][k] = obs["target_pos"], info["ee_pos_true"]
    arr["p_c"][k], arr["error"][k] = obs["arm_base_pos"], info["tracking_error"]


def _arrays(arr: dict, i: int, k: int, dt: float) -> dict[str, np.ndarray]:
    """Robot i's arrays of its first k steps, contiguous as `_Buffers.arrays` hands them out (so the metrics
    reduce them in the same order)."""
    out = {"t": np.arange(k + 1) * dt}
    for key, value in arr.items():
        out[key] = np.ascontiguousarray(value[: k + (0 if key in ("action", "predict_us") else 1), i])
    return out

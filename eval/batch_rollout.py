"""The rollout loop of `eval.rollout` for N episodes at once: one vector env, one batched policy.

```
obs, info = venv.reset(seed=S)                 # robot i: the single env's episode of seed S + i
policy.reset(obs, info, seed=S)                # row i: policy_seed(S + i), as rollout() seeds a policy
repeat: actions, _ = policy.predict(obs)       # one call for every robot still running
        obs, reward, terminated, truncated, info = venv.step(actions)
```

`rollout_batch` returns, for each robot i, the (record, arrays) that `eval.rollout.rollout` returns for the
episode of seed S + i with the same policy spec: the vector env (`mobman_env.vector`) is bit-identical to the
single env and a batched policy's rows run the single-env law (`policies.batched`), so every array and metric is
equal, for chaotic controllers too (`tests/test_batch_rollout.py`). What differs is the timing: `predict_us` of
a row is the batched call's wall time divided by the robots it served, and `wall_s` is the batch's wall time
divided by N. A robot whose episode ended stays out of the statistics (the vector env autoresets it; its later
rows are ignored). An exception fails the whole batch: every record gets status "failed" and the traceback.

Layer 3 (above `rollout`, whose helpers it reuses): imports `eval.metrics`, `eval.rollout` and numpy.
"""

from __future__ import annotations

import os
import time
import traceback
from typing import Any

import numpy as np

from eval import metrics as M
from eval.rollout import _Buffers, _empty_record, _finish, _JacobianRecorder, _metrics_none


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
    seed: int,
    *,
    tolerance: float = M.DEFAULT_TOLERANCE,
    settle_time: float = M.DEFAULT_SETTLE_TIME,
    meta: dict | None = None,
) -> list[tuple[dict, dict | None]]:
    """Run the N episodes of seeds `seed` .. `seed + N - 1` of `policy` (a `policies.batched.BatchedPolicy` for
    `venv`) on the vector env `venv`; returns each robot's (record, arrays) as `eval.rollout.rollout` would."""
    n = venv.num_envs
    bases = [_RobotBase(venv, i) for i in range(n)]
    recs = [_empty_record(bases[i], seed + i, meta) for i in range(n)]
    wall0 = time.perf_counter()
    bufs: list[_Buffers] = []
    try:
        obs, info = venv.reset(seed=seed)
        n_steps = np.asarray(info["task"]["n_steps"], dtype=int)
        for i, rec in enumerate(recs):
            rec.update(
                path=_path(info, i),
                start=info["task"]["start"][i],
                true_params_hash=info["true_params_hash"][i],
            )
            buf = _Buffers(int(n_steps[i]), bases[i].dt, len(np.asarray(bases[i].action_scale)))
            buf.observe(0, {k: v[i] for k, v in obs.items()}, _row_info(info, i))
            bufs.append(buf)
        policy.reset(obs, info, seed=seed)
        rows = getattr(policy, "rows", [policy] * n)
        jacs = [
            _JacobianRecorder(rows[i], bases[i], int(n_steps[i]))
            if getattr(rows[i], "jacobian_kind", None) is not None
            else None
            for i in range(n)
        ]
        running = np.ones(n, dtype=bool)
        last_info: list[dict] = [{} for _ in range(n)]
        k = 0
        clock = time.perf_counter
        while running.any():
            t0 = clock()
            actions, _ = policy.predict(obs, episode_start=None, deterministic=True)
            us = (clock() - t0) * 1e6 / running.sum()
            act = np.asarray(actions, dtype=np.float32)
            live = np.flatnonzero(running)
            for i in live:
                bufs[i].us[k] = us
                if jacs[i] is not None:
                    jacs[i].record(k, {"joint_pos": obs["joint_pos"][i], "base_yaw": obs["base_yaw"][i]})
            obs, _, term, trunc, info = venv.step(act)
            clipped = np.clip(act, -1.0, 1.0)
            for i in live:
                bufs[i].act[k] = clipped[i]
                row = _row_info(info, i)
                bufs[i].observe(
                    k + 1, {"target_pos": obs["target_pos"][i], "arm_base_pos": obs["arm_base_pos"][i]}, row
                )
                last_info[i] = row
                if term[i] or trunc[i] or k + 1 >= n_steps[i]:
                    running[i] = False
                    _close(recs[i], bufs[i], k + 1, last_info[i], bases[i], tolerance, settle_time, jacs[i])
                    recs[i]["terminated"] = bool(term[i])
            k += 1
        out = [(rec, rec.pop("_arrays")) for rec in recs]
    except KeyboardInterrupt:
        raise
    except BaseException:
        tb = traceback.format_exc()
        out = []
        for i, rec in enumerate(recs):
            rec.pop("_arrays", None)
            rec.update(status="failed", error=tb, n_steps=bufs[i].k if i < len(bufs) else 0, **_metrics_none())
            out.append((rec, bufs[i].arrays(bufs[i].k) if i < len(bufs) else None))
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


def _close(rec: dict, buf: _Buffers, k: int, info: dict, base: Any, tolerance: float, settle: float, jac) -> None:
    rec["_arrays"] = _finish(rec, buf.arrays(k), info, k, base, tolerance, settle, jac)

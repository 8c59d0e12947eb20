"""`eval.rollout.rollout_batch` gives each robot the record and arrays `eval.rollout.rollout` gives the
single-env episode of the same seed (all but the timings), for non-chaotic and chaotic controllers alike."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policies
from eval.rollout import make_env, rollout, rollout_batch
from mobman_env import TASKS

TIMING = ("wall_s", "pid", "predict_us_median", "predict_us_p99")


@pytest.mark.parametrize("spec", ["zero", "clik", "oracle", "nnbc", "nnbc-plus"])
def test_batch_equals_single_rollouts(spec):
    env_id, n, seed = "WheeledPuma-Circle-v0", 3, 10_000
    kwargs = {"dynamics": "kinematic", "path": dict(TASKS[env_id], duration=0.8), "obs_noise": 0.001}
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs)
    batch = rollout_batch(venv, policies.make(spec, venv), seed, meta={"env": env_id, "policy": spec})
    env = make_env(env_id, env_kwargs=kwargs)
    pol = policies.make(spec, env)
    for i, (rec, arrays) in enumerate(batch):
        ref, ref_arrays = rollout(env, pol, seed + i, meta={"env": env_id, "policy": spec})
        assert rec["status"] == "ok", rec["error"]
        assert set(rec) == set(ref)
        for key in set(ref) - set(TIMING):
            assert rec[key] == ref[key], (spec, i, key, rec[key], ref[key])
        assert set(arrays) == set(ref_arrays)
        for key in set(ref_arrays) - {"predict_us"}:
            assert np.array_equal(arrays[key], ref_arrays[key], equal_nan=True), (spec, i, key)
    venv.close()
    env.close()

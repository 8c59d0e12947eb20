"""Batched policies (`policies.make(spec, vector_env)`): robot i's actions equal a single-env policy reset with
`policy_seed(S + i)` on the same observations (here bit for bit: the rows run the single law), and
`episode_start` re-initialises its rows only. Seeds >= 10,000."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policies
from mobman_env import TASKS, WheeledPumaEnv
from policies.base import policy_seed
from policies.batched import BatchedPolicy

SPECS = ("zero", "random", "jmpi", "clik", "clik-full", "oracle", "nnbc", "nnbc-plus", "broyden", "rls")
ENV_ID = "WheeledPuma-Lemniscate-v0"


@pytest.mark.parametrize("spec", SPECS)
def test_rows_equal_single_policies(spec):
    n, seed, steps = 3, 10_000, 60
    path = dict(TASKS[ENV_ID], duration=0.4)  # 40 steps: the episodes end and autoreset
    venv = gym.make_vec(ENV_ID, num_envs=n, vectorization_mode="vector_entry_point", dynamics="kinematic", path=path)
    batched = policies.make(spec, venv)
    assert isinstance(batched, BatchedPolicy) and batched.num_envs == n
    envs = [WheeledPumaEnv(dynamics="kinematic", path=path) for _ in range(n)]
    singles = [policies.make(spec, env) for env in envs]
    obs, info = venv.reset(seed=seed)
    batched.reset(obs, info, seed=seed)
    single_obs = []
    for i, (env, pol) in enumerate(zip(envs, singles)):
        o, inf = env.reset(seed=seed + i)
        pol.reset(o, inf, seed=policy_seed(seed + i))
        single_obs.append(o)
    starts = np.zeros(n, dtype=bool)
    for t in range(steps):
        if t == 25:
            starts[1] = True  # re-initialise row 1 only, mid-episode
        actions, _ = batched.predict(obs, episode_start=starts)
        assert actions.shape == (n, 8) and actions.dtype == np.float32
        for i, pol in enumerate(singles):
            a, _ = pol.predict(single_obs[i], episode_start=np.array([starts[i]]))
            assert np.array_equal(actions[i], a), (spec, t, i, actions[i], a)
        obs, *_ = venv.step(actions)
        for i, env in enumerate(envs):
            if single_obs[i] is None:
                single_obs[i], _ = env.reset()
            else:
                single_obs[i], _, te, tr, _ = env.step(actions[i])
                if te or tr:
                    single_obs[i] = None
        # rows that autoreset this step: the vector env returns the new episode's first obs on the next step
        starts = np.array([o is None for o in single_obs])
        for i in np.flatnonzero(starts):
            single_obs[i], _ = envs[i].reset()
        if starts.any():
            obs, *_ = venv.step(np.zeros((n, 8), dtype=np.float32))  # the autoreset step (actions ignored)
    venv.close()
    for env in envs:
        env.close()


def test_bad_batches_raise():
    venv = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="vector_entry_point", dynamics="kinematic")
    pol = policies.make("clik", venv)
    obs, _ = venv.reset(seed=10_100)
    with pytest.raises(ValueError, match="leading axis of 2"):
        pol.predict({k: v[:1] for k, v in obs.items()})
    with pytest.raises(ValueError, match="list of 2 seeds"):
        pol.reset(obs, seed=[1, 2, 3])
    venv.close()

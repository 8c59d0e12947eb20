"""Recorded actions pin the model-free controllers at their defaults: `nnbc-plus`, `nnbc-plus-wb`, `broyden` and
`rls` issue, bit for bit, the actions recorded in `tests/data/model_free_actions_0.3.npz`.

The file was recorded by `record()` with `PYTHONPATH=$PWD python tests/test_model_free_actions.py --write`, last
by `nnbc-plus` v5.1 (issue 38), whose Kalman filter's R starts at the probe's residual variance: it moved
`nnbc-plus`'s and `nnbc-plus-wb`'s actions in the noisy Lemniscate (by up to 0.17 rad/s) and in physics (by up to
1e-4 rad/s: contacts leave a residual), left their noiseless kinematic Circle bit for bit, and `broyden`'s and
`rls`'s in all three (they have no R, and no episode here has an actuator lag, where the bank they share with
v5.1 moves them); before, by v5, which moved `nnbc-plus`'s and `nnbc-plus-wb`'s actions on purpose (the joint-angle
regressor, learnt stops, the low-passed dither) and left `broyden`'s and `rls`'s bit for bit (their defaults
keep the v4 scaffolding); before, by v4 (issue 28): the actuator-model bank (lag models beside the delays: all
four controllers), the filtered heading and the 0.02 rad/s probe (`nnbc-plus`, `nnbc-plus-wb`).
Before, v4's deletion of the failed and dead options had passed it unchanged (each was a no-op at its default).
A change meant to leave the default controllers as they are must pass this test unchanged; a change that moves
them on purpose records the file anew in the same commit and says why.

Episodes: the PUMA's Circle-v0 in kinematic and physics mode, and its Lemniscate-v0 with sensor noise (1 mm,
0.01 m/s) and a 2-step observation delay (kinematic), each for `STEPS` control steps past the probe, the
delay-settling phase and two blocks of dither signs; development seeds 0-2 (nothing here is a claim). The
controllers were recorded when they multiplied small arrays with numpy (BLAS; `_blas` in the file names the
OpenBLAS kernel, SkylakeX). Since the port of the model-free law to numba kernels without BLAS
(`policies.kernels.model_free`: the commands moved by at most 4e-13 relative) they issue the recorded float32
actions unchanged, so the file was kept.
"""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import mobman_env  # noqa: F401 (registers the ids)
import policies
from policies.base import policy_seed

DATA = Path(__file__).parent / "data" / "model_free_actions_0.3.npz"
SPECS = ("nnbc-plus", "nnbc-plus-wb", "broyden", "rls")
#: (label, env id, constructor kwargs, development seed)
EPISODES = (
    ("circle-kinematic", "WheeledPuma-Circle-v0", {"dynamics": "kinematic"}, 0),
    ("circle-physics", "WheeledPuma-Circle-v0", {"dynamics": "physics"}, 1),
    (
        "lemniscate-noise-delay",
        "WheeledPuma-Lemniscate-v0",
        {"dynamics": "kinematic", "obs_noise": 0.001, "obs_noise_vel": 0.01, "obs_delay": 2},
        2,
    ),
)
STEPS = 600


def record_one(spec: str, env_id: str, kwargs: dict, seed: int, steps: int = STEPS) -> np.ndarray:
    """The actions (steps x n, float32) `spec` issues in one episode, seeded as eval seeds it."""
    env = gym.make(env_id, **kwargs)
    try:
        policy = policies.make(spec, env)
        obs, info = env.reset(seed=seed)
        policy.reset(obs, info, seed=policy_seed(seed))
        actions = []
        for _ in range(steps):
            action, _ = policy.predict(obs, deterministic=True)
            actions.append(action)
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
        return np.array(actions)
    finally:
        env.close()


def record() -> dict[str, np.ndarray]:
    """Every spec on every episode, keyed `<spec>/<label>/<seed>`."""
    return {
        f"{spec}/{label}/{seed}": record_one(spec, env_id, kwargs, seed)
        for spec in SPECS
        for label, env_id, kwargs, seed in EPISODES
    }


def _blas() -> str:
    from threadpoolctl import threadpool_info

    return "; ".join(f"{i.get('internal_api')} {i.get('version')} {i.get('architecture')}" for i in threadpool_info())


@pytest.mark.parametrize("spec", SPECS)
def test_the_default_model_free_controllers_issue_their_recorded_actions(spec):
    ref = np.load(DATA)
    for label, env_id, kwargs, seed in EPISODES:
        key = f"{spec}/{label}/{seed}"
        new = record_one(spec, env_id, kwargs, seed)
        old = ref[key]
        if not (new.shape == old.shape and np.array_equal(new, old)):
            n = min(len(new), len(old))
            diff = np.flatnonzero((new[:n] != old[:n]).any(axis=1))
            first = int(diff[0]) if diff.size else n
            pytest.fail(
                f"{key}: the actions moved (shapes {new.shape} / {old.shape}, first differing step {first}); "
                f"recorded with BLAS {ref['_blas']}, running {_blas()}. If the change is meant, record the file "
                f"again (`PYTHONPATH=$PWD python tests/test_model_free_actions.py --write`) and say why"
            )


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: PYTHONPATH=$PWD python tests/test_model_free_actions.py --write")
    DATA.parent.mkdir(exist_ok=True)
    np.savez_compressed(DATA, _blas=np.array(_blas()), **record())
    print(f"wrote {DATA}")

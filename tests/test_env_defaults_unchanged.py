"""At default option values the env's observations, rewards and info stay what release 0.1 produced.

`tests/data/env_defaults_0.1.npz` was recorded by `record()` below from commit 3d1df75 (before the release-0.2
env options `obs_noise_joint_vel`, `obs_delay` and `wear_rate`, the URDF and leak-guard changes existed), with
`PYTHONPATH=$PWD python tests/test_env_defaults_unchanged.py --write`. Five episodes in four envs: both
dynamics modes, with and without sensor noise, a random path whose seed comes from the env's RNG, and two
consecutive episodes in one physics env (the second reuses the client, so body replacement is covered); actions
are random and partly outside [-1, 1] (clipping).

Comparison is bit for bit when numpy runs on the same BLAS kernel as at recording time (the kinematic mode's
4x4 products go through BLAS, and another kernel may round the last bit differently); on another kernel the
values must agree to 1e-9 (m, m/s, rad) and the discrete fields exactly.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from mobman_env import TASKS, WheeledPumaEnv

DATA = Path(__file__).parent / "data" / "env_defaults_0.1.npz"
#: (name, constructor kwargs, [(seed, steps), ...]); seeds >= 10,000 (reported range, never tuned on)
EPISODES = (
    ("kinematic", {"dynamics": "kinematic"}, [(10_000, 150)]),
    (
        "kinematic_noise_random",
        {"dynamics": "kinematic", "obs_noise": 0.001, "obs_noise_vel": 0.01, "path": TASKS["WheeledPuma-Random-v0"]},
        [(10_001, 150)],
    ),
    ("physics", {}, [(10_002, 80), (10_003, 80)]),
    (
        "physics_noise_line",
        {"obs_noise": 0.002, "obs_noise_vel": 0.02, "path": TASKS["WheeledPuma-Line-v0"]},
        [(10_004, 80)],
    ),
)
DISCRETE = ("terminated", "truncated", "n_clipped", "joint_limit_hits", "action_clipped", "tipped_over")


def _blas_kernel() -> str:
    try:
        from threadpoolctl import threadpool_info

        return ";".join(f"{i.get('internal_api')}:{i.get('architecture')}" for i in threadpool_info())
    except Exception:  # threadpoolctl missing: treat as unknown kernel
        return "unknown"


def record() -> dict[str, np.ndarray]:
    """Run the episodes of `EPISODES` and return their arrays, keyed `<name>/<seed>/<field>`."""
    out: dict[str, np.ndarray] = {}
    for name, kwargs, runs in EPISODES:
        env = WheeledPumaEnv(**kwargs)
        try:
            for seed, steps in runs:
                rng = np.random.default_rng(seed)
                obs, info = env.reset(seed=seed)
                rows: dict[str, list] = {k: [v.copy()] for k, v in obs.items()}
                rows.update(ee_pos_true=[info["ee_pos_true"]], tracking_error=[info["tracking_error"]])
                prefix = f"{name}/{seed}/"
                out[prefix + "reset_info"] = np.array(json.dumps(info["task"], sort_keys=True))
                out[prefix + "true_params_hash"] = np.array(info["true_params_hash"])
                for field in ("reward", "tracking", "effort", *DISCRETE):
                    rows[field] = []
                for _ in range(steps):
                    obs, reward, term, trunc, info = env.step(rng.uniform(-1.2, 1.2, 8))
                    for k, v in obs.items():
                        rows[k].append(v.copy())
                    rows["ee_pos_true"].append(info["ee_pos_true"])
                    rows["tracking_error"].append(info["tracking_error"])
                    rows["reward"].append(reward)
                    rows["tracking"].append(info["reward_terms"]["tracking"])
                    rows["effort"].append(info["reward_terms"]["effort"])
                    rows["terminated"].append(term)
                    rows["truncated"].append(trunc)
                    for k in DISCRETE[2:]:
                        rows[k].append(info[k])
                    assert info["true_params_hash"] == out[prefix + "true_params_hash"]
                    if term or trunc:
                        break
                for k, v in rows.items():
                    out[prefix + k] = np.asarray(v)
        finally:
            env.close()
    return out


def test_default_options_reproduce_release_0_1():
    ref = np.load(DATA)
    new = record()
    assert set(new) == set(ref.files) - {"_blas_kernel"}
    exact = str(ref["_blas_kernel"]) == _blas_kernel()
    for key in sorted(new):
        a, b = new[key], ref[key]
        field = key.rsplit("/", 1)[1]
        if exact or a.dtype.kind not in "f" or field in DISCRETE:
            assert a.shape == b.shape and np.array_equal(a, b), key
        else:
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-9, err_msg=key)


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: PYTHONPATH=$PWD python tests/test_env_defaults_unchanged.py --write")
    DATA.parent.mkdir(exist_ok=True)
    np.savez_compressed(DATA, _blas_kernel=np.array(_blas_kernel()), **record())
    print(f"wrote {DATA}")

"""At default option values the env's observations, rewards and info stay what release 0.1 produced.

`tests/data/env_defaults_0.1.npz` was recorded by `record()` below from commit 3d1df75 (before the release-0.2
env options `obs_noise_joint_vel`, `obs_delay` and `wear_rate`, the URDF and leak-guard changes existed), with
`PYTHONPATH=$PWD python tests/test_env_defaults_unchanged.py --write`. Five episodes in four envs: both
dynamics modes, with and without sensor noise, a random path whose seed comes from the env's RNG, and two
consecutive episodes in one physics env (the second reuses the client, so body replacement is covered); actions
are random and partly outside [-1, 1] (clipping).

`tests/data/env_kinematic_0.2.npz` (`ROBOT_EPISODES`) pins the kinematic mode of every robot and of the
release-0.2 options (joint-speed noise, delay, wear) before the tight kinematic step (recorded from commit
24bc55f with `... --write robots`): UR5, Panda and the random arm on the Circle and the Line, and the PUMA's
Lemniscate with wear, delay and joint-speed noise.

Comparison is bit for bit when numpy runs on the same BLAS kernel as at recording time (the kinematic mode's
4x4 products go through BLAS, and another kernel may round the last bit differently); on another kernel the
values must agree to 1e-9 (m, m/s, rad) and the discrete fields exactly.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

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
ROBOT_DATA = Path(__file__).parent / "data" / "env_kinematic_0.2.npz"
ROBOT_EPISODES = (
    *(
        (
            f"{robot}_{task.lower()}",
            {"dynamics": "kinematic", "robot": robot, "path": TASKS[f"WheeledPuma-{task}-v0"]},
            [(10_010 + i, 120)],
        )
        for i, (robot, task) in enumerate((r, t) for r in ("ur5", "panda", "random") for t in ("Circle", "Line"))
    ),
    (
        "puma_lemniscate_wear_delay",
        {
            "dynamics": "kinematic",
            "path": TASKS["WheeledPuma-Lemniscate-v0"],
            "wear_rate": 0.01,
            "obs_delay": 2,
            "obs_noise_joint_vel": 0.01,
        },
        [(10_020, 200)],
    ),
)
DATASETS = {"defaults": (DATA, EPISODES), "robots": (ROBOT_DATA, ROBOT_EPISODES)}
DISCRETE = ("terminated", "truncated", "n_clipped", "joint_limit_hits", "action_clipped", "tipped_over")


def _blas_kernel() -> str:
    try:
        from threadpoolctl import threadpool_info

        return ";".join(f"{i.get('internal_api')}:{i.get('architecture')}" for i in threadpool_info())
    except Exception:  # threadpoolctl missing: treat as unknown kernel
        return "unknown"


def record(episodes=EPISODES) -> dict[str, np.ndarray]:
    """Run `episodes` and return their arrays, keyed `<name>/<seed>/<field>`."""
    out: dict[str, np.ndarray] = {}
    for name, kwargs, runs in episodes:
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
                    obs, reward, term, trunc, info = env.step(rng.uniform(-1.2, 1.2, env.n_actuators))
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


@pytest.mark.parametrize("dataset", sorted(DATASETS))
def test_recorded_episodes_reproduce(dataset):
    path, episodes = DATASETS[dataset]
    ref = np.load(path)
    new = record(episodes)
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
    if len(sys.argv) != 3 or sys.argv[1] != "--write" or sys.argv[2] not in DATASETS:
        sys.exit(f"usage: PYTHONPATH=$PWD python tests/test_env_defaults_unchanged.py --write {{{','.join(DATASETS)}}}")
    path, episodes = DATASETS[sys.argv[2]]
    path.parent.mkdir(exist_ok=True)
    np.savez_compressed(path, _blas_kernel=np.array(_blas_kernel()), **record(episodes))
    print(f"wrote {path}")

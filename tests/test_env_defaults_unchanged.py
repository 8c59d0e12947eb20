"""Recorded episodes pin the env's numbers: bit for bit those of release 0.3's engine, and within the last bits
of releases 0.1 and 0.2.

`tests/data/env_0.3.npz` (`DATASETS["engine"]`, every episode below) was recorded by `record()` with
`PYTHONPATH=$PWD python tests/test_env_defaults_unchanged.py --write engine` from the engine of release 0.3
(`mobman_env.engine`: BLAS-free, so the comparison is bit for bit on every machine and BLAS kernel).

The files of earlier releases stay as a cross-check of the engine against the code it replaced: release 0.1's
`tests/data/env_defaults_0.1.npz` (recorded from commit 3d1df75: five episodes in four envs, both dynamics
modes, with and without sensor noise, a random path whose seed comes from the env's RNG, two consecutive
episodes in one physics env) and release 0.2's `tests/data/env_kinematic_0.2.npz` (commit 24bc55f: UR5, Panda and
the random arm on the Circle and the Line, the PUMA's Lemniscate with wear, delay and joint-speed noise). Their
actions are random and partly outside [-1, 1], so the episodes are not chaotic: the release-0.3 values agree with
them to 1e-9 (m, m/s, rad; float64 fields), to one float32 rounding (the observations, whose float64 values moved
by up to ~1e-10 m: the engine sums in another order, and physics mode computes the end-effector from the joint
states instead of PyBullet's link state) and exactly in the discrete fields.
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
ENGINE_DATA = Path(__file__).parent / "data" / "env_0.3.npz"
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
#: the options release 0.3 added, in both modes
OPTION_EPISODES = (
    (
        "puma_circle_lag_yaw_noise",
        {"dynamics": "kinematic", "actuator_tau": 0.05, "obs_noise_yaw": 0.002},
        [(10_030, 150)],
    ),
    (
        "panda_line_lag_physics",
        {"robot": "panda", "path": TASKS["WheeledPuma-Line-v0"], "actuator_tau": 0.03},
        [(10_031, 80)],
    ),
)
DATASETS = {
    "defaults": (DATA, EPISODES),
    "robots": (ROBOT_DATA, ROBOT_EPISODES),
    "engine": (ENGINE_DATA, EPISODES + ROBOT_EPISODES + OPTION_EPISODES),
}
DISCRETE = ("terminated", "truncated", "n_clipped", "joint_limit_hits", "action_clipped", "tipped_over")


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


def test_the_engine_reproduces_its_recorded_episodes():
    ref = np.load(ENGINE_DATA)
    new = record(DATASETS["engine"][1])
    assert set(new) == set(ref.files)
    for key in sorted(new):
        assert new[key].shape == ref[key].shape and np.array_equal(new[key], ref[key]), key


@pytest.mark.parametrize("dataset", ["defaults", "robots"])
def test_the_engine_agrees_with_the_releases_it_replaced(dataset):
    path, episodes = DATASETS[dataset]
    ref = np.load(path)
    new = record(episodes)
    assert set(new) == set(ref.files) - {"_blas_kernel"}
    for key in sorted(new):
        a, b = new[key], ref[key]
        field = key.rsplit("/", 1)[1]
        if field == "reset_info":  # the path's start is the end-effector: within 1e-9 m, the rest exact
            ta, tb = json.loads(str(a)), json.loads(str(b))
            np.testing.assert_allclose(ta.pop("start"), tb.pop("start"), rtol=0, atol=1e-9, err_msg=key)
            assert ta == tb, key
        elif a.dtype.kind not in "f" or field in DISCRETE:
            assert a.shape == b.shape and np.array_equal(a, b), key
        elif a.dtype == np.float32:  # one float32 rounding of a value that moved by ~1e-10
            np.testing.assert_allclose(a, b, rtol=2.0**-22, atol=1e-9, err_msg=key)
        else:
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-9, err_msg=key)


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] != "--write" or sys.argv[2] not in DATASETS:
        sys.exit(f"usage: PYTHONPATH=$PWD python tests/test_env_defaults_unchanged.py --write {{{','.join(DATASETS)}}}")
    path, episodes = DATASETS[sys.argv[2]]
    path.parent.mkdir(exist_ok=True)
    if sys.argv[2] != "engine":
        sys.exit("only the engine's file is recorded now; the release files are the fixed references")
    np.savez_compressed(path, **record(episodes))
    print(f"wrote {path}")

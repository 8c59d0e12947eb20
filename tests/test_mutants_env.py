"""Known-answer tests of the env that an earlier mutation pass showed missing (issue 10, "tests that fail on
meaning"): sensor noise on p_c, the exact joint-limit hit count of kinematic mode, the effort reward's norm.

Each test here failed with its mutation applied by hand (see tests/mutation/mutants.py) and passes without it.
Kinematic mode, a few dozen steps each.
"""

from __future__ import annotations

import numpy as np
import pytest

from mobman_env.env import PAPER_ARM_JOINT_POS


# --- obs_noise reaches ee_pos AND arm_base_pos (obs_noise_vel: ee_vel AND arm_base_vel) ----------------------
@pytest.mark.parametrize(
    "kwargs, key, std",
    [
        ({"obs_noise": 0.01}, "arm_base_pos", 0.01),
        ({"obs_noise": 0.01}, "ee_pos", 0.01),
        ({"obs_noise_vel": 0.02}, "arm_base_vel", 0.02),
        ({"obs_noise_vel": 0.02}, "ee_vel", 0.02),
    ],
)
def test_sensor_noise_has_the_documented_std_on_each_noisy_key(make_env, kwargs, key, std):
    """obs[key] - truth over 300 steps has mean ~0 and the configured std (the Observation Space table)."""
    env = make_env(dynamics="kinematic", **kwargs)
    env.reset(seed=11)
    truth_of = {
        "arm_base_pos": lambda s: s.arm_base_pos,
        "ee_pos": lambda s: s.ee_pos,
        "arm_base_vel": lambda s: s.arm_base_vel,
        "ee_vel": lambda s: s.ee_vel,
    }[key]
    diffs = []
    action = np.r_[0.1, -0.1, 0.1, 0.0, 0.1, 0.0, 0.2, 0.1]  # the platform and the arm move
    for _ in range(300):
        obs, *_ = env.step(action)
        diffs.append(obs[key] - truth_of(env.state()))
    d = np.asarray(diffs, dtype=float)
    # 300 x n samples: the std is within 12% of the target and the mean within 4 standard errors of 0
    assert np.all(np.abs(d.std(axis=0) / std - 1.0) < 0.12), d.std(axis=0)
    assert np.all(np.abs(d.mean(axis=0)) < 4 * std / np.sqrt(len(d))), d.mean(axis=0)


def test_without_noise_the_observation_is_the_truth(make_env):
    env = make_env(dynamics="kinematic")
    env.reset(seed=11)
    for _ in range(20):
        obs, *_ = env.step(np.full(8, 0.2))
    s = env.state()
    for key, truth in (("arm_base_pos", s.arm_base_pos), ("ee_pos", s.ee_pos), ("arm_base_vel", s.arm_base_vel)):
        np.testing.assert_allclose(obs[key], truth, rtol=0, atol=1e-6, err_msg=key)


# --- the kinematic joint-limit hit count ------------------------------------------------------------------
def test_kinematic_joint_limit_hits_are_counted_exactly(make_env):
    """One hit per joint and step whose command was cut: crossing the limit inside a step counts (the angle
    stops at the limit), pushing at the limit counts, moving away or standing still does not."""
    env = make_env(dynamics="kinematic", path={"type": "circle", "radius": 0.1, "duration": 1.0})
    env.reset(seed=0)
    upper = np.array(env.true_params.joint_upper)
    lower = np.array(env.true_params.joint_lower)
    q0 = np.array(PAPER_ARM_JOINT_POS)
    q0[4] = upper[4] - 0.02  # joint 5: 0.02 rad below its upper limit, one step at +5 rad/s is 0.05 rad
    q0[0] = lower[0] + 0.01  # joint 1: 0.01 rad above its lower limit, one step at -3 rad/s is 0.03 rad
    obs, info = env.reset(seed=0, options={"arm_joint_pos": q0})
    assert info["joint_limit_hits"] == 0
    j5_up = np.r_[0, 0, 0, 0, 1.0, 0, 0, 0]
    hits = []
    for _ in range(2):  # step 1 crosses the limit, step 2 pushes at it
        obs, _, _, _, info = env.step(j5_up)
        hits.append(info["joint_limit_hits"])
        assert obs["joint_pos"][4] == pytest.approx(upper[4], abs=1e-6)
    assert hits == [1, 2]
    obs, _, _, _, info = env.step(np.zeros(8))  # standing still at the limit: no hit
    assert info["joint_limit_hits"] == 2
    obs, _, _, _, info = env.step(-j5_up)  # moving away: no hit, the joint moves the full step
    assert info["joint_limit_hits"] == 2
    assert obs["joint_pos"][4] == pytest.approx(upper[4] - 0.05, abs=1e-6)
    # two joints at once, from a new start: both cross in the first step, both push in the second
    env.reset(seed=0, options={"arm_joint_pos": q0})
    both = np.r_[-1.0, 0, 0, 0, 1.0, 0, 0, 0]
    assert [env.step(both)[4]["joint_limit_hits"] for _ in range(2)] == [2, 4]
    q = env.state().joint_pos
    assert q[0] == pytest.approx(lower[0], abs=1e-9) and q[4] == pytest.approx(upper[4], abs=1e-9)


# --- the effort reward is -w ||a||^2 (not ||a||_1) ---------------------------------------------------------
@pytest.mark.parametrize(
    "action, squared_norm",
    [
        # L1 = 1.25, L2^2 = 0.5625
        (np.r_[0.5, -0.5, 0.25, 0, 0, 0, 0, 0], 0.5625),
        # clipped to [1, -1, 0.5, 0...]: L1 = 2.5, L2^2 = 2.25 (the norm of the clipped action)
        (np.r_[3.0, -2.0, 0.5, 0, 0, 0, 0, 0], 2.25),
    ],
)
def test_effort_term_is_the_squared_norm_of_the_clipped_action(make_env, action, squared_norm):
    env = make_env(dynamics="kinematic", reward_weights={"tracking": 1.0, "effort": 0.3})
    env.reset(seed=2)
    _, reward, _, _, info = env.step(action)
    assert info["reward_terms"]["effort"] == pytest.approx(-0.3 * squared_norm, rel=1e-12)
    assert reward == pytest.approx(-info["tracking_error"] - 0.3 * squared_norm, rel=1e-12)

"""Release-0.2 env options: joint-velocity noise, observation delay, robot wear; as arguments and reset options."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import SHORT_CIRCLE

from mobman_env import kinematics as K
from mobman_env.sensors import SENSOR_KEYS

TWO_S = dict(SHORT_CIRCLE, duration=2.0)


def _run(env, seed, actions, options=None):
    obs, info = env.reset(seed=seed, options=options)
    out = [(obs, info)]
    for a in actions:
        obs, _, _, _, info = env.step(a)
        out.append((obs, info))
    return out


@pytest.mark.parametrize("dynamics", ["kinematic", "physics"])
def test_joint_velocity_noise_statistics_and_nothing_else_changes(make_env, dynamics):
    """At rest the true joint speeds are ~0, so the observed ones are the noise: mean ~0, std ~sigma over
    8 x 150 samples (5 standard errors); the other keys and the truth in info are those of the noise-free env."""
    sigma = 0.05
    actions = [np.zeros(8)] * 150
    clean = _run(make_env(dynamics=dynamics, path=TWO_S), 7, actions)
    noisy = _run(make_env(dynamics=dynamics, path=TWO_S, obs_noise_joint_vel=sigma), 7, actions)
    diff = np.array([n[0]["joint_vel"] - c[0]["joint_vel"] for c, n in zip(clean, noisy)], dtype=float)
    n = diff.size
    assert abs(diff.mean()) < 5 * sigma / np.sqrt(n)
    assert abs(diff.std() - sigma) < 5 * sigma / np.sqrt(2 * n)
    for (co, ci), (no, ni) in zip(clean, noisy):
        for k in co:
            if k != "joint_vel":
                np.testing.assert_array_equal(co[k], no[k], err_msg=k)
        np.testing.assert_array_equal(ci["ee_pos_true"], ni["ee_pos_true"])


@pytest.mark.parametrize(
    ("dynamics", "robot", "k"),
    [("kinematic", "puma560", 1), ("kinematic", "puma560", 5), ("physics", "puma560", 1), ("physics", "puma560", 5)]
    + [("kinematic", "panda", 1), ("kinematic", "panda", 3), ("kinematic", "ur5", 2)],
)
def test_delay_shifts_sensor_readings_by_exactly_k_steps(make_env, dynamics, robot, k):
    """With obs_delay = k the sensor keys of step n are those of step n - k of the undelayed env (the reset
    reading before that), noise included; target, time and info are current. Every entry is delayed, whatever
    the robot's actuator count (the Panda's 9: its last joint speeds too)."""
    rng = np.random.default_rng(3)
    n_act = make_env(dynamics="kinematic", path=TWO_S, robot=robot).action_space.shape[0]
    actions = list(rng.uniform(-0.5, 0.5, (40, n_act)))
    kw = dict(dynamics=dynamics, path=TWO_S, obs_noise=0.002, obs_noise_vel=0.01, obs_noise_joint_vel=0.01)
    kw["robot"] = robot
    now = _run(make_env(**kw), 11, actions)
    late = _run(make_env(**kw, obs_delay=k), 11, actions)
    for n, (obs, info) in enumerate(late):
        src = now[max(n - k, 0)][0]
        for key in SENSOR_KEYS:
            np.testing.assert_array_equal(obs[key], src[key], err_msg=f"{key} at step {n}")
        for key in ("target_pos", "target_vel", "time"):
            np.testing.assert_array_equal(obs[key], now[n][0][key])
        np.testing.assert_array_equal(info["ee_pos_true"], now[n][1]["ee_pos_true"])
        assert info["tracking_error"] == now[n][1]["tracking_error"]
    moved = [not np.array_equal(late[n][0]["ee_pos"], now[n][0]["ee_pos"]) for n in range(k + 1, len(late))]
    assert all(moved)  # the delay is visible once the arm moves


def test_wear_drifts_the_true_robot_linearly_and_info_stays_truthful(make_env):
    """At rest, the lengths scale by 1 + w t and the end-effector point is affine in that factor (every arm length
    and the mount offset scale; the shoulder height does not), so ee_pos_true moves linearly in time; info equals
    the FK of the robot of time t, and the hash names the robot of t = 0."""
    w = 0.02
    env = make_env(dynamics="kinematic", path=TWO_S, wear_rate=w)
    _, info = env.reset(seed=5)
    p0, h0 = env.true_params, info["true_params_hash"]
    q, pose = env.arm_joint_pos[:6], env.base_pose
    ee = [info["ee_pos_true"]]
    for n in range(1, 151):
        obs, _, _, _, info = env.step(np.zeros(8))
        np.testing.assert_allclose(obs["ee_pos"], info["ee_pos_true"], atol=1e-6)  # observable (float32)
        t = n * env.dt
        assert env.true_params.a2 == pytest.approx(p0.a2 * (1 + w * t), rel=1e-14)
        assert env.true_params.wheel_radius == pytest.approx(p0.wheel_radius * (1 + w * t), rel=1e-14)
        np.testing.assert_allclose(info["ee_pos_true"], K.ee_position(p0.scaled(1 + w * t), q, pose), atol=1e-12)
        assert info["true_params_hash"] == h0
        ee.append(info["ee_pos_true"])
    ee = np.array(ee)
    second = np.diff(ee, 2, axis=0)
    assert np.abs(second).max() < 1e-12 and np.linalg.norm(ee[-1] - ee[0]) > 1e-3  # linear, and it does move


def test_wear_moves_the_platform_with_the_worn_wheels(make_env):
    """Driving straight at constant wheel speed: the distance covered is r(t) integrated step by step with the
    radius of each step's start (zero-order hold), so it differs from the unworn robot's by the wear."""
    w, a = 0.05, np.r_[np.zeros(6), 0.5, 0.5]
    worn = make_env(dynamics="kinematic", path=TWO_S, wear_rate=w, model_error=0.0)
    new = make_env(dynamics="kinematic", path=TWO_S, model_error=0.0)
    worn.reset(seed=0)
    new.reset(seed=0)
    for _ in range(100):
        worn.step(a)
        new.step(a)
    r0, dt, v_wheel = new.true_params.wheel_radius, worn.dt, 0.5 * worn.action_scale[6]
    expected = sum(r0 * (1 + w * k * dt) * v_wheel * dt for k in range(100))
    start = new.base_pose[:2]
    assert np.linalg.norm(worn.state().base_pose[:2] - start) == pytest.approx(expected, rel=1e-12)
    assert np.linalg.norm(new.state().base_pose[:2] - start) == pytest.approx(r0 * v_wheel * 1.0, rel=1e-12)


def test_conditions_as_reset_options_last_one_episode(make_env):
    env = make_env(dynamics="kinematic", path=TWO_S)
    base = _run(env, 2, [np.full(8, 0.2)] * 10)
    opts = {"obs_delay": 3, "wear_rate": 0.01, "obs_noise_joint_vel": 0.1, "model_error": 0.2}
    changed = _run(env, 2, [np.full(8, 0.2)] * 10, options=opts)
    assert changed[0][1]["true_params_hash"] != base[0][1]["true_params_hash"]  # model_error 0.2 this episode
    np.testing.assert_array_equal(changed[3][0]["joint_pos"], changed[0][0]["joint_pos"])  # delayed 3 steps
    again = _run(env, 2, [np.full(8, 0.2)] * 10)
    for (a, ai), (b, bi) in zip(base, again):
        for k in a:
            np.testing.assert_array_equal(a[k], b[k])
        assert ai["tracking_error"] == bi["tracking_error"]
    with pytest.raises(ValueError, match="obs_delay must be an integer >= 0"):
        env.reset(options={"obs_delay": -2})
    with pytest.raises(ValueError, match="over a 20 s path"):
        env.reset(options={"wear_rate": 0.06, "path": dict(TWO_S, duration=20.0)})


def test_wear_is_refused_in_physics_mode_also_as_a_reset_option(make_env):
    env = make_env(dynamics="physics", path=SHORT_CIRCLE)
    with pytest.raises(ValueError, match="wear_rate=0.01 needs dynamics='kinematic'"):
        env.reset(options={"wear_rate": 0.01})


@pytest.mark.parametrize("dynamics", ["kinematic", "physics"])
def test_new_options_are_deterministic(make_env, dynamics):
    kw = dict(dynamics=dynamics, path=TWO_S, obs_noise_joint_vel=0.02, obs_delay=2)
    if dynamics == "kinematic":
        kw["wear_rate"] = 0.01
    actions = list(np.random.default_rng(0).uniform(-1, 1, (30, 8)))
    a, b = _run(make_env(**kw), 9, actions), _run(make_env(**kw), 9, actions)
    for (x, xi), (y, yi) in zip(a, b):
        for k in x:
            np.testing.assert_array_equal(x[k], y[k])
        np.testing.assert_array_equal(xi["ee_pos_true"], yi["ee_pos_true"])

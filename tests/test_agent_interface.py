"""The agent's interface (`policies.agents.agent_interface`): no clock, one layout for every robot, padding that
round-trips."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mobman_env
from mobman_env import TASKS
from policies.agents import agent_interface as I

ROBOTS = {"puma560": 8, "ur5": 8, "panda": 9}
IDS = {"puma560": "WheeledPuma-Circle-v0", "ur5": "WheeledUR5-Circle-v0", "panda": "WheeledPanda-Circle-v0"}


def _obs(robot: str, seed: int = 3) -> dict:
    env = gym.make(IDS[robot], dynamics="kinematic")
    obs, _ = env.reset(seed=seed)
    for _ in range(5):
        obs, *_ = env.step(env.action_space.sample() * 0.1)
    env.close()
    return obs


def test_the_agent_sees_no_clock_and_no_absolute_position():
    keys = set(I.AGENT_OBS_KEYS)
    assert "time" not in keys
    assert not keys & {"ee_pos", "target_pos", "arm_base_pos"}
    obs = I.agent_observation(_obs("puma560"))
    assert set(obs) == keys


def test_two_episodes_at_different_times_with_the_same_state_look_the_same():
    obs = _obs("puma560")
    later = dict(obs, time=obs["time"] + 7.0)
    a, b = I.agent_observation(obs), I.agent_observation(later)
    assert all(np.array_equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize("robot", sorted(ROBOTS))
def test_every_robot_has_the_same_observation_and_action_layout(robot):
    obs = I.agent_observation(_obs(robot))
    assert I.observation_space().contains(obs)
    n = ROBOTS[robot] - 2
    assert obs["mask"].tolist() == [1.0] * n + [0.0] * (7 - n) + [1.0, 1.0]
    assert not obs["arm_pos"][n:].any() and not obs["joint_vel"][n:7].any()


@pytest.mark.parametrize("m", [8, 9])
def test_padding_round_trips(m):
    rng = np.random.default_rng(0)
    env_act = rng.uniform(-1, 1, (5, m)).astype(np.float32)
    agent = I.agent_action(env_act)
    assert agent.shape == (5, I.N_ACTIONS)
    assert np.array_equal(I.env_action(agent, m), env_act)
    assert np.array_equal(agent[:, m - 2 : 7], np.zeros((5, 9 - m)))
    full = rng.uniform(-1, 1, (5, I.N_ACTIONS)).astype(np.float32)
    # the padded slots are ignored: whatever is in them, the env gets the same action
    other = full.copy()
    other[:, m - 2 : 7] = 0.7
    assert np.array_equal(I.env_action(full, m), I.env_action(other, m))
    assert np.array_equal(I.env_action(full, m)[:, -2:], full[:, 7:])


def test_errors_are_given_in_the_heading_frame():
    obs = {k: np.asarray(v, dtype=np.float32) for k, v in _obs("puma560").items()}
    obs["base_yaw"] = np.array([np.pi / 2], np.float32)
    obs["target_pos"] = obs["ee_pos"] + np.array([0.0, 0.01, 0.0], np.float32)  # 1 cm to the world's +y
    got = I.agent_observation(obs)["pos_error"]
    assert got == pytest.approx([0.01, 0.0, 0.0], abs=1e-6)  # heading +y: the error is straight ahead


def test_a_bad_action_width_is_refused_naming_the_layout():
    with pytest.raises(ValueError, match="7 arm slots, 2 wheels"):
        I.env_action(np.zeros(8), 8)
    with pytest.raises(ValueError, match="1-7 joints"):
        I.arm_joints(10)


def test_agent_vec_env_passes_the_robots_own_actions_and_converts_terminal_observations():
    pytest.importorskip("stable_baselines3")
    from train.vec_env import AgentVecEnv, SB3VecEnv

    path = dict(TASKS["WheeledPuma-Circle-v0"], duration=0.05)
    vec = gym.make_vec(
        mobman_env.ENV_IDS[0],
        num_envs=2,
        vectorization_mode="vector_entry_point",
        dynamics="kinematic",
        autoreset_mode="SameStep",
        path=path,
    )
    venv = AgentVecEnv(SB3VecEnv(vec), ("agent",), I.AGENT_OBS_KEYS)
    venv.seed(0)
    obs = venv.reset()
    assert set(obs) == set(I.AGENT_OBS_KEYS) and obs["mask"].shape == (2, 9)
    action = np.zeros((2, 9), np.float32)
    action[:, 3] = 0.5  # arm joint 4 of both robots
    action[:, 6] = 1.0  # a padded slot of the 6-joint PUMA: ignored
    for _ in range(5):
        obs, _, dones, infos = venv.step(action)
    assert dones.all()
    final = infos[0]["terminal_observation"]
    assert set(final) == set(I.AGENT_OBS_KEYS)
    assert final["joint_vel"][3] == pytest.approx(0.5 * 5.0, rel=1e-5)  # the PUMA's joint 4 at half its 5 rad/s
    assert final["joint_vel"][6] == 0.0
    venv.close()

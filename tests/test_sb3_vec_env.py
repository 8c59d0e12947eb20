"""The SB3 adapter of the native vector env: SB3's reset/step conventions and a short PPO run on it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mobman_env
from mobman_env import TASKS

pytest.importorskip("stable_baselines3")
from train.vec_env import SB3VecEnv


def _venv(n, duration=0.2, mode="SameStep"):
    path = dict(TASKS["WheeledPuma-Circle-v0"], duration=duration)
    return gym.make_vec(
        mobman_env.ENV_IDS[0],
        num_envs=n,
        vectorization_mode="vector_entry_point",
        dynamics="kinematic",
        autoreset_mode=mode,
        path=path,
    )


def test_terminal_observation_and_next_episode_as_sb3_expects():
    venv = SB3VecEnv(_venv(3))
    venv.seed(10_000)
    obs = venv.reset()
    single = gym.make(
        mobman_env.ENV_IDS[0], dynamics="kinematic", path=dict(TASKS["WheeledPuma-Circle-v0"], duration=0.2)
    )
    o, _ = single.reset(seed=10_001)
    assert np.array_equal(obs["ee_pos"][1], o["ee_pos"])
    a = np.zeros((3, 8), dtype=np.float32)
    for _ in range(20):
        obs, rewards, dones, infos = venv.step(a)
        o, r, te, tr, _ = single.step(a[1])
        assert rewards.dtype == np.float32 and rewards[1] == np.float32(r)
    assert dones.all() and tr
    assert np.array_equal(infos[1]["terminal_observation"]["ee_pos"], o["ee_pos"])
    assert infos[1]["TimeLimit.truncated"]
    o, _ = single.reset()
    assert np.array_equal(obs["time"][1], o["time"]) and obs["time"][1, 0] == 0.0
    venv.close()
    single.close()


def test_next_step_mode_is_refused_with_the_fix():
    with pytest.raises(ValueError, match="SameStep"):
        SB3VecEnv(_venv(2, mode="NextStep"))


@pytest.mark.slow
def test_ppo_learns_on_the_adapter():
    from stable_baselines3 import PPO

    venv = SB3VecEnv(_venv(8, duration=0.5))
    model = PPO("MultiInputPolicy", venv, n_steps=32, batch_size=64, n_epochs=1, seed=10_002, device="cpu")
    model.learn(total_timesteps=512)
    assert model.num_timesteps >= 512
    obs = venv.reset()
    action, _ = model.predict(obs, deterministic=True)
    assert action.shape == (8, 8)
    venv.close()

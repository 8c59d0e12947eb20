"""mobman-train on the native vector env: the default config steps N robots of one `WheeledPumaVectorEnv` through
`SB3VecEnv` with PPO and the robot-independent agent interface; physics keeps SB3's vec envs; progress lines; a
trained agent acts on robots with other arms through `SB3Policy`. Tiny budgets; nothing here asserts success."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

from policies.agents.agent_interface import AGENT_OBS_KEYS, N_ACTIONS
from train.config import TrainConfig

#: a 0.5 s version of the paper's circle (50 steps per episode)
SHORT_PATH = {"type": "circle", "radius": 0.05, "tilt": 0.5236, "yaw": 3.1416, "duration": 0.5}


def _base(venv):
    """The innermost VecEnv under SB3's wrappers."""
    while hasattr(venv, "venv"):
        if type(venv).__name__ == "SB3VecEnv":
            return venv
        venv = venv.venv
    return venv


def test_default_config_is_ppo_on_the_native_vector_env_with_the_agent_interface():
    from mobman_env.vector import WheeledPumaVectorEnv
    from train.run import make_vec_env
    from train.vec_env import AgentVecEnv, SB3VecEnv

    cfg = TrainConfig()
    assert cfg.algo == "ppo" and cfg.wrappers == ("agent",) and cfg.obs_keys == AGENT_OBS_KEYS
    assert "time" not in cfg.obs_keys
    venv = make_vec_env(cfg)
    try:
        base = _base(venv)
        assert isinstance(base, SB3VecEnv) and isinstance(base.venv.unwrapped, WheeledPumaVectorEnv)
        assert base.num_envs == cfg.n_envs > 1  # N robots in this process, not N processes
        assert isinstance(venv.venv, AgentVecEnv)
        assert venv.action_space.shape == (N_ACTIONS,) and base.action_space.shape == (8,)
        obs = venv.reset()
        assert set(obs) == set(AGENT_OBS_KEYS) and obs["mask"].shape == (cfg.n_envs, N_ACTIONS)
        _, rewards, _, _ = venv.step(np.zeros((cfg.n_envs, N_ACTIONS), np.float32))
        # the alive bonus is added once, on the vec env: error ~0 after one still step, so reward ~ bonus
        assert rewards == pytest.approx(np.full(cfg.n_envs, cfg.alive_bonus), abs=0.05)
    finally:
        venv.close()


def test_physics_keeps_sb3s_vec_envs_with_the_same_interface():
    from stable_baselines3.common.vec_env import DummyVecEnv

    from train.run import make_vec_env

    venv = make_vec_env(TrainConfig(dynamics="physics", n_envs=1))
    try:
        assert isinstance(_base(venv), DummyVecEnv)
        assert venv.action_space.shape == (N_ACTIONS,)
        assert set(venv.reset()) == set(AGENT_OBS_KEYS)
    finally:
        venv.close()


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """The default recipe with a tiny budget (one rollout), a progress line per step, the final evaluation on
    one short episode."""
    from train.run import run

    out = tmp_path_factory.mktemp("native") / "run"
    cfg = TrainConfig(
        timesteps=1,
        n_envs=64,
        seed=3,
        out=str(out),
        env_kwargs={"reward_weights": {"tracking": 20.0, "effort": 0.02}, "error_bound": 0.1, "path": SHORT_PATH},
        eval_freq=0,
        final_eval_episodes=1,
        checkpoint_freq=0,
        log_every_s=1e-6,
        progress_bar=False,
    )
    summary = run(cfg)
    assert summary["status"] == "done"
    return out


def test_a_tiny_default_run_steps_the_robots_and_logs_progress(trained):
    summary = json.loads((trained / "summary.json").read_text())
    cfg = json.loads((trained / "config.json").read_text())
    n_steps = cfg["hyperparams_resolved"]["n_steps"]
    assert summary["timesteps"] == 64 * n_steps  # one rollout of 64 robots
    log = (trained / "train.log").read_text()
    assert "steps/s" in log and "episodes ended: mean return" in log and "success" in log
    assert "final evaluation: 1 episodes each of the agent and zero" in log
    assert "final evaluation results:" in log
    assert (trained / "final_eval.json").is_file()


@pytest.mark.parametrize("env_id, m", [("WheeledPuma-Circle-v0", 8), ("WheeledPanda-Circle-v0", 9)])
def test_the_agent_acts_on_arms_of_6_and_7_joints(trained, env_id, m):
    import warnings

    import policies
    from eval.rollout import rollout

    env = gym.make(env_id, dynamics="kinematic", path=SHORT_PATH)
    try:
        with warnings.catch_warnings():  # "trained on WheeledPuma-Circle-v0 and evaluated on ...": deliberate
            warnings.simplefilter("ignore", UserWarning)
            policy = policies.make(f"sb3:{trained / 'model.zip'}", env)
        obs, _ = env.reset(seed=5)
        action, _ = policy.predict(obs)
        assert action.shape == (m,)
        rec, _ = rollout(env, policy, 5)
    finally:
        env.close()
    assert rec["status"] == "ok" and rec["n_steps"] == 50


def test_a_linear_schedule_never_goes_negative_when_a_rollout_overshoots_the_budget():
    from train.algos import LinearSchedule

    lr = LinearSchedule(3e-4)
    assert lr(1.0) == 3e-4 and lr(0.5) == pytest.approx(1.5e-4)
    assert lr(1 - 32_768 / 1) == 0.0  # SB3's progress after one rollout of 32,768 steps on a budget of 1


def test_n_envs_defaults_to_256_robots_kinematic_and_one_physics_world():
    from train.config import KINEMATIC_N_ENVS, PHYSICS_N_ENVS

    assert TrainConfig().n_envs == KINEMATIC_N_ENVS == 256
    assert TrainConfig(dynamics="physics").n_envs == PHYSICS_N_ENVS == 1
    assert TrainConfig(dynamics="physics", n_envs=2).n_envs == 2
    assert TrainConfig.from_json(TrainConfig(dynamics="physics").to_json()).n_envs == 1


def test_the_progress_line_counts_success_only_for_episodes_run_to_their_end_within_tolerance():
    from train.callbacks import ProgressLog

    cb = ProgressLog(every_s=1e9, tolerance=0.006)
    venv = type("Venv", (), {"num_envs": 3})()
    cb.model = type("Model", (), {"num_timesteps": 0, "get_env": lambda self: venv})()
    cb._on_training_start()

    def step(errors, dones, truncated):
        infos = [{"tracking_error": e} for e in errors]
        for i, (d, t) in enumerate(zip(dones, truncated)):
            if d:
                infos[i].update({"episode": {"r": 10.0 * (i + 1), "l": 2}, "TimeLimit.truncated": t})
        cb.locals = {"infos": infos, "dones": np.array(dones)}
        cb.model.num_timesteps += 3
        cb._on_step()

    step([0.001, 0.007, 0.001], [False, False, False], [False] * 3)
    # robot 0: ran to its end within 6 mm; robot 1: 7 mm once; robot 2: ended early (error bound)
    step([0.002, 0.001, 0.002], [True, True, True], [True, True, False])
    line = cb.line(cb._t0 + 1.0)
    assert "6 steps" in line and "3 episodes ended: mean return 20.0, mean length 2, success 33%" in line
    step([0.001, 0.001, 0.001], [True, False, False], [True, False, False])  # robot 0's new episode, fresh max
    assert "4 episodes ended" in cb.line(cb._t0 + 1.0) and "success 50%" in cb.line(cb._t0 + 1.0)

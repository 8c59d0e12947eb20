"""`sb3:` loads agents saved by plain Stable-Baselines3 and by rl-baselines3-zoo, and acts as SB3 itself would.

Each agent is a tiny PPO (net_arch [16], a few hundred kinematic steps on a 1 s circle) trained here with
plain SB3: the tests are about the files and the observation processing, not about learning. The reference
is SB3's own loop (DummyVecEnv + VecNormalize.load(training=False, norm_reward=False) + model.predict
deterministic), run beside mobman's loader on an identically seeded env.
"""

from __future__ import annotations

import json
import pickle
import shutil
import warnings
from collections import OrderedDict

import gymnasium as gym
import numpy as np
import pytest

import policies

pytest.importorskip("stable_baselines3")

ENV = "WheeledPuma-Circle-v0"
PATH = {"type": "circle", "radius": 0.1, "duration": 1.0}
AGENT_KEYS = ["pos_error", "target_vel", "ee_vel", "joint_pos"]
FLAT_KEYS = ["target_pos", "ee_pos", "ee_vel", "joint_pos"]  # not sorted, on purpose


def _raw_env():
    return gym.make(ENV, dynamics="kinematic", path=PATH)


def _flat_env():
    return gym.wrappers.FlattenObservation(gym.wrappers.FilterObservation(_raw_env(), FLAT_KEYS))


def _agent_view_env():
    from train.wrappers import AgentObservation

    return AgentObservation(_raw_env(), ["pos_error"], AGENT_KEYS)


def _train(make_env, policy: str, out, stats_path, **vn_kwargs):
    """PPO for 256 steps with VecNormalize; model saved to out/model.zip unless moved by the caller."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    torch.set_num_threads(1)
    venv = VecNormalize(DummyVecEnv([make_env]), **vn_kwargs)
    venv.seed(0)
    model = PPO(
        policy, venv, n_steps=128, batch_size=64, n_epochs=2, policy_kwargs={"net_arch": [16]}, seed=0, device="cpu"
    )
    model.set_logger(configure(str(out), []))
    model.learn(256)
    venv.save(str(stats_path))
    venv.close()
    return model


@pytest.fixture(scope="module")
def plain_dir(tmp_path_factory):
    """Plain SB3: a Dict agent on the raw env, statistics under SB3's conventional name vec_normalize.pkl."""
    out = tmp_path_factory.mktemp("plain")
    model = _train(_raw_env, "MultiInputPolicy", out, out / "vec_normalize.pkl", norm_obs=True, norm_reward=True)
    model.save(out / "model.zip")
    return out


@pytest.fixture(scope="module")
def flat_dir(tmp_path_factory):
    """Plain SB3 on FlattenObservation(FilterObservation(env, FLAT_KEYS)); config.json names the keys."""
    out = tmp_path_factory.mktemp("flat")
    model = _train(_flat_env, "MlpPolicy", out, out / "vecnormalize.pkl", norm_obs=True, norm_reward=False)
    model.save(out / "model.zip")
    (out / "config.json").write_text(json.dumps({"obs_keys": FLAT_KEYS}))
    return out


def _zoo_yaml(path, mapping):
    """What rl-zoo writes: yaml.dump of an OrderedDict of the sorted items (hence the python/object tags)."""
    import yaml

    with open(path, "w") as f:
        yaml.dump(OrderedDict([(k, mapping[k]) for k in sorted(mapping)]), f)


ZOO_HP = {
    "env_wrapper": [
        {"train.wrappers.AgentObservation": {"wrappers": ["pos_error"], "obs_keys": AGENT_KEYS}},
        {"train.wrappers.AliveBonus": {"bonus": 2.0}},
    ],
    "normalize": "{'norm_obs': True, 'norm_reward': True}",
    "n_timesteps": 256.0,
    "policy": "MultiInputPolicy",
    "policy_kwargs": "dict(net_arch=[16])",
}
ZOO_ARGS = {"algo": "ppo", "env": ENV, "env_kwargs": {"dynamics": "kinematic", "path": PATH}, "seed": 0}


@pytest.fixture(scope="module")
def zoo_dir(tmp_path_factory):
    """An rl-zoo run folder written as rl_zoo3 2.9.2 writes it: <ENV>.zip, <ENV>/{vecnormalize.pkl, *.yml}."""
    out = tmp_path_factory.mktemp("logs") / "ppo" / f"{ENV}_1"
    (out / ENV).mkdir(parents=True)
    model = _train(_agent_view_env, "MultiInputPolicy", out, out / ENV / "vecnormalize.pkl", norm_obs=True)
    model.save(out / f"{ENV}.zip")
    _zoo_yaml(out / ENV / "config.yml", ZOO_HP)
    _zoo_yaml(out / ENV / "args.yml", ZOO_ARGS)
    return out


def _sb3_loop(model_file, stats_file, make_env, seed, steps=None):
    """SB3's own evaluation: the tracking errors (reset + every step) and the actions of one episode."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize.load(str(stats_file), DummyVecEnv([make_env]))
    venv.training, venv.norm_reward = False, False
    model = PPO.load(model_file, device="cpu")
    venv.seed(seed)
    obs = venv.reset()
    errors, actions = [venv.venv.reset_infos[0]["tracking_error"]], []  # VecNormalize keeps no infos
    while True:
        action, _ = model.predict(obs, deterministic=True)
        obs, _, done, infos = venv.step(action)
        actions.append(action[0])
        errors.append(infos[0]["tracking_error"])
        if done[0] or (steps is not None and len(actions) == steps):
            break
    venv.close()
    return np.array(errors), np.array(actions)


def _assert_acts_as_sb3(actions, expected):
    """mobman's actions (a PPO actor in numpy, `policies.agents.sb3_actor`) are SB3's torch actions to float32 rounding
    (a few 1e-8 per step; the closed loop keeps them within 1e-6 over these short episodes)."""
    assert actions.shape == expected.shape
    np.testing.assert_allclose(actions, expected, rtol=0, atol=1e-6)


def _mobman_actions(spec, seed, n):
    env = _raw_env()
    try:
        policy = policies.make(spec, env)
        obs, _ = env.reset(seed=seed)
        actions = []
        for _ in range(n):
            action, _ = policy.predict(obs)
            actions.append(action)
            obs, *_ = env.step(action)
    finally:
        env.close()
    return policy, np.array(actions)


# --- 5. exactness: eval.run gives SB3's own metrics ------------------------------------------------------
def test_eval_run_of_a_plain_sb3_agent_equals_sb3s_own_loop(plain_dir, tmp_path):
    from eval import EvalConfig, run

    seeds = (10_000, 10_001)
    config = EvalConfig(
        envs=(ENV,),
        policies=(f"sb3:{plain_dir}",),
        episodes=len(seeds),
        seed=seeds[0],
        out=str(tmp_path / "eval"),
        dynamics=("kinematic",),
        env_kwargs={"path": PATH},
        progress=False,
        plots=False,
    )
    episodes = run(config).results["episodes"]
    assert [e["status"] for e in episodes] == ["ok", "ok"]
    for rec, seed in zip(episodes, seeds):
        errors, _ = _sb3_loop(plain_dir / "model.zip", plain_dir / "vec_normalize.pkl", _raw_env, seed)
        assert rec["seed"] == seed and len(errors) == 101
        # eval acts through policies.agents.sb3_actor (numpy, row by row: batch-size independent bits), SB3's loop
        # through torch: the actions agree to float32 rounding, the errors to far below a micrometre
        assert rec["max_error_m"] == pytest.approx(errors.max(), rel=1e-6, abs=1e-10)
        assert rec["rms_error_m"] == pytest.approx(np.sqrt(np.mean(errors**2)), rel=1e-6, abs=1e-10)
    # the statistics matter: unnormalised, the same agent tracks differently
    assert episodes[0]["max_error_m"] != pytest.approx(_unnormalised_max_error(plain_dir, seeds[0]), rel=1e-6)


def _unnormalised_max_error(plain_dir, seed):
    from stable_baselines3 import PPO

    model, env = PPO.load(plain_dir / "model.zip", device="cpu"), _raw_env()
    obs, info = env.reset(seed=seed)
    errors, done = [info["tracking_error"]], False
    while not done:
        obs, _, term, trunc, info = env.step(model.predict(obs, deterministic=True)[0])
        errors.append(info["tracking_error"])
        done = term or trunc
    env.close()
    return max(errors)


# --- 1. statistics under either file name ----------------------------------------------------------------
def test_vec_normalize_pkl_is_read_and_two_statistics_files_are_refused(plain_dir, tmp_path):
    policy, actions = _mobman_actions(f"sb3:{plain_dir / 'model.zip'}", 10_002, 20)
    assert policy.stats_path == plain_dir / "vec_normalize.pkl" and policy._norm is not None
    _, expected = _sb3_loop(plain_dir / "model.zip", plain_dir / "vec_normalize.pkl", _raw_env, 10_002, steps=20)
    _assert_acts_as_sb3(actions, expected)

    both = shutil.copytree(plain_dir, tmp_path / "both")
    shutil.copy(both / "vec_normalize.pkl", both / "vecnormalize.pkl")
    with pytest.raises(ValueError, match=r"two VecNormalize files, vecnormalize.pkl and vec_normalize.pkl"):
        policies.SB3Policy(both)

    crafted = shutil.copytree(plain_dir, tmp_path / "crafted")  # the new name goes through the same unpickler
    marker = tmp_path / "pwned"
    (crafted / "vec_normalize.pkl").write_bytes(pickle.dumps(_System(f"touch {marker}")))
    with pytest.raises(ValueError, match=r"vec_normalize.pkl: refused to load (posix|os)\.system"):
        policies.SB3Policy(crafted)
    assert not marker.exists()


class _System:
    """Pickles as a call of os.system (what a crafted statistics file can do)."""

    def __init__(self, command):
        self.command = command

    def __reduce__(self):
        import os

        return (os.system, (self.command,))


# --- 3. Box observations (FlattenObservation) -------------------------------------------------------------
def test_flatten_observation_agent_acts_as_in_sb3(flat_dir):
    policy, actions = _mobman_actions(f"sb3:{flat_dir}", 10_003, 30)
    assert policy.flattens and policy.obs_keys == tuple(FLAT_KEYS)
    _, expected = _sb3_loop(flat_dir / "model.zip", flat_dir / "vecnormalize.pkl", _flat_env, 10_003, steps=30)
    _assert_acts_as_sb3(actions, expected)
    # gymnasium's order is the sorted keys, not FLAT_KEYS' order
    flat, raw = _flat_env(), _raw_env()
    obs, _ = flat.reset(seed=10_004)
    raw_obs, _ = raw.reset(seed=10_004)
    flat.close(), raw.close()
    np.testing.assert_array_equal(policy._view(raw_obs), obs)
    in_given_order = np.concatenate([raw_obs[k] for k in FLAT_KEYS])
    assert not np.array_equal(in_given_order, obs)  # the test would notice the wrong order


# --- 4. space mismatches are refused before any rollout ----------------------------------------------------
def test_box_agent_without_its_keys_is_refused_naming_both_spaces(flat_dir, tmp_path):
    bare = shutil.copytree(flat_dir, tmp_path / "bare")
    (bare / "config.json").unlink()  # now the loader would flatten all 10 keys (34 numbers), not 17
    env = _raw_env()
    try:
        with pytest.raises(ValueError, match=r"takes observations Box\(.*\(17,\).*is Box\(.*\(34,\)"):
            policies.make(f"sb3:{bare}", env)
    finally:
        env.close()


class _SixJoints(gym.ObservationWrapper):
    """An env whose joint_pos has 6 entries (an agent trained for another robot has such a space)."""

    def __init__(self, env):
        super().__init__(env)
        spaces = dict(env.observation_space.spaces)
        spaces["joint_pos"] = gym.spaces.Box(-1e5, 1e5, (6,), np.float32)
        self.observation_space = gym.spaces.Dict(spaces)

    def observation(self, obs):
        return {**obs, "joint_pos": obs["joint_pos"][:6]}


def test_observation_and_action_space_mismatch_refused_before_any_episode(plain_dir, tmp_path):
    from stable_baselines3 import PPO

    from eval import EvalConfig, EvalError, run

    bad_obs = tmp_path / "obs"
    bad_obs.mkdir()
    six = _train(
        lambda: _SixJoints(_raw_env()), "MultiInputPolicy", bad_obs, bad_obs / "vecnormalize.pkl", norm_obs=True
    )
    six.save(bad_obs / "model.zip")
    bad_act = shutil.copytree(plain_dir, tmp_path / "act")  # a model.zip recording another action space
    model = PPO.load(plain_dir / "model.zip", device="cpu")
    model.action_space = gym.spaces.Box(-0.5, 0.5, (8,), np.float32)
    model.save(bad_act / "model.zip")
    out = tmp_path / "eval"
    config = dict(envs=(ENV,), episodes=1, dynamics=("kinematic",), env_kwargs={"path": PATH}, progress=False)
    with pytest.raises(EvalError, match=r"takes observations Dict\(.*'joint_pos': Box\(.*\(6,\).*\(8,\)"):
        run(EvalConfig(policies=(f"sb3:{bad_obs}",), out=str(out), **config))
    assert not out.exists()  # refused before any episode ran
    with pytest.raises(EvalError, match=r"actions in Box\(-0.5, 0.5, \(8,\).*env takes Box\(-1, 1, \(8,\)"):
        run(EvalConfig(policies=(f"sb3:{bad_act}",), out=str(out), **config))


# --- 2. rl-baselines3-zoo run folders ----------------------------------------------------------------------
def test_zoo_run_folder_is_read_and_acts_as_in_sb3(zoo_dir):
    policy, actions = _mobman_actions(f"sb3:{zoo_dir}", 10_005, 30)
    assert policy.layout == "zoo" and policy.path == zoo_dir / f"{ENV}.zip" and policy.algo == "ppo"
    assert policy.wrappers == ("pos_error",) and policy.obs_keys == tuple(AGENT_KEYS)
    assert policy.stats_path == zoo_dir / ENV / "vecnormalize.pkl"
    assert policy.trained_env == {"env_id": ENV, "env_kwargs": {"dynamics": "kinematic", "path": PATH}}
    _, expected = _sb3_loop(zoo_dir / f"{ENV}.zip", zoo_dir / ENV / "vecnormalize.pkl", _agent_view_env, 10_005, 30)
    _assert_acts_as_sb3(actions, expected)


def test_zoo_prefers_the_final_model_and_says_so(zoo_dir, tmp_path):
    d = shutil.copytree(zoo_dir, tmp_path / f"{ENV}_2")
    shutil.copy(d / f"{ENV}.zip", d / "best_model.zip")
    with pytest.warns(UserWarning, match=rf"took the final model {ENV}.zip, not best_model.zip"):
        policy = policies.SB3Policy(d)
    assert policy.path == d / f"{ENV}.zip"
    (d / f"{ENV}.zip").unlink()
    with pytest.warns(UserWarning, match=r"took best_model.zip: the final model .* is missing"):
        assert policies.SB3Policy(d).path == d / "best_model.zip"


def test_zoo_config_it_cannot_reproduce_is_refused(zoo_dir, tmp_path):
    d = shutil.copytree(zoo_dir, tmp_path / f"{ENV}_3")
    wrappers = [*ZOO_HP["env_wrapper"], "gymnasium.wrappers.FrameStackObservation"]
    _zoo_yaml(d / ENV / "config.yml", {**ZOO_HP, "env_wrapper": wrappers})
    with pytest.raises(ValueError, match=r"env_wrapper 'gymnasium.wrappers.FrameStackObservation' cannot be repro"):
        policies.SB3Policy(d)
    _zoo_yaml(d / ENV / "config.yml", ZOO_HP)
    (d / ENV / "vecnormalize.pkl").unlink()
    with pytest.raises(ValueError, match=r"normalised observations, but .*vecnormalize.pkl is missing"):
        policies.SB3Policy(d)
    (d / ENV / "config.yml").write_text("!!python/object/apply:os.system\n- echo pwned\n")
    with pytest.raises(ValueError, match=r"config.yml is not a readable rl-zoo YAML file"):
        policies.SB3Policy(d)


def test_zoo_agent_on_another_env_warns(zoo_dir):
    env = gym.make("WheeledPuma-Line-v0", dynamics="kinematic")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            with pytest.raises(UserWarning, match=rf"trained on {ENV} and is evaluated on WheeledPuma-Line-v0"):
                policies.make(f"sb3:{zoo_dir}", env)
    finally:
        env.close()


def test_shipped_hyperparameter_files_are_zoo_format_with_algos_defaults():
    from pathlib import Path

    import yaml

    import train
    from train import algos

    folder = Path(train.__file__).parent / "hyperparams"
    ppo = yaml.safe_load((folder / "ppo.yml").read_text())[ENV]
    sac = yaml.safe_load((folder / "sac.yml").read_text())[ENV]
    ppo_defaults = algos.ALGOS["ppo"].defaults
    assert {k: ppo[k] for k in ("n_steps", "batch_size", "n_epochs")} == {
        k: ppo_defaults[k] for k in ("n_steps", "batch_size", "n_epochs")
    }
    assert ppo["n_timesteps"] == 5e6
    defaults = algos.ALGOS["sac"].defaults
    assert {k: sac[k] for k in defaults if k != "policy_kwargs"} == {
        k: v for k, v in defaults.items() if k != "policy_kwargs"
    }
    assert eval(sac["policy_kwargs"], {"dict": dict}) == defaults["policy_kwargs"]
    for hp in (ppo, sac):  # the loader accepts what these files make rl-zoo save
        assert policies.agents.sb3._zoo_view(hp, folder) == {
            "wrappers": ["agent"],  # the robot-independent agent interface (policies.agents.agent_interface)
            "obs_keys": list(ppo["env_wrapper"][0]["train.wrappers.AgentObservation"]["obs_keys"]),
        }

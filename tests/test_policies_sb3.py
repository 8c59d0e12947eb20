"""`SB3Policy`: a run folder (model.zip, vecnormalize.pkl, config.json) behind the Policy contract.

The agent is a tiny SAC trained here for 200 steps: the test is about loading and observation processing
(the same numbers the agent saw in training), not about learning.
"""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from conftest import SHORT_CIRCLE

import policies

pytest.importorskip("stable_baselines3")

OBS_KEYS = ["pos_error", "ee_vel", "target_vel", "joint_pos"]


class _AgentView(gym.ObservationWrapper):
    """What a mobman-train agent sees: `pos_error` added, then the dict reduced to OBS_KEYS."""

    def __init__(self, env):
        super().__init__(env)
        spaces = dict(env.observation_space.spaces)
        spaces["pos_error"] = gym.spaces.Box(-2000.0, 2000.0, (3,), np.float32)
        self.observation_space = gym.spaces.Dict({k: spaces[k] for k in OBS_KEYS})

    def observation(self, obs):
        obs = dict(obs)
        obs["pos_error"] = (obs["target_pos"] - obs["ee_pos"]).astype(np.float32)
        return {k: obs[k] for k in OBS_KEYS}


def _make_env():
    return _AgentView(gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE))


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    import torch
    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("run")
    venv = VecNormalize(
        DummyVecEnv([_make_env]),
        norm_obs=True,
        norm_reward=False,
        clip_obs=5.0,
        norm_obs_keys=["pos_error", "ee_vel", "joint_pos"],
    )  # target_vel left raw on purpose
    venv.seed(0)
    model = SAC(
        "MultiInputPolicy",
        venv,
        learning_starts=100,
        batch_size=32,
        buffer_size=1000,
        policy_kwargs={"net_arch": [16, 16]},
        seed=0,
        device="cpu",
    )
    from stable_baselines3.common.logger import configure

    model.set_logger(configure(str(out), []))  # not SB3's default /tmp/SB3-<date> folder
    model.learn(200)
    model.save(out / "model.zip")
    venv.save(str(out / "vecnormalize.pkl"))
    config = {
        "algo": "sac",
        "env_id": "WheeledPuma-Circle-v0",
        "env_kwargs": {"dynamics": "kinematic"},
        "obs_keys": OBS_KEYS,
        "wrappers": ["pos_error"],
    }
    (out / "config.json").write_text(json.dumps(config))
    venv.close()
    return out


@pytest.fixture
def env():
    e = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE)
    yield e
    e.close()


def _reference(run_dir, obs_batch):
    """The action SB3 itself gives: VecNormalize.normalize_obs on the agent's view, then model.predict."""
    import pickle

    from stable_baselines3 import SAC

    with open(run_dir / "vecnormalize.pkl", "rb") as f:
        vn = pickle.load(f)
    model = SAC.load(run_dir / "model.zip", device="cpu")
    view = _AgentView.observation(None, obs_batch)
    return model.predict(vn.normalize_obs(view), deterministic=True)[0], vn


def test_sb3_policy_matches_sb3_on_the_agents_view(run_dir, env):
    policy = policies.make(f"sb3:{run_dir / 'model.zip'}", env)
    assert policy.algo == "sac" and policy.obs_keys == tuple(OBS_KEYS) and policy.wrappers == ("pos_error",)
    obs, _ = env.reset(seed=10_000)
    for _ in range(30):
        batch = {k: v[None] for k, v in obs.items()}
        expected, vn = _reference(run_dir, batch)
        action, _ = policy.predict(batch)
        np.testing.assert_array_equal(action, expected)
        single, _ = policy.predict(obs)
        np.testing.assert_array_equal(single, expected[0])
        # only the normalised keys are normalised, exactly as VecNormalize does
        mine = policy.transform(batch)
        ref = vn.normalize_obs(_AgentView.observation(None, batch))
        for k in OBS_KEYS:
            np.testing.assert_array_equal(mine[k], ref[k])
        np.testing.assert_array_equal(mine["target_vel"], batch["target_vel"])
        obs, *_ = env.step(single)
    assert np.any(np.abs(mine["joint_pos"]) > 0)


def test_sb3_policy_runs_in_evaluate_policy_and_takes_longer_batches(run_dir):
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import DummyVecEnv

    factory = lambda: Monitor(gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE))
    venv = DummyVecEnv([factory, factory])
    try:
        policy = policies.make(f"sb3:{run_dir}", venv)  # the run folder works as well as its model.zip
        rewards, lengths = evaluate_policy(policy, venv, n_eval_episodes=2, return_episode_rewards=True)
        obs = venv.reset()
        actions, _ = policy.predict(obs)
    finally:
        venv.close()
    assert lengths == [100, 100] and all(np.isfinite(rewards))
    assert actions.shape == (2, 8) and np.all(np.abs(actions) <= 1.0)


def test_sb3_policy_finds_the_algorithm_without_config(run_dir, tmp_path, env):
    import shutil

    d = tmp_path / "bare"
    d.mkdir()
    shutil.copy(run_dir / "model.zip", d / "model.zip")
    shutil.copy(run_dir / "vecnormalize.pkl", d / "vecnormalize.pkl")
    cfg = json.loads((run_dir / "config.json").read_text())
    del cfg["algo"]
    (d / "config.json").write_text(json.dumps(cfg))
    policy = policies.SB3Policy(d / "model.zip")
    assert policy.algo == "sac"
    obs, _ = env.reset(seed=10_001)
    reference = policies.SB3Policy(run_dir / "model.zip")
    np.testing.assert_array_equal(policy.predict(obs)[0], reference.predict(obs)[0])


def test_sb3_policy_refuses_what_it_cannot_reproduce(run_dir, tmp_path, env):
    import shutil

    d = tmp_path / "odd"
    d.mkdir()
    shutil.copy(run_dir / "model.zip", d / "model.zip")
    cfg = json.loads((run_dir / "config.json").read_text())
    (d / "config.json").write_text(json.dumps({**cfg, "wrappers": ["pos_error", "FrameStack"]}))
    with pytest.raises(ValueError, match="wrapper 'FrameStack' cannot be reproduced.*supported: pos_error"):
        policies.make(f"sb3:{d / 'model.zip'}", env)
    (d / "config.json").write_text(json.dumps({**cfg, "obs_keys": ["ee_pos", "ee_vel"]}))
    with pytest.raises(ValueError, match="differ from the model's observation keys"):
        policies.make(f"sb3:{d / 'model.zip'}", env)
    (d / "config.json").write_text(json.dumps({**cfg, "algo": "dqn"}))
    with pytest.raises(ValueError, match="unknown algo 'dqn'; accepted: ppo, sac, td3"):
        policies.make(f"sb3:{d / 'model.zip'}", env)


# --- files that are corrupt, crafted or missing their extras -------------------------------------------------
def _copy_run(run_dir, dest):
    import shutil

    shutil.copytree(run_dir, dest)
    return dest


class _System:
    """Pickles as a call of os.system (what a crafted vecnormalize.pkl or model.zip entry can do)."""

    def __init__(self, command):
        self.command = command

    def __reduce__(self):
        import os

        return (os.system, (self.command,))


def test_crafted_vecnormalize_pickle_is_refused_not_run(run_dir, tmp_path, env):
    import pickle

    d = _copy_run(run_dir, tmp_path / "crafted")
    marker = tmp_path / "pwned"
    (d / "vecnormalize.pkl").write_bytes(pickle.dumps(_System(f"touch {marker}")))
    with pytest.raises(ValueError, match=r"vecnormalize.pkl: refused to load (posix|os)\.system.*trust"):
        policies.make(f"sb3:{d}", env)
    assert not marker.exists()


def test_crafted_model_zip_entry_is_refused_not_run(run_dir, tmp_path, env):
    import base64
    import pickle
    import zipfile

    d = _copy_run(run_dir, tmp_path / "crafted")
    marker = tmp_path / "pwned"
    with zipfile.ZipFile(run_dir / "model.zip") as zf:
        entries = {name: zf.read(name) for name in zf.namelist()}
    data = json.loads(entries["data"])
    data["observation_space"][":serialized:"] = base64.b64encode(pickle.dumps(_System(f"touch {marker}"))).decode()
    entries["data"] = json.dumps(data).encode()
    with zipfile.ZipFile(d / "model.zip", "w") as zf:
        for name, blob in entries.items():
            zf.writestr(name, blob)
    with pytest.raises(ValueError, match=r"entry 'observation_space': refused to load (posix|os)\.system"):
        policies.make(f"sb3:{d}", env)
    assert not marker.exists()


def _pos_error_view(obs, keys):
    obs = {**obs, "pos_error": obs["target_pos"] - obs["ee_pos"]}
    return {k: obs[k] for k in keys}


def test_shipped_agent_loads_with_the_restricted_unpickler(env):
    """The packaged baseline reads through the restricted paths and acts exactly as SB3's own loaders."""
    import pickle

    from stable_baselines3 import SAC

    policy = policies.make("sb3:sac-circle", env)
    with open(policy.run_dir / "vecnormalize.pkl", "rb") as f:
        vn = pickle.load(f)  # trusted here: the reference
    obs, _ = env.reset(seed=10_002)
    view = {k: np.asarray(v, dtype=np.float32) for k, v in _pos_error_view(obs, policy.obs_keys).items()}
    ref = SAC.load(policy.path, device="cpu").predict(vn.normalize_obs(view), deterministic=True)
    np.testing.assert_array_equal(policy.predict(obs)[0], ref[0])


@pytest.mark.parametrize(
    "name, content, match",
    [
        ("model.zip", b"not a zip", r"model.zip is not a Stable-Baselines3 model file"),
        ("vecnormalize.pkl", b"\x80\x04garbage", r"vecnormalize.pkl is not a readable VecNormalize file"),
        ("config.json", b"{not json", r"config.json is not a readable JSON file"),
    ],
)
def test_corrupt_files_are_named_once(run_dir, tmp_path, env, name, content, match):
    d = _copy_run(run_dir, tmp_path / "corrupt")
    (d / name).write_bytes(content)
    with pytest.raises(ValueError, match=match) as exc:
        policies.make(f"sb3:{d}", env)
    text = str(exc.value)
    assert text.count("wasn't a zip") <= 1 and 'add "algo"' not in text


def test_sb3_without_torch_names_the_extra(tmp_path):
    import subprocess
    import sys

    code = (
        "import sys; sys.modules['torch'] = None\n"  # torch hidden: its import fails
        "import gymnasium as gym, policies\n"
        "env = gym.make('WheeledPuma-Circle-v0', dynamics='kinematic')\n"
        "try:\n    policies.make('sb3:sac-circle', env)\n"
        "except ImportError as exc:\n    print(exc)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "need Stable-Baselines3 and torch, which are not installed here" in out.stdout, out.stderr
    assert 'install them with pip install "mobman[rl]"' in out.stdout


# --- which statistics are read, and the record of what was loaded ---------------------------------------------
def _shipped_copy(tmp_path, name="sac-circle"):
    import shutil

    return shutil.copytree(policies.agents.sb3.MODELS_DIR / name, tmp_path / name)


class _NotStatistics:
    """Pickles as a plain object of an allowed class (a set), not VecNormalize statistics."""

    def __reduce__(self):
        return (set, ([1, 2],))


def _not_statistics(kind: str) -> bytes:
    import pickle

    from stable_baselines3.common.running_mean_std import RunningMeanStd
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    if kind == "array":
        return pickle.dumps(np.zeros(3))
    if kind == "dict":
        return pickle.dumps({"obs_rms": {"mean": np.zeros(3)}})
    if kind == "set":
        return pickle.dumps(_NotStatistics())
    if kind == "running_mean_std":
        return pickle.dumps(RunningMeanStd(shape=(3,)))
    venv = VecNormalize(DummyVecEnv([_make_env]), norm_obs=False, norm_reward=True)  # reward-only statistics
    venv.venv.close()
    return pickle.dumps(venv)


@pytest.mark.parametrize("kind", ["array", "dict", "set", "running_mean_std", "norm_obs_off"])
def test_statistics_that_are_not_the_agents_are_refused(tmp_path, env, kind):
    d = _shipped_copy(tmp_path)
    (d / "vecnormalize.pkl").write_bytes(_not_statistics(kind))
    match = r"normalize_obs is true but .*norm_obs off" if kind == "norm_obs_off" else "does not hold VecNormalize stat"
    with pytest.raises(ValueError, match=match):
        policies.make(f"sb3:{d}", env)


def test_normalize_obs_without_statistics_is_refused(tmp_path, env):
    d = _shipped_copy(tmp_path)
    (d / "vecnormalize.pkl").unlink()
    with pytest.raises(ValueError, match=r"config.json: normalize_obs is true .* holds no vecnormalize.pkl; copy it"):
        policies.make(f"sb3:{d}", env)
    cfg = json.loads((d / "config.json").read_text())
    (d / "config.json").write_text(json.dumps({**cfg, "normalize_obs": False}))
    assert policies.make(f"sb3:{d}", env)._norm is None  # an agent trained without statistics loads


def test_statistics_under_another_name_are_named_in_a_warning(tmp_path, env):
    d = _shipped_copy(tmp_path)
    (d / "vecnormalize.pkl").rename(d / "stats.pkl")
    cfg = json.loads((d / "config.json").read_text())
    del cfg["normalize_obs"]  # a plain SB3 folder does not say
    (d / "config.json").write_text(json.dumps(cfg))
    with pytest.warns(UserWarning, match=r"stats.pkl not used: only vecnormalize.pkl or vec_normalize.pkl is read"):
        policies.make(f"sb3:{d}", env)


def test_artefacts_name_every_file_loaded_with_its_sha256(tmp_path, env):
    import hashlib

    d = _shipped_copy(tmp_path)
    policy = policies.make(f"sb3:{d}", env)
    expected = [
        {"path": str(d / name), "sha256": hashlib.sha256((d / name).read_bytes()).hexdigest()}
        for name in ("model.zip", "vecnormalize.pkl", "config.json")
    ]
    assert policy.artefacts == expected
    venv = gym.make_vec("WheeledPuma-Circle-v0", num_envs=2, vectorization_mode="vector_entry_point")
    try:
        assert policies.make(f"sb3:{d}", venv).artefacts == expected  # the rows' files, each once
        assert policies.make("clik", venv).artefacts == []
    finally:
        venv.close()


def test_episode_records_hold_the_files_loaded_and_the_robot(tmp_path):
    """The record of an evaluated episode says which files its agent loaded (path and SHA-256, as read at load
    time) and which robot ran; a controller's record has no artefacts."""
    import hashlib

    from eval.rollout import rollout

    d = _shipped_copy(tmp_path)
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE)
    try:
        rec, _ = rollout(env, policies.make(f"sb3:{d}", env), 10000)
        assert rec["status"] == "ok" and rec["robot"] == "puma560" and rec["knowledge"] == "none"
        assert rec["artefacts"] == [
            {"path": str(d / name), "sha256": hashlib.sha256((d / name).read_bytes()).hexdigest()}
            for name in ("model.zip", "vecnormalize.pkl", "config.json")
        ]
    finally:
        env.close()
    env = gym.make("WheeledUR5-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE)
    try:
        rec, _ = rollout(env, policies.make("clik", env), 10000)
        assert rec["status"] == "ok" and rec["robot"] == "ur5" and rec["artefacts"] is None
        assert rec["knowledge"] == "nominal"
    finally:
        env.close()

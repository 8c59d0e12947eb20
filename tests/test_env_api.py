"""The env's Gymnasium contract: checkers, spaces, seeding, rewards, info, errors, registration, docs."""

from __future__ import annotations

import inspect
import math
import re
import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import SHORT_CIRCLE

import mobman_env
from mobman_env import ENV_IDS, WheeledPumaEnv

# Warnings the checkers may legitimately raise for this env (regex, with the reason); anything else fails the
# test. Empty on purpose: neither gymnasium's nor SB3's checker warns about this env (finite Dict boxes, float32,
# a symmetric normalised action space, declared render modes).
WARNING_WHITELIST: tuple[str, ...] = ()


def _no_unexpected(caught):
    bad = [str(w.message) for w in caught if not any(re.search(p, str(w.message)) for p in WARNING_WHITELIST)]
    assert not bad, f"unexpected warnings: {bad}"


def _gymnasium_check(env):
    from gymnasium.utils.env_checker import check_env

    check_env(env.unwrapped, skip_render_check=True)


def _sb3_check(env):
    from stable_baselines3.common.env_checker import check_env

    check_env(env.unwrapped, warn=True)


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize(
    "checker, dynamics", [(_gymnasium_check, "kinematic"), (_sb3_check, "physics")], ids=["gymnasium", "sb3"]
)
def test_env_checkers(env_id, checker, dynamics):
    env = gym.make(env_id, dynamics=dynamics)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            checker(env)
        _no_unexpected(caught)
    finally:
        env.close()


def _rollout(env, seed, n=150):
    obs, info = env.reset(seed=seed)
    rng = np.random.default_rng(123)
    out = [obs]
    for _ in range(n):
        obs, r, term, trunc, info = env.step(rng.uniform(-0.3, 0.3, 8).astype(np.float32))
        out.append(obs)
        out.append({"r": np.array([r])})
    return out


@pytest.mark.parametrize("dynamics", ["kinematic", "physics"])
def test_same_seed_bit_identical(make_env, dynamics):
    a = _rollout(make_env(dynamics=dynamics, obs_noise=0.001, obs_noise_vel=0.01), 5)
    b = _rollout(make_env(dynamics=dynamics, obs_noise=0.001, obs_noise_vel=0.01), 5)
    c = _rollout(make_env(dynamics=dynamics, obs_noise=0.001, obs_noise_vel=0.01), 6)
    for x, y in zip(a, b):
        for k in x:
            assert np.array_equal(x[k], y[k]), k
    assert not all(np.array_equal(x[k], y[k]) for x, y in zip(a, c) for k in x)


@pytest.mark.parametrize("dynamics", ["kinematic", "physics"])
def test_obs_inside_space_and_reward_is_sum_of_terms(make_env, dynamics):
    env = make_env(dynamics=dynamics, reward_weights={"tracking": 2.0, "effort": 0.5})
    obs, info = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    rng = np.random.default_rng(0)
    for _ in range(200):
        obs, reward, term, trunc, info = env.step(rng.uniform(-1.5, 1.5, 8))
        assert env.observation_space.contains(obs)
        assert reward == sum(info["reward_terms"].values())
        assert set(info["reward_terms"]) == {"tracking", "effort"}
        assert info["reward_terms"]["tracking"] == pytest.approx(-2.0 * info["tracking_error"], abs=0)
        if term or trunc:
            break


def test_info_keys_and_task(make_env):
    env = make_env(dynamics="kinematic")
    obs, info = env.reset(seed=0)
    assert info["task"]["path"]["type"] == "circle" and info["task"]["start"] == pytest.approx(obs["ee_pos"], abs=1e-6)
    assert info["tracking_error"] == 0.0 and "true_params" not in info
    obs, r, term, trunc, info = env.step(np.full(8, 2.0))
    assert info["action_clipped"] and info["n_clipped"] == 1
    obs, r, term, trunc, info = env.step(np.zeros(8))
    assert not info["action_clipped"] and info["n_clipped"] == 1
    for key in ("ee_pos_true", "tracking_error", "reward_terms", "joint_limit_hits", "tipped_over", "true_params_hash"):
        assert key in info
    assert "true_params" not in info
    assert info["true_params_hash"] == env.unwrapped.true_params.hash()


def test_true_robot_per_reset_from_seed(make_env):
    env = make_env(dynamics="kinematic")
    env.reset(seed=1)
    p1 = env.true_params
    env.reset(seed=2)
    p2 = env.true_params
    env.reset(seed=1)
    assert env.true_params == p1 and p1 != p2 and p1 != env.nominal_params
    env0 = make_env(dynamics="kinematic", model_error=0.0)
    env0.reset(seed=1)
    assert env0.true_params == env0.nominal_params


def test_truncation_at_duration_and_error_bound(make_env):
    env = make_env(dynamics="kinematic", path=SHORT_CIRCLE, control_freq=50)
    env.reset(seed=0)
    steps = 0
    while True:
        steps += 1
        obs, r, term, trunc, info = env.step(np.zeros(8))
        if trunc or term:
            break
    assert trunc and not term and steps == 50 and obs["time"][0] == pytest.approx(1.0)
    env = make_env(dynamics="kinematic", error_bound=0.01)
    env.reset(seed=0)
    for _ in range(300):
        obs, r, term, trunc, info = env.step(np.zeros(8))
        if term:
            break
    assert term and info["tracking_error"] > 0.01


def test_sensor_noise_changes_obs_not_truth(make_env):
    clean = make_env(dynamics="kinematic")
    noisy = make_env(dynamics="kinematic", obs_noise=0.01, obs_noise_vel=0.05)
    o1, i1 = clean.reset(seed=3)
    o2, i2 = noisy.reset(seed=3)
    for _ in range(20):
        a = np.full(8, 0.1)
        o1, _, _, _, i1 = clean.step(a)
        o2, _, _, _, i2 = noisy.step(a)
    np.testing.assert_array_equal(i1["ee_pos_true"], i2["ee_pos_true"])
    assert i1["tracking_error"] == i2["tracking_error"]
    assert 0.001 < np.abs(o1["ee_pos"] - o2["ee_pos"]).max() < 0.06
    assert np.abs(o1["ee_vel"] - o2["ee_vel"]).max() > 0.005
    np.testing.assert_array_equal(o1["joint_pos"], o2["joint_pos"])


def test_reset_options_override_for_one_episode(make_env):
    env = make_env(dynamics="kinematic")
    obs, info = env.reset(
        seed=0,
        options={"path": SHORT_CIRCLE, "base_pose": [1.0, 2.0, 0.0], "arm_joint_pos": [0.1, 0.7, -0.2, 1.0, -0.5, 0.0]},
    )
    assert info["task"]["path"]["duration"] == 1.0 and info["task"]["base_pose"] == [1.0, 2.0, 0.0]
    assert obs["joint_pos"][:6] == pytest.approx([0.1, 0.7, -0.2, 1.0, -0.5, 0.0], abs=1e-6)
    obs, info = env.reset(seed=0)
    assert info["task"]["path"]["duration"] == 20.0 and info["task"]["base_pose"][2] == pytest.approx(math.pi)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"dynamics": "rigid"}, "unknown dynamics mode 'rigid'; accepted: physics, kinematic"),
        ({"control_freq": 0}, "control_freq must be a finite number > 0"),
        ({"control_freq": -5}, "control_freq must be a finite number > 0"),
        ({"obs_noise": -0.1}, "obs_noise must be a finite number >= 0"),
        ({"obs_noise_vel": float("nan")}, "obs_noise_vel must be a finite number >= 0"),
        ({"model_error": -1}, "model_error must be a finite number >= 0"),
        ({"n_substeps": 0}, "n_substeps must be an integer >= 1"),
        ({"path": {"type": "spiral"}}, "unknown path type 'spiral'; known: circle, line, lemniscate, random"),
        ({"path": {"type": "circle", "radius": 0}}, "radius must be a finite number > 0"),
        ({"arm_joint_pos": [0, 1, 2]}, "arm_joint_pos must be 6 or 8 finite numbers"),
        ({"arm_joint_pos": [0, 4.5, 0, 0, 0, 0]}, "outside the joint limits"),
        ({"base_pose": [0, 0]}, "base_pose must be 3 finite numbers"),
        ({"reward_weights": {"speed": 1.0}}, "reward_weights must be a dict with keys from"),
        ({"render_mode": "video"}, "unknown render_mode 'video'; accepted"),
        # bools, numeric strings and complex numbers are not numbers (obs_noise=True would be 1 m of noise)
        ({"obs_noise": True}, "obs_noise must be a finite number >= 0, got True"),
        ({"obs_noise_vel": "0.1"}, "obs_noise_vel must be a finite number >= 0, got '0.1'"),
        (
            {"obs_noise_joint_vel": 1j},
            r"obs_noise_joint_vel must be a finite number >= 0, got 1j \(standard deviation, rad/s\)",
        ),
        ({"control_freq": True}, "control_freq must be a finite number > 0 and <= 10000, got True"),
        ({"n_substeps": 2.0}, "n_substeps must be an integer >= 1 and <= 1000, got 2.0"),
        ({"error_bound": False}, "error_bound must be a finite number >= 0, got False"),
        ({"reward_weights": {"effort": True}}, r"reward_weights\['effort'\] must be a finite number >= 0, got True"),
        ({"base_pose": [0, 0, "3"]}, r"base_pose must be 3 finite numbers, got \[0, 0, '3'\]"),
        ({"arm_joint_pos": [0, True, 0, 0, 0, 0]}, "arm_joint_pos must be 6 or 8 finite numbers"),
        # model_error: lengths are scaled by factors in [max(0.1, 1 - 3 model_error), 1 + 3 model_error]
        ({"model_error": 1 / 3}, r"model_error must be a finite number >= 0 and < 0.333333, got 0.333.*a tenth.*1/3"),
        ({"model_error": 5.0}, "model_error must be a finite number >= 0 and < 0.333333, got 5.0"),
        # the release-0.2 options
        ({"obs_delay": -1}, r"obs_delay must be an integer >= 0 and <= 10000, got -1 \(control steps\)"),
        ({"obs_delay": 1.0}, "obs_delay must be an integer >= 0 and <= 10000, got 1.0"),
        ({"obs_delay": True}, "obs_delay must be an integer"),
        ({"wear_rate": 0.2, "dynamics": "kinematic"}, "wear_rate must be a finite number >= -0.1 and <= 0.1, got 0.2"),
        ({"wear_rate": 0.01}, "wear_rate=0.01 needs dynamics='kinematic': a loaded PyBullet body cannot change"),
        (
            {"wear_rate": -0.05, "dynamics": "kinematic"},
            r"over a 20 s path .*a tenth.*\|wear_rate\| \* duration must stay <= 0.9 \(here \|wear_rate\| <= 0.045",
        ),
        (  # 0.9 of the lengths in 20 s would leave a tenth: still accepted; beyond, refused
            {"wear_rate": -0.046, "dynamics": "kinematic"},
            r"must stay <= 0.9",
        ),
    ],
)
def test_bad_constructor_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        WheeledPumaEnv(**kwargs)


def test_joint_limit_message_prints_plain_numbers():
    with pytest.raises(ValueError, match=r"arm_joint_pos \[0.0, 4.5, 0.0, 0.0, 0.0, 0.0\] is outside") as exc:
        WheeledPumaEnv(arm_joint_pos=np.array([0, 4.5, 0, 0, 0, 0]))
    assert "np.float64" not in str(exc.value) and "upper [2.7925, 3.927, " in str(exc.value)


@pytest.mark.parametrize("dynamics", ["kinematic", "physics"])
def test_model_error_0_3_keeps_every_length_positive(make_env, dynamics):
    """0.3 is the largest condition of the benchmark protocol: factors stay in [0.1, 1.9]."""
    from mobman_env.params import PERTURBED_FIELDS

    env = make_env(dynamics=dynamics, model_error=0.3, path=SHORT_CIRCLE)
    for seed in range(20):
        env.reset(seed=seed)
        for name in PERTURBED_FIELDS:
            ratio = getattr(env.true_params, name) / getattr(env.nominal_params, name)
            assert 0.1 - 1e-12 <= ratio <= 1.9 + 1e-12, (seed, name, ratio)
    env.step(np.zeros(8))


@pytest.mark.parametrize("dynamics", ["kinematic", "physics"])
def test_closed_env_refuses_reset_step_render_alike(dynamics):
    env = WheeledPumaEnv(dynamics=dynamics, path=SHORT_CIRCLE, render_mode="rgb_array")
    env.reset(seed=0)
    env.close()
    env.close()  # safe twice
    for call in (lambda: env.step(np.zeros(8)), lambda: env.reset(seed=0), env.render):
        with pytest.raises(RuntimeError, match=r"the env is closed; make a new one with gym.make\(\.\.\.\)"):
            call()


def test_bad_reset_options_and_actions(make_env):
    env = make_env(dynamics="kinematic")
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(8))
    with pytest.raises(ValueError, match=r"unknown reset option\(s\) \['start'\]; accepted: 'path', 'arm_joint_pos'"):
        env.reset(options={"start": [0, 0, 0]})
    with pytest.raises(ValueError, match=r"reset options must be a dict .*, got 'abc'; accepted keys: 'path'"):
        env.reset(options="abc")
    with pytest.raises(ValueError, match="obs_noise must be a finite number >= 0, got True"):
        env.reset(options={"obs_noise": True})
    with pytest.raises(ValueError, match="seed must be None or an integer >= 0, got True"):
        env.reset(seed=True)
    with pytest.raises(ValueError, match="line path: direction must be 3 finite numbers .*, got 'x'"):
        env.reset(options={"path": {"type": "line", "direction": "x"}})
    with pytest.raises(ValueError, match="unknown path type"):
        env.reset(options={"path": {"type": "square"}})
    with pytest.raises(ValueError, match="arm_joint_pos must be 6 or 8 finite numbers"):
        env.reset(options={"arm_joint_pos": [0.0] * 7})
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(8,\)"):
        env.step(np.zeros(7))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0, 0, np.nan, 0, 0, 0, 0, 0]))
    with pytest.raises(ValueError, match="finite"):
        env.step(np.array([0, 0, 0, 0, 0, 0, np.inf, 0]))
    with pytest.raises(ValueError, match="action must be real numbers .*complex: the imaginary part would be lost"):
        env.step(np.zeros(8) + 0.1j)
    with pytest.raises(ValueError, match="action must be real numbers"):
        env.step(["0.1"] * 8)
    with pytest.raises(ValueError, match="action must be real numbers"):
        env.step(np.ones(8, dtype=bool))
    env.step(np.zeros(8, dtype=np.int64))  # integers are real numbers


def test_registration_twice_is_harmless_and_silent():
    before = {k: gym.registry[k] for k in ENV_IDS}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mobman_env.register_envs()
        import importlib

        importlib.reload(mobman_env)
    assert {k: gym.registry[k].kwargs for k in ENV_IDS} == {k: before[k].kwargs for k in ENV_IDS}
    # the entries registered before the reload still pickle (an async vector env sends the spec to its workers)
    import pickle

    for k in ENV_IDS:
        assert pickle.loads(pickle.dumps(gym.spec(k))).kwargs == before[k].kwargs


def test_make_without_prior_import_and_import_is_light():
    code = (
        "import sys, gymnasium as gym\n"
        "env = gym.make('mobman_env:WheeledPuma-Line-v0', dynamics='kinematic'); env.reset(seed=0); env.close()\n"
        "assert 'torch' not in sys.modules and 'stable_baselines3' not in sys.modules, 'heavy import'\n"
        "import mobman_env\n"
        "assert 'torch' not in sys.modules and 'stable_baselines3' not in sys.modules\n"
        "print('ok')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
    # PyBullet's banners stay off stdout
    assert "pybullet build time" not in out.stdout


def test_make_vec_async():
    envs = gym.make_vec(
        "mobman_env:WheeledPuma-Circle-v0", num_envs=2, vectorization_mode="async", dynamics="kinematic"
    )
    try:
        obs, info = envs.reset(seed=[0, 1])
        assert obs["ee_pos"].shape == (2, 3)
        obs, r, term, trunc, info = envs.step(np.zeros((2, 8), np.float32))
        assert r.shape == (2,)
    finally:
        envs.close()


def test_docstring_arguments_table_matches_signature():
    doc = WheeledPumaEnv.__doc__
    table = doc.split("## Arguments")[1].split("##")[0]
    rows = dict(re.findall(r"^\s*\| (\w+) \| ([^|]+) \|", table, re.M))
    rows.pop("argument", None)
    sig = inspect.signature(WheeledPumaEnv.__init__).parameters
    assert set(rows) == set(sig) - {"self"}
    for name, default in rows.items():
        assert repr(sig[name].default) == default.strip().replace('"', "'"), name
    for section in (
        "Description",
        "Action Space",
        "Observation Space",
        "Rewards",
        "Starting State",
        "Episode End",
        "Arguments",
        "Version History",
    ):
        assert f"## {section}" in doc


@pytest.mark.parametrize("model_error", [0.05, 0.0])
def test_episode_does_not_depend_on_earlier_episodes(make_env, model_error):
    """Physics mode: an episode run after another one is bit-identical to the same episode in a fresh env
    (what `--workers N` relies on); with model_error 0 the loaded body is reused across resets."""
    fresh = _rollout(make_env(dynamics="physics", model_error=model_error), 5, n=100)
    used = make_env(dynamics="physics", model_error=model_error)
    _rollout(used, 3, n=100)
    again = _rollout(used, 5, n=100)
    for x, y in zip(fresh, again):
        for k in x:
            assert np.array_equal(x[k], y[k]), k


def test_gymnasium_default_check_env_passes_headless(monkeypatch):
    """`check_env` with its defaults also builds a `render_mode="human"` env through the spec: without a display
    that env warns (the only warning allowed) and runs without a window instead of raising."""
    from gymnasium.utils.env_checker import check_env

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            check_env(env.unwrapped)
        messages = [str(w.message) for w in caught]
        assert any("render_mode='human' needs a display" in m for m in messages)
        assert all("render_mode='human' needs a display" in m for m in messages), messages
    finally:
        env.close()


def test_render_fps_is_the_control_frequency_and_record_video_plays_in_real_time(tmp_path):
    """gymnasium's RecordVideo writes one frame per step at `metadata["render_fps"]`: the file's frame rate is
    the env's control frequency (per instance; the class dict is untouched), so the video lasts as long as the
    episode."""
    pytest.importorskip("moviepy")
    imageio = pytest.importorskip("imageio.v2")
    from gymnasium.wrappers import RecordVideo

    class_fps = WheeledPumaEnv.metadata["render_fps"]
    env = gym.make(
        "WheeledPuma-Circle-v0", dynamics="kinematic", control_freq=20.0, path=SHORT_CIRCLE, render_mode="rgb_array"
    )
    assert env.metadata["render_fps"] == 20.0 and WheeledPumaEnv.metadata["render_fps"] == class_fps
    env = RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda k: True, name_prefix="circle")
    try:
        env.reset(seed=0)
        steps = 0
        while True:
            steps += 1
            *_, term, trunc, _ = env.step(np.zeros(8, np.float32))
            if term or trunc:
                break
    finally:
        env.close()
    (video,) = (tmp_path / "videos").glob("circle*.mp4")
    reader = imageio.get_reader(video)
    try:
        fps, n_frames = reader.get_meta_data()["fps"], reader.count_frames()
    finally:
        reader.close()
    assert fps == pytest.approx(20.0) and steps == 20
    assert n_frames == steps + 1  # the reset frame and one per step: 1.05 s of video for 1 s of episode

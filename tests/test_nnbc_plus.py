"""`nnbc-plus` (policies/laws/nnbc_plus.py): the model-free controller that fixes the paper's NNBC (issue 6).

Kinematic mode, full 20 s episodes, a few reported seeds per claim (DESIGN "Seeds": the gains were tuned on seeds
0-999 only). The claims asserted here are the issue's targets on a reduced seed set: every task tracked within
the paper's 6 mm, also from a J_hat(0) perturbed by 50% of its norm, with 1 mm position noise and with 10% model
error.
"""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import mobman_env
from mobman_env import kinematics as K
from policies.base import EnvFacts
from policies.laws.nnbc_plus import NNBCPlus, NNBCPlusConfig

REPORTED_SEEDS = range(10_000, 10_005)
TOLERANCE = 0.006  # m: the paper's maximum error, the success criterion of the issue
TASKS = ("Circle", "Line", "Lemniscate", "Random")


def make_env(task: str, **kwargs) -> gym.Env:
    return gym.make(f"WheeledPuma-{task}-v0", dynamics="kinematic", **kwargs)


def rollout(env: gym.Env, policy: NNBCPlus, seed: int, n_steps: int | None = None) -> dict:
    """One episode; returns the true (noise-free) tracking errors and the last info."""
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info, seed=seed)
    errors, actions = [], []
    while True:
        action, _ = policy.predict(obs)
        actions.append(action)
        obs, _, terminated, truncated, info = env.step(action)
        errors.append(info["tracking_error"])
        if terminated or truncated or (n_steps is not None and len(errors) >= n_steps):
            break
    e = np.asarray(errors)
    return {"max": float(e.max()), "rms": float(np.sqrt(np.mean(e**2))), "actions": np.array(actions), "info": info}


def run_seeds(task: str, config: NNBCPlusConfig | None = None, **env_kwargs) -> list[dict]:
    env = make_env(task, **env_kwargs)
    try:
        policy = NNBCPlus(EnvFacts.from_env(env), config)
        return [rollout(env, policy, seed) for seed in REPORTED_SEEDS]
    finally:
        env.close()


def plant_obs(q, r, u, J, t, target, target_vel) -> dict:
    """The observation of a linear plant r_dot = J u at joint angles q and speeds u (no platform, heading 0)."""
    return {
        "ee_pos": r.copy(), "ee_vel": J @ u, "arm_base_pos": np.zeros(2), "arm_base_vel": np.zeros(2),
        "joint_pos": q.copy(), "joint_vel": u.copy(), "target_pos": target, "target_vel": target_vel,
        "base_yaw": np.zeros(1), "time": np.array([t]),
    }  # fmt: skip


# --- accuracy claims ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("task", TASKS)
def test_tracks_every_task_within_the_papers_6mm(task):
    results = run_seeds(task)
    worst = [round(r["max"] * 1e3, 2) for r in results]
    assert all(r["max"] <= TOLERANCE for r in results), f"{task}: max errors (mm) over seeds {worst}"
    if task == "Circle":
        median_rms = np.median([r["rms"] for r in results])
        assert median_rms <= 0.5e-3, f"Circle median RMS {median_rms * 1e3:.3f} mm > 0.5 mm"


@pytest.mark.parametrize("task", ["Circle", "Line"])
def test_physics_mode_tracks_within_the_papers_6mm(task):
    """PyBullet contact dynamics (the default mode): two reported seeds per task (about 1 s per episode)."""
    env = gym.make(f"WheeledPuma-{task}-v0", dynamics="physics")
    try:
        policy = NNBCPlus(EnvFacts.from_env(env))
        results = [rollout(env, policy, seed) for seed in REPORTED_SEEDS[:2]]
    finally:
        env.close()
    assert all(r["max"] <= TOLERANCE for r in results), [round(r["max"] * 1e3, 2) for r in results]


def test_spec_registry_builds_it_with_options():
    """`policies.make("nnbc-plus:...")` builds this class from EnvFacts with the spec's options."""
    import policies

    env = make_env("Circle")
    try:
        policy = policies.make("nnbc-plus:j0_noise=0.5,gamma=15", env)
        assert isinstance(policy, NNBCPlus)
        assert policy.config.j0_noise == 0.5 and policy.config.gamma == 15.0
        assert isinstance(policy.config.gamma, float)
    finally:
        env.close()


def test_robust_to_a_50_percent_perturbed_initial_jacobian():
    results = run_seeds("Circle", NNBCPlusConfig(j0_noise=0.5))
    assert all(r["max"] <= TOLERANCE for r in results), [round(r["max"] * 1e3, 2) for r in results]


def test_position_noise_of_1mm_keeps_the_true_error_within_6mm():
    results = run_seeds("Circle", obs_noise=0.001)
    assert all(r["max"] <= TOLERANCE for r in results), [round(r["max"] * 1e3, 2) for r in results]


def test_velocity_sensor_noise_is_tolerated_without_being_told():
    """Issue 16: 1 mm on positions and 0.01 m/s on ee_vel and arm_base_vel with the default gains (v1 needed
    meas_std = the sensor's noise): the Kalman filter estimates its measurement noise from its innovations."""
    results = run_seeds("Circle", obs_noise=0.001, obs_noise_vel=0.01)
    assert all(r["max"] <= TOLERANCE for r in results), [round(r["max"] * 1e3, 2) for r in results]


def test_joint_speed_noise_is_tolerated():
    """Issue 16: 0.01 rad/s of noise on the measured actuator speeds (the estimator's regressor)."""
    results = run_seeds("Lemniscate", obs_noise_joint_vel=0.01)
    assert all(r["max"] <= TOLERANCE for r in results), [round(r["max"] * 1e3, 2) for r in results]


def test_observation_delay_is_found_and_compensated():
    """Issue 16: observations 2 control steps old. The controller finds the delay (its measured actuator speeds
    match the command of 3 steps before) and predicts the fed-back position forward by the commands since:
    the error stays at the delay-free level (v1: 4.2 mm median, development seeds), and off it is larger."""
    env = make_env("Circle", obs_delay=2)
    try:
        facts = EnvFacts.from_env(env)
        policy = NNBCPlus(facts)
        on = [rollout(env, policy, seed) for seed in REPORTED_SEEDS[:3]]
        assert policy.delay_estimate == 2
        off = rollout(env, NNBCPlus(facts, NNBCPlusConfig(max_delay=0)), REPORTED_SEEDS[0])
    finally:
        env.close()
    assert all(r["max"] <= 1.5e-3 for r in on), [round(r["max"] * 1e3, 2) for r in on]
    assert off["max"] > 2 * on[0]["max"], (off["max"], on[0]["max"])


def test_a_5_second_circle_is_tracked_while_probing():
    """Issue 16: the paper's circle in 5 s moves 6.3 mm during a 16-step probe that stands still (v1: 0/25);
    the probe now runs on top of the tracking, which uses each actuator as soon as it has been probed."""
    path = {**mobman_env.env.PAPER_CIRCLE, "duration": 5.0}
    results = run_seeds("Circle", path=path)
    assert all(r["max"] <= 3e-3 for r in results), [round(r["max"] * 1e3, 2) for r in results]


def test_an_actuator_at_its_stop_is_taken_out_of_the_pseudo_inverse():
    """Issue 16, random starts: a start with joint 4 near its stop (2.967 rad). The joint is commanded and does
    not move; the controller marks it blocked, lets the other actuators do the task and the pull move it off the
    stop. Without (block_release=0) it keeps commanding the stuck joint (measured on this episode: 5.8 mm, 531 stop
    hits, against 1.9 mm and 21)."""
    q0 = list(mobman_env.env.PAPER_ARM_JOINT_POS)
    q0[3] = 2.92
    env = make_env("Lemniscate", arm_joint_pos=q0)
    try:
        facts, seed = EnvFacts.from_env(env), REPORTED_SEEDS[0]
        policy = NNBCPlus(facts)
        on = rollout(env, policy, seed)
        off = rollout(env, NNBCPlus(facts, NNBCPlusConfig(block_release=0.0)), seed)
    finally:
        env.close()
    assert on["max"] <= 3e-3 and off["max"] > 1.5 * on["max"], (on["max"], off["max"])
    assert on["info"]["joint_limit_hits"] < 0.5 * off["info"]["joint_limit_hits"]


def test_any_number_of_actuators_on_a_linear_plant():
    """n-generic (issue 13's UR5 has 8 actuators, the Panda 9): the controller sizes itself from
    len(facts.action_scale). On a plant r_dot = J u with a constant random 3 x 9 J it learns J and tracks."""
    n, dt = 9, 0.01
    facts = EnvFacts(dt=dt, action_scale=(3.0,) * 7 + (10.0, 10.0), obs_keys=mobman_env.OBS_KEYS)
    rng = np.random.default_rng(5)
    J = 0.3 * rng.standard_normal((3, n))
    policy = NNBCPlus(facts, NNBCPlusConfig(formulation="whole_body"), seed=1)  # (a linear plant: no platform)
    assert policy.n_act == 9 and policy.n_arm == 7 and policy.n_probe == 18
    q, r, u = np.zeros(n), np.zeros(3), np.zeros(n)
    errors = []
    for k in range(600):
        t = k * dt
        target = 0.05 * np.array([np.sin(t), 1.0 - np.cos(t), 0.5 * np.sin(2 * t)])
        target_vel = 0.05 * np.array([np.cos(t), np.sin(t), np.cos(2 * t)])
        obs = plant_obs(q, r, u, J, t, target, target_vel)
        action, _ = policy.predict(obs)
        assert action.shape == (n,)
        u = np.asarray(action, float) * facts.scale
        q = q + dt * u
        r = r + dt * J @ u
        errors.append(
            np.linalg.norm(r - 0.05 * np.array([np.sin(t + dt), 1 - np.cos(t + dt), 0.5 * np.sin(2 * t + 2 * dt)]))
        )
    assert np.linalg.norm(policy.J_hat - J) < 0.05 * np.linalg.norm(J)
    assert max(errors[100:]) < 1e-3, max(errors[100:])


def test_position_filter_reduces_the_effect_of_noise():
    """The complementary filter (pos_filter) is what keeps noisy feedback small: off, the error is larger."""
    env = make_env("Circle", obs_noise=0.001)
    try:
        facts = EnvFacts.from_env(env)
        seed = REPORTED_SEEDS[0]
        on = rollout(env, NNBCPlus(facts), seed)
        off = rollout(env, NNBCPlus(facts, NNBCPlusConfig(pos_filter=1.0)), seed)
    finally:
        env.close()
    assert on["rms"] < 0.8 * off["rms"], (on["rms"], off["rms"])


def test_ten_percent_model_error_changes_nothing():
    results = run_seeds("Circle", model_error=0.10)
    assert all(r["max"] <= TOLERANCE for r in results), [round(r["max"] * 1e3, 2) for r in results]


# --- the estimator -----------------------------------------------------------------------------------------
def test_probe_recovers_the_true_whole_body_jacobian():
    """After the 16 probe steps J_hat equals the true whole-body Jacobian to 2% of its norm (the probe is the
    only source of J_hat(0): no model is read). v4's 0.02 rad/s probe leaves 1.6% on this seed (the arm moves
    with the tracking while it probes, and the probe is smaller beside that motion); v3's 0.05 rad/s, under 1%."""
    env = make_env("Circle")
    try:
        policy = NNBCPlus(EnvFacts.from_env(env), NNBCPlusConfig(dither=0.0, task_dither=0.0))
        rollout(env, policy, REPORTED_SEEDS[0], n_steps=17)
        base = env.unwrapped
        state = base.state()
        J = K.whole_body_jacobian(base.true_params, state.joint_pos[:6], state.base_pose[2])
    finally:
        env.close()
    assert np.linalg.norm(policy.J_hat - J) <= 0.02 * np.linalg.norm(J)


def test_the_estimate_follows_the_true_jacobian_in_every_direction():
    """The paper's failure mode: J_hat's smallest singular value collapses while the true one does not. Here
    J_hat stays close to the true Jacobian over the whole circle (every direction is kept fresh)."""
    env = make_env("Circle")
    try:
        policy = NNBCPlus(EnvFacts.from_env(env))
        obs, info = env.reset(seed=REPORTED_SEEDS[1])
        policy.reset(obs, info, seed=REPORTED_SEEDS[1])
        base = env.unwrapped
        rel_errors, sv_ratio = [], []
        for k in range(2000):
            action, _ = policy.predict(obs)
            obs, _, terminated, truncated, info = env.step(action)
            if k > 50 and k % 50 == 0:
                state = base.state()
                J = K.whole_body_jacobian(base.true_params, state.joint_pos[:6], state.base_pose[2])
                rel_errors.append(np.linalg.norm(policy.J_hat - J) / np.linalg.norm(J))
                sv_ratio.append(
                    np.linalg.svd(policy.J_hat, compute_uv=False)[-1] / np.linalg.svd(J, compute_uv=False)[-1]
                )
            if terminated or truncated:
                break
    finally:
        env.close()
    # development seeds 0-2: at most 5% relative error (median 1.5%), singular-value ratio 0.97-1.00; the
    # paper's update collapses the ratio below 0.5 on this circle
    assert max(rel_errors) < 0.1, f"largest relative error of J_hat: {max(rel_errors):.3f}"
    assert min(sv_ratio) > 0.8 and max(sv_ratio) < 1.25, (min(sv_ratio), max(sv_ratio))


# --- contract ----------------------------------------------------------------------------------------------
def test_same_seed_same_actions_and_episode_start_reinitialises():
    env = make_env("Random")
    try:
        facts = EnvFacts.from_env(env)
        policy = NNBCPlus(facts)
        first = rollout(env, policy, 3, n_steps=120)["actions"]
        again = rollout(env, NNBCPlus(facts), 3, n_steps=120)["actions"]
        np.testing.assert_array_equal(first, again)
        # SB3 never calls reset(): after 120 steps, a batched predict with episode_start=[True] must start a new
        # episode (the probe again, from an empty estimate)
        assert np.abs(policy.J_hat).sum() > 0
        obs, _ = env.reset(seed=4)
        batched = {k: v[None] for k, v in obs.items()}
        action, _ = policy.predict(batched, episode_start=np.array([True]))
        expected = np.zeros(8, dtype=np.float32)  # the probe's first step; nothing else moves yet
        expected[0] = policy.config.probe_speed / facts.action_scale[0]
        np.testing.assert_allclose(action, expected[None], rtol=1e-6)
        assert not policy.J_hat.any()
    finally:
        env.close()


def test_model_free_construction_and_config_validation():
    facts = EnvFacts(dt=0.01, action_scale=(3, 3, 3, 5, 5, 5, 10, 10), obs_keys=mobman_env.OBS_KEYS)
    with pytest.raises(TypeError, match="model-free"):
        NNBCPlus(facts, nominal_params=object())
    with pytest.raises(ValueError, match="formulation"):
        NNBCPlusConfig(formulation="full")
    with pytest.raises(ValueError, match="pos_filter"):
        NNBCPlusConfig(pos_filter=1.5)
    for bad in (0.0, 1.5):  # a weight in (0, 1]: 0 would never read the heading, above 1 overshoots it
        with pytest.raises(ValueError, match=r"heading_filter must be a finite number > 0 and <= 1"):
            NNBCPlusConfig(heading_filter=bad)
    with pytest.raises(ValueError, match="gamma"):
        NNBCPlusConfig(gamma=-1.0)
    cfg = NNBCPlusConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.gamma = 1.0  # type: ignore[misc]
    # every numeric gain is validated by name (a field whose annotation escaped the check would pass silently)
    for f in dataclasses.fields(NNBCPlusConfig):
        if isinstance(getattr(cfg, f.name), float):
            for bad in (-1.0, float("nan"), True):
                with pytest.raises(ValueError, match=f.name):
                    NNBCPlusConfig(**{f.name: bad})
    # every gain is documented in the source of the class that declares it (one docstring per field; the
    # scaffolding's fields live in the base class ModelFreeConfig)
    assert_every_field_documented(NNBCPlusConfig)


def test_the_manual_lists_every_option_with_its_default():
    """The options table of the module docstring (the controller's manual) names every field of NNBCPlusConfig,
    in declaration order, with the field's default, so the manual and the code cannot drift."""
    import ast
    import re

    from policies.laws import nnbc_plus

    rows = re.findall(r"^\| `(\w+)` \| ([^|]+) \|", nnbc_plus.__doc__ or "", re.M)
    assert [name for name, _ in rows] == [f.name for f in dataclasses.fields(NNBCPlusConfig)]
    cfg = NNBCPlusConfig()
    for name, default in rows:
        assert ast.literal_eval(default.strip()) == getattr(cfg, name), name


def assert_every_field_documented(config_cls: type) -> None:
    """Each dataclass field has a docstring right after its declaration, in the class of the MRO declaring it."""
    import inspect

    for f in dataclasses.fields(config_cls):
        owner = next(k for k in config_cls.__mro__ if f.name in vars(k).get("__annotations__", {}))
        src = inspect.getsource(owner)
        line = next(ln for ln in src.splitlines() if ln.strip().startswith(f"{f.name}:"))
        after = src.split(line, 1)[1].lstrip()
        assert after.startswith('"""'), f"config field {f.name} of {owner.__name__} has no docstring"


def test_a_joint_stop_is_detected_within_two_steps_ur5_line():
    """Issue 16 / robots bench: the UR5's elbow reaches its stop (pi) about 8 s into Line-v0 while the platform
    takes over the straight line. Until the controller sees the stop, the task loses the elbow's share of the
    motion (about 1 mm per step at 0.1 m/s): checked every 4 steps (2 checks in a row: 8 steps), that cost 7.5 mm
    on this development episode (9 of development seeds 0-9 failed); checked every step, 2.3 mm."""
    env = gym.make("WheeledUR5-Line-v0", dynamics="kinematic")
    try:
        facts, seed = EnvFacts.from_env(env), 0  # a development seed: this is a regression test, not a claim
        now = rollout(env, NNBCPlus(facts), seed)
        before = rollout(env, NNBCPlus(facts, NNBCPlusConfig(block_every=4)), seed)
    finally:
        env.close()
    assert now["info"]["joint_limit_hits"] > 0  # the stop is reached: the test exercises the detection
    assert now["max"] <= 4e-3 < TOLERANCE < before["max"], (now["max"], before["max"])


# --- v4 (issue 28): actuator lag and heading noise ----------------------------------------------------------------
def test_a_lagging_actuator_is_neither_a_delay_nor_a_joint_stop():
    """Issue 28: with a 50 ms first-order actuator lag (`actuator_tau`, the dev track's `lag`) v3 read the lag as
    a 1-3 step observation delay and as blocked joints and lost every episode (0/64 on the reported dev seeds,
    807-1470 mm median on the PUMA). v4 matches the speeds against lag models too: it finds the lag, compensates
    no delay, blocks nothing and tracks within the paper's 6 mm; the same env with a real 2-step delay is still
    read as a delay."""
    from policies.laws.nnbc_plus import LAG_TAUS

    results, models, blocked = [], [], []
    env = make_env("Lemniscate", actuator_tau=0.05)
    try:
        policy = NNBCPlus(EnvFacts.from_env(env))
        for seed in REPORTED_SEEDS[:3]:
            obs, info = env.reset(seed=seed)
            policy.reset(obs, info, seed=seed)
            errors, n_blocked = [], 0
            while True:
                action, _ = policy.predict(obs)
                obs, _, terminated, truncated, info = env.step(action)
                errors.append(info["tracking_error"])
                n_blocked += int(policy.blocked.any())
                if terminated or truncated:
                    break
            results.append(max(errors))
            models.append(policy.actuator_model)
            blocked.append(n_blocked)
            assert policy.delay_estimate == 0
    finally:
        env.close()
    nearest = min(range(len(LAG_TAUS)), key=lambda k: abs(LAG_TAUS[k] - 0.05))  # v5.1: 0.0502 s
    lag_index = policy.config.max_delay + 1 + nearest
    assert models == [lag_index] * 3, models
    assert blocked == [0, 0, 0], blocked
    assert max(results) <= TOLERANCE, [round(e * 1e3, 2) for e in results]


def test_heading_noise_does_not_reach_the_estimate():
    """Issue 28: 1 mrad of noise on `base_yaw` (the dev track's `yaw-noise`) is 0.14 rad/s of noise on its finite
    difference at 100 Hz; v3 turned the arm's measurement into the platform's frame with it and tracked 22% of the
    dev track's yaw-noise episodes. v4 filters the heading with the wheel map's rate (`heading_filter`): the
    episodes are tracked within the paper's 6 mm, and with the raw heading (heading_filter=1) they are not."""
    filtered = run_seeds("Circle", obs_noise_yaw=0.001)
    raw = run_seeds("Circle", NNBCPlusConfig(heading_filter=1.0), obs_noise_yaw=0.001)
    assert all(r["max"] <= TOLERANCE for r in filtered), [round(r["max"] * 1e3, 2) for r in filtered]
    assert np.median([r["max"] for r in raw]) > 2 * np.median([r["max"] for r in filtered])

"""The native vector env (`mobman_env.vector`): robot i equals a single kinematic env reset with seed S + i, bit
for bit (observations, rewards, terminations, truncations, the metric fields of info), under Gymnasium's
autoreset semantics, for the 4 tasks and every env option; seeds >= 10,000."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import mobman_env
from mobman_env import TASKS, WheeledPumaEnv
from mobman_env import engine as E
from mobman_env import kinematics as K
from mobman_env.vector import MAX_NUM_ENVS, PhysicsVectorEnv, WheeledPumaVectorEnv

METRIC_KEYS = ("tracking_error", "n_clipped", "joint_limit_hits", "true_params_hash")
STEP_KEYS = ("action_clipped", "tipped_over")


def _vec(env_id: str, n: int, **kwargs):
    return gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point", dynamics="kinematic", **kwargs)


def _check_row(i, obs, info, o, inf, where):
    for k in obs:
        assert np.array_equal(obs[k][i], o[k]), (where, i, k, obs[k][i], o[k])
        assert obs[k].dtype == np.float32
    for k in METRIC_KEYS:
        if k in inf:
            assert info[f"_{k}"][i] and info[k][i] == inf[k], (where, i, k, info[k][i], inf[k])
    assert np.array_equal(info["ee_pos_true"][i], inf["ee_pos_true"]), (where, i)
    for k in STEP_KEYS:
        if k in inf:
            assert info[k][i] == inf[k], (where, i, k)
    if "reward_terms" in inf:
        for k, v in inf["reward_terms"].items():
            assert info["reward_terms"][k][i] == v, (where, i, k)


def _compare(env_id, kwargs, n, steps, seed, options=None, mode=AutoresetMode.NEXT_STEP):
    venv = _vec(env_id, n, autoreset_mode=mode, **kwargs)
    singles = [gym.make(env_id, dynamics="kinematic", **kwargs) for _ in range(n)]
    try:
        assert venv.metadata["autoreset_mode"] == mode
        rng = np.random.default_rng(seed)
        obs, info = venv.reset(seed=seed, options=options)
        done = np.zeros(n, dtype=bool)
        for i, env in enumerate(singles):
            o, inf = env.reset(seed=seed + i, options=options)
            _check_row(i, obs, info, o, inf, "reset")
            assert info["task"]["path"]["_type"][i] and info["task"]["duration"][i] == inf["task"]["duration"]
        ends = 0
        for t in range(steps):
            a = rng.uniform(-1.2, 1.2, (n, venv.single_action_space.shape[0]))  # partly outside [-1, 1]: clipping
            obs, rew, term, trunc, info = venv.step(a)
            for i, env in enumerate(singles):
                if mode == AutoresetMode.NEXT_STEP and done[i]:
                    o, inf = env.reset()
                    r, te, tr = 0.0, False, False
                else:
                    o, r, te, tr, inf = env.step(a[i])
                    if mode == AutoresetMode.SAME_STEP and (te or tr):
                        for k in o:
                            assert np.array_equal(info["final_obs"][i][k], o[k])
                        assert info["final_info"][i]["tracking_error"] == inf["tracking_error"]
                        o, inf = env.reset()
                assert rew[i] == r and term[i] == te and trunc[i] == tr, (t, i, rew[i], r)
                _check_row(i, obs, info, o, inf, t)
                done[i] = te or tr
                ends += te or tr
        return ends
    finally:
        venv.close()
        for env in singles:
            env.close()


@pytest.mark.parametrize("env_id", mobman_env.env_ids("puma560"))
def test_tasks_equal_single_envs_over_episodes_and_autoresets(env_id):
    short = dict(TASKS[env_id], duration=0.6)  # 60 steps: 150 steps cross two autoresets
    assert _compare(env_id, {"path": short}, n=6, steps=150, seed=10_000) == 12


@pytest.mark.parametrize("robot", ["ur5", "panda"])
@pytest.mark.parametrize("seed", [10_600, 10_700])
def test_other_arms_equal_single_envs_over_whole_episodes(robot, seed):
    """UR5 (standard DH, 6 joints) and Panda (modified DH, 7 joints, 9 actuators): every task, whole default-length
    episodes would take minutes on a shared machine, so each task runs 2 s episodes across an autoreset, with
    model error, wear, noise and delay on the last two tasks."""
    ids = mobman_env.env_ids(robot)
    for k, env_id in enumerate(ids):
        spec = mobman_env.ROBOT_TASKS[env_id][1]
        extra = {"wear_rate": 0.01, "obs_noise": 0.001, "obs_delay": 2, "model_error": 0.1} if k >= 2 else {}
        venv = _vec(env_id, 3)
        assert isinstance(venv, WheeledPumaVectorEnv)
        venv.close()
        assert _compare(env_id, {"path": dict(spec, duration=2.0), **extra}, n=3, steps=230, seed=seed) == 3


def test_random_arms_are_native_each_robot_its_own_arm():
    """robot="random" draws a new arm per reset from robot i's generator: the native vector env holds a different
    arm per row, each equal to its single env."""
    env_id = mobman_env.env_ids("random")[0]
    venv = _vec(env_id, 2)
    assert isinstance(venv, WheeledPumaVectorEnv)
    venv.reset(seed=10_800)
    assert venv.unwrapped.nominal_params_of(0).arm != venv.unwrapped.nominal_params_of(1).arm
    venv.close()
    short = dict(TASKS["WheeledPuma-Circle-v0"], duration=0.2)
    assert _compare(env_id, {"path": short}, n=2, steps=25, seed=10_800) == 2


@pytest.mark.parametrize(
    ("kwargs", "options"),
    [
        ({"obs_noise": 0.001, "obs_noise_vel": 0.01, "obs_noise_joint_vel": 0.02, "model_error": 0.1}, None),
        ({"obs_delay": 3, "wear_rate": 0.01}, None),
        ({"model_error": 0.0}, {"obs_delay": 2, "wear_rate": -0.02, "obs_noise": 0.01, "model_error": 0.2}),
        ({"error_bound": 0.02}, None),  # robots end at different steps
        ({}, {"arm_joint_pos": [0.1, 0.7, -0.4, 0.2, -0.8, 0.3], "base_pose": [0.5, -0.2, 2.0]}),
    ],
)
def test_env_options_equal_single_envs(kwargs, options):
    path = dict(TASKS["WheeledPuma-Random-v0"], duration=0.8)
    _compare("mobman_env:WheeledPuma-Random-v0", {"path": path, **kwargs}, 5, 120, 10_100, options)


def test_same_step_autoreset_equals_single_envs():
    path = dict(TASKS["WheeledPuma-Circle-v0"], duration=0.3)
    assert _compare("WheeledPuma-Circle-v0", {"path": path}, 5, 70, 10_200, mode=AutoresetMode.SAME_STEP) == 10


def test_full_episode_at_a_thousand_robots_sampled():
    """Default task and length, N = 1,027; 4 robots compared with their single envs over 400 steps."""
    n, seed = 1027, 10_300
    venv = _vec("WheeledPuma-Lemniscate-v0", n)
    rows = (0, 5, 1024, 1026)
    singles = {i: WheeledPumaEnv(dynamics="kinematic", path=TASKS["WheeledPuma-Lemniscate-v0"]) for i in rows}
    rng = np.random.default_rng(seed)
    obs, info = venv.reset(seed=seed)
    for i, env in singles.items():
        _check_row(i, obs, info, *env.reset(seed=seed + i), "reset")
    for t in range(400):
        a = rng.uniform(-1, 1, (n, 8))
        obs, rew, term, trunc, info = venv.step(a)
        for i, env in singles.items():
            o, r, te, tr, inf = env.step(a[i])
            assert rew[i] == r and term[i] == te and trunc[i] == tr
            _check_row(i, obs, info, o, inf, t)
    venv.close()


def _reset_work(n: int, **kwargs) -> int:
    """The Python lines `mobman_env` runs in one reset of an N-robot vector env (a count of work, not a time)."""
    import sys
    from pathlib import Path

    package = str(Path(mobman_env.__file__).parent)
    venv = _vec("WheeledPuma-Circle-v0", n, **kwargs)
    lines = 0

    def local(frame, event, arg):
        nonlocal lines
        lines += event == "line"
        return local

    def calls(frame, event, arg):
        return local if frame.f_code.co_filename.startswith(package) else None

    sys.settrace(calls)
    try:
        venv.reset(seed=10_400)
    finally:
        sys.settrace(None)
        venv.close()
    return lines


@pytest.mark.parametrize("kwargs", [{}, {"obs_noise": 0.001, "obs_noise_yaw": 0.01}], ids=["clean", "noisy"])
def test_a_reset_does_work_linear_in_the_number_of_robots(kwargs):
    """4x the robots, 4x the work: `RobotBatch.begin` once rebuilt the list of noisy rows over all N rows for
    every row, so 16,384 robots took 59-113 s to reset and 65,536 over 5 minutes."""
    small, large = _reset_work(64, **kwargs), _reset_work(256, **kwargs)
    assert large <= 4.2 * small, (small, large)


@pytest.mark.parametrize(
    "env_id", ["WheeledPuma-Circle-v0", "WheeledUR5-Line-v0", "WheeledPanda-Circle-v0", "WheeledRandomArm-Line-v0"]
)
def test_one_call_of_many_states_equals_the_per_state_functions(env_id):
    """One robot's Jacobians at many states in one engine call (eval's Jacobian metrics) equal, bit for bit, the
    per-state functions of `mobman_env.kinematics`: standard and modified DH, theta offsets, worn lengths."""
    env = gym.make(env_id, dynamics="kinematic")
    env.reset(seed=10_401)
    p = env.unwrapped.true_params
    env.close()
    rng = np.random.default_rng(10_402)
    q, yaw = rng.uniform(-3.0, 3.0, (23, p.n_joints)), rng.uniform(-7.0, 7.0, 23)
    arm, prm = E.packed([p])
    for full, single in ((False, K.paper_jacobian), (True, K.whole_body_jacobian)):
        expected = np.array([single(p, q[i], float(yaw[i])) for i in range(len(q))])
        got = np.empty(expected.shape)
        E.jacobians(arm, prm, np.zeros(len(q), dtype=np.intp), q, yaw, full, got)
        assert np.array_equal(got, expected)


def test_spaces_and_physics_fallback():
    venv = _vec("WheeledPuma-Circle-v0", 3)
    assert isinstance(venv, WheeledPumaVectorEnv)
    assert venv.observation_space["ee_pos"].shape == (3, 3) and venv.action_space.shape == (3, 8)
    obs, _ = venv.reset(seed=10_600)
    assert venv.observation_space.contains(obs)
    venv.close()
    phys = gym.make_vec("WheeledPuma-Circle-v0", num_envs=2, vectorization_mode="vector_entry_point")
    assert isinstance(phys, PhysicsVectorEnv) and isinstance(phys, gym.vector.SyncVectorEnv)
    assert phys.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    phys.close()


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: WheeledPumaVectorEnv(0), r"num_envs must be an integer in \[1, "),
        (lambda: WheeledPumaVectorEnv(10**12), r"1000000000000.*step several vector envs"),
        (lambda: WheeledPumaVectorEnv(MAX_NUM_ENVS + 1), "num_envs"),
        (lambda: WheeledPumaVectorEnv(2.0), "num_envs"),
        (lambda: WheeledPumaVectorEnv(2, dynamics="physics"), "kinematic mode only"),
        (lambda: WheeledPumaVectorEnv(2, render_mode="rgb_array"), "does not render"),
        (lambda: WheeledPumaVectorEnv(2, autoreset_mode=AutoresetMode.DISABLED), "not supported"),
        (lambda: WheeledPumaVectorEnv(2, obs_noise=-1.0), "obs_noise"),
    ],
)
def test_bad_arguments_raise(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_bad_actions_and_options_raise():
    venv = WheeledPumaVectorEnv(2)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, 8)))
    venv.reset(seed=10_700)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros(8))
    with pytest.raises(ValueError, match="finite"):
        venv.step(np.full((2, 8), np.nan))
    with pytest.raises(ValueError, match="unknown reset option"):
        venv.reset(options={"colour": 1})
    venv.close()
    with pytest.raises(RuntimeError, match="closed"):
        venv.reset()


@pytest.mark.parametrize(
    ("seed", "match"),
    [
        ([10, 11, 12, "z"], r"seed\[3\] = 'z'.*robot 3"),
        (1.5, "seed 1.5 is not accepted"),
        ("abc", "seed 'abc' is not accepted"),
        ([10, 11, 12], "got 3 seeds for 4 robots"),
        (-1, "seed must be >= 0"),
        ([10, True, 12, 13], r"seed\[1\] = True"),
    ],
)
def test_a_refused_reset_leaves_every_robot_as_it_was(seed, match):
    """Seeds are checked for every robot before any generator or state changes: after a refused reset the vector
    env steps on exactly as if the call had not happened."""
    a = np.random.default_rng(0).uniform(-1, 1, (3, 4, 8))
    runs = []
    for refuse in (False, True):
        venv = WheeledPumaVectorEnv(4, path={"type": "circle", "duration": 1.0})
        venv.reset(seed=[10_900, 10_901, 10_902, 10_903])
        venv.step(a[0])
        if refuse:
            with pytest.raises(ValueError, match=match):
                venv.reset(seed=seed)
        runs.append([venv.step(x)[0]["ee_pos"].copy() for x in a[1:]])
        venv.close()
    np.testing.assert_array_equal(runs[0], runs[1])


def test_a_numpy_array_of_seeds_is_a_list_of_seeds():
    venv = WheeledPumaVectorEnv(3, path={"type": "circle", "duration": 1.0})
    obs_a, _ = venv.reset(seed=np.array([10_910, 10_911, 10_912]))
    obs_b, _ = venv.reset(seed=[10_910, 10_911, 10_912])
    np.testing.assert_array_equal(obs_a["ee_pos"], obs_b["ee_pos"])
    venv.close()


@pytest.mark.parametrize("pose", [[1e308, 0.0, 0.0], [0.0, -1e4, 0.0], [0.0, 0.0, 40.0]])
def test_an_absurd_base_pose_is_refused(pose):
    venv = WheeledPumaVectorEnv(2)
    with pytest.raises(ValueError, match=r"base_pose.*\[-100, 100\] m"):
        venv.reset(seed=10_920, options={"base_pose": pose})
    with pytest.raises(ValueError, match="base_pose"):
        WheeledPumaEnv(dynamics="kinematic", base_pose=pose)
    venv.close()


def test_a_physics_vector_env_checks_every_row_before_stepping_any():
    """A NaN in row 1 is refused, naming the row, before row 0's world moved."""
    venv = gym.make_vec("WheeledPuma-Circle-v0", num_envs=2, vectorization_mode="vector_entry_point")
    obs, _ = venv.reset(seed=10_930)
    a = np.zeros((2, 8))
    a[0] = 0.5
    a[1, 3] = np.nan
    with pytest.raises(ValueError, match="robot 1"):
        venv.step(a)
    a[1, 3] = 0.0
    first, *_ = venv.step(a)
    venv.close()
    fresh = gym.make_vec("WheeledPuma-Circle-v0", num_envs=2, vectorization_mode="vector_entry_point")
    fresh.reset(seed=10_930)
    expected, *_ = fresh.step(a)
    fresh.close()
    np.testing.assert_array_equal(first["ee_pos"], expected["ee_pos"])

"""Every robot in the env: URDF = numpy FK, Jacobians = finite differences, spaces sized by n, seeding,
physics at rest, the random family's draws, the known-model ceiling and every controller running for any n.

(gymnasium's and SB3's checkers run on every registered id in `test_env_api.test_env_checkers`; the model-free
guard on every robot's circle in `test_policies`.)
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import SHORT_CIRCLE

import mobman_env
import policies
from eval.rollout import rollout
from mobman_env import kinematics as K
from mobman_env.params import RobotParams
from mobman_env.robots import PANDA, PUMA560, UR5
from mobman_env.robots.kinematics import arm_point_and_jacobian
from mobman_env.robots.random_arms import random_arm
from mobman_env.robots.sources import ROBOT_NAMES, robot_source
from mobman_env.robots.starts import STARTS
from mobman_env.sim import Sim

RANDOM_ARMS = [random_arm(np.random.default_rng(s)).arm for s in (0, 1)]
ARMS = [PUMA560, UR5, PANDA, *RANDOM_ARMS]
ARM_IDS = ["puma560", "ur5", "panda", "random0", "random1"]
ROBOT_IDS = {v: k for k, v in mobman_env.ROBOT_IDS.items()}


def _params(arm, worn_seed=None):
    p = RobotParams.nominal(arm)
    return p if worn_seed is None else p.perturbed(np.random.default_rng(worn_seed), 0.05)


def _config(rng, p):
    lo, hi = np.maximum(p.joint_lower, -math.pi), np.minimum(p.joint_upper, math.pi)
    return rng.uniform(lo, hi), np.array([*rng.uniform(-2, 2, 2), rng.uniform(-4, 4)])


@pytest.mark.parametrize("arm", ARMS, ids=ARM_IDS)
@pytest.mark.parametrize("worn", [None, 3], ids=["nominal", "worn"])
def test_urdf_end_effector_equals_numpy_fk(arm, worn):
    """PyBullet's `ee` link (the generated URDF of the robot) equals `kinematics.ee_position` at 50 random
    configurations and base poses to 1e-6 m, for every robot, nominal and worn."""
    p = _params(arm, worn)
    sim = Sim(0.01, 2)
    try:
        sim.reset(p, np.zeros(p.n_actuators), np.zeros(3))
        assert len(sim.arm_ids) == p.n_joints and len(sim.torque_limits) == p.n_actuators
        rng = np.random.default_rng(11)
        for _ in range(50):
            q, pose = _config(rng, p)
            sim.set_state(np.r_[q, rng.uniform(-3, 3, 2)], pose)
            ls = sim.client.getLinkState(sim.body, sim.ee_id, computeForwardKinematics=1)
            np.testing.assert_allclose(ls[0], K.ee_position(p, q, pose), rtol=0, atol=1e-6)
    finally:
        sim.close()


@pytest.mark.parametrize("arm", ARMS, ids=ARM_IDS)
def test_urdf_limits_are_the_descriptions(arm):
    p = _params(arm)
    sim = Sim(0.01, 2)
    try:
        sim.reset(p, np.zeros(p.n_actuators), np.zeros(3))
        for i, j in enumerate(sim.arm_ids):
            info = sim.client.getJointInfo(sim.body, j)
            assert (info[8], info[9]) == pytest.approx((arm.joint_lower[i], arm.joint_upper[i]), abs=1e-9)
            assert (info[10], info[11]) == pytest.approx((arm.torque_limit[i], arm.speed_limit[i]), rel=1e-9)
        assert sim.torque_limits == [*arm.torque_limit, p.wheel_torque_limit, p.wheel_torque_limit]
    finally:
        sim.close()


@pytest.mark.parametrize("arm", ARMS, ids=ARM_IDS)
def test_numpy_kinematics_equal_the_generic_kernel(arm):
    p = _params(arm, 5)
    rng = np.random.default_rng(2)
    for _ in range(20):
        q, _ = _config(rng, p)
        r0, J0 = K.arm_point_and_jacobian(p, q)
        r1, J1 = arm_point_and_jacobian(p.arm, q)
        np.testing.assert_allclose(r0, r1, rtol=0, atol=1e-12)
        np.testing.assert_allclose(J0, J1, rtol=0, atol=1e-12)


@pytest.mark.parametrize("arm", ARMS, ids=ARM_IDS)
def test_jacobians_match_finite_differences(arm):
    """Whole-body Jacobian (3, n + 2): arm columns = d r_a / d q by central differences; wheel columns = the
    motion of r_a over a tiny exact unicycle step. The paper's J differs from it by d p_c_dot / d u."""
    p = _params(arm, 7)
    n = p.n_joints
    rng = np.random.default_rng(3)
    h = 1e-6
    for _ in range(10):
        q, pose = _config(rng, p)
        J = K.whole_body_jacobian(p, q, pose[2])
        assert J.shape == (3, n + 2)
        for i in range(n):
            dq = np.zeros(n)
            dq[i] = h
            fd = (K.ee_position(p, q + dq, pose) - K.ee_position(p, q - dq, pose)) / (2 * h)
            np.testing.assert_allclose(J[:, i], fd, rtol=0, atol=1e-7)
        for w in range(2):
            u = np.zeros(2)
            u[w] = 1.0
            fwd = K.ee_position(p, q, K.integrate_unicycle(p, pose, u, h))
            bwd = K.ee_position(p, q, K.integrate_unicycle(p, pose, -u, h))
            np.testing.assert_allclose(J[:, n + w], (fwd - bwd) / (2 * h), rtol=0, atol=1e-7)
        J_pc = K.arm_base_jacobian(p, pose[2])
        Jp = K.paper_jacobian(p, q, pose[2])
        np.testing.assert_allclose(Jp[:2] + J_pc, J[:2], rtol=0, atol=1e-14)
        np.testing.assert_array_equal(Jp[2], J[2])


@pytest.mark.parametrize("robot", ROBOT_NAMES)
def test_spaces_and_starts_follow_the_robot(robot):
    env = gym.make(f"{ROBOT_IDS[robot]}-Circle-v0", dynamics="kinematic")
    try:
        base = env.unwrapped
        n = base.nominal_params.n_joints
        assert env.action_space.shape == (n + 2,) and base.n_actuators == n + 2
        assert env.observation_space["joint_pos"].shape == env.observation_space["joint_vel"].shape == (n + 2,)
        np.testing.assert_array_equal(base.action_scale, [*base.nominal_params.arm.speed_limit, 10.0, 10.0])
        obs, info = env.reset(seed=10_000)
        assert env.observation_space.contains(obs)
        assert policies.EnvFacts.from_env(env).n_actuators == n + 2
        q0 = info["task"]["arm_joint_pos"]
        if robot in STARTS:
            np.testing.assert_array_equal(q0, [*STARTS[robot].q0, 0.0, 0.0])
        assert info["task"]["base_pose"] == [0.0, 0.0, math.pi]
        assert base.nominal_params.tool == base.nominal_params.arm.tool
        with pytest.raises(ValueError, match=rf"action must have shape \({n + 2},\)"):
            env.step(np.zeros(n + 3))
    finally:
        env.close()


def test_ids_and_robot_argument():
    assert len(mobman_env.ENV_IDS) == 20
    assert ROBOT_IDS == {
        "puma560": "WheeledPuma",
        "ur5": "WheeledUR5",
        "panda": "WheeledPanda",
        "random": "WheeledRandomArm",
        "random-scaled": "WheeledScaledArm",
    }
    assert mobman_env.env_ids("panda") == tuple(
        f"WheeledPanda-{t}-v0" for t in ("Circle", "Line", "Lemniscate", "Random")
    )
    # the PUMA ids are registered exactly as in release 0.1: the path alone
    assert set(gym.spec("WheeledPuma-Line-v0").kwargs) == {"path"}
    assert gym.spec("WheeledUR5-Line-v0").kwargs["robot"] == "ur5"
    with pytest.raises(
        ValueError, match=r"unknown robot 'ur10'; accepted: 'puma560', 'ur5', 'panda', 'random', 'random-scaled'"
    ):
        robot_source("ur10")
    with pytest.raises(ValueError, match="unknown robot"):
        mobman_env.WheeledPumaEnv(robot="kuka")
    with pytest.raises(ValueError, match="draws each arm with its own start"):
        mobman_env.WheeledPumaEnv(robot="random", arm_joint_pos=[0.0] * 6)
    with pytest.raises(ValueError, match="arm_joint_pos must be 7 or 9 finite numbers"):
        mobman_env.WheeledPumaEnv(robot="panda", arm_joint_pos=[0.0] * 6)
    with pytest.raises(ValueError, match="outside the joint limits of panda"):
        mobman_env.WheeledPumaEnv(robot="panda", arm_joint_pos=[0.0] * 7)  # joint 4 must be < -0.0698


@pytest.mark.parametrize("mode", ["make", "vector_entry_point", "sync"])
@pytest.mark.parametrize(
    "env_id, robot, other",
    [
        ("WheeledUR5-Circle-v0", "panda", "WheeledPanda"),
        ("WheeledPuma-Line-v0", "ur5", "WheeledUR5"),
        ("WheeledRandomArm-Circle-v0", "puma560", "WheeledPuma"),
        ("WheeledPanda-Circle-v0", "kuka", None),
    ],
)
def test_a_robot_that_contradicts_the_id_is_refused(env_id, robot, other, mode):
    prefix = env_id.split("-")[0]
    fix = f"use the {other}-\\* id of the task" if other else "accepted here: robot="
    match = rf"robot='{robot}' contradicts the id: {prefix}-\* ids are the .*; {fix}"
    with pytest.raises(ValueError, match=match):
        if mode == "make":
            gym.make(env_id, robot=robot, dynamics="kinematic")
        else:
            gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, robot=robot, dynamics="kinematic")


def test_the_ids_entry_points_still_make_the_env_everywhere():
    """The robot check sits in the entry point: gym.make(id).unwrapped is the env class, the `mobman_env:` form
    works, the id's own robot may be named, and the spec pickles (an async vector env sends it to workers)."""
    import pickle

    env = gym.make("mobman_env:WheeledUR5-Circle-v0", robot="ur5", dynamics="kinematic")
    try:
        assert type(env.unwrapped) is mobman_env.WheeledPumaEnv and env.unwrapped.robot == "ur5"
    finally:
        env.close()
    spec = pickle.loads(pickle.dumps(gym.spec("WheeledPanda-Line-v0")))
    assert spec.entry_point.robot == "panda" and spec.kwargs["robot"] == "panda"
    venv = gym.make_vec("WheeledPanda-Line-v0", num_envs=2, vectorization_mode="async", dynamics="kinematic")
    try:
        obs, _ = venv.reset(seed=10_000)
        assert obs["joint_pos"].shape == (2, 9)
    finally:
        venv.close()


@pytest.mark.parametrize("robot", ROBOT_NAMES)
def test_same_seed_same_episode_for_every_robot(robot):
    """Same seed and actions -> bit-identical observations (the random arm's draw included); another seed
    draws another true robot (and, for the random family, another arm)."""

    def run(seed):
        env = gym.make(f"{ROBOT_IDS[robot]}-Random-v0", dynamics="kinematic")
        try:
            obs, info = env.reset(seed=seed)
            rng = np.random.default_rng(0)
            out = [obs["ee_pos"].copy()]
            for _ in range(30):
                obs, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
                out.append(np.concatenate([obs[k] for k in sorted(obs)]))
            return info["true_params_hash"], env.unwrapped.nominal_params.hash(), np.concatenate(out)
        finally:
            env.close()

    a, b, c = run(10_001), run(10_001), run(10_002)
    assert a[0] == b[0] and a[1] == b[1]
    np.testing.assert_array_equal(a[2], b[2])
    assert a[0] != c[0]
    assert (a[1] != c[1]) == (robot in ("random", "random-scaled"))


@pytest.mark.parametrize("robot", ROBOT_NAMES)
def test_physics_holds_still_under_zero_command(robot):
    """Physics mode: torque limits hold the arm against gravity; with a zero command for 2 s the end-effector
    moves less than 1 mm (the velocity motors' creep) and the platform does not tip."""
    env = gym.make(f"{ROBOT_IDS[robot]}-Circle-v0", dynamics="physics")
    try:
        obs, info = env.reset(seed=10_003)
        start = info["ee_pos_true"].copy()
        for _ in range(200):
            obs, _, terminated, _, info = env.step(np.zeros(env.action_space.shape, np.float32))
            assert not terminated
        assert np.linalg.norm(info["ee_pos_true"] - start) < 1e-3
        assert info["joint_limit_hits"] == 0
    finally:
        env.close()


def test_random_arm_family_per_reset():
    """Each reset draws a new arm (the episode's nominal robot) and its start; the true robot is its worn copy."""
    env = gym.make("WheeledRandomArm-Circle-v0", dynamics="kinematic")
    try:
        arms = []
        for seed in (10_010, 10_011, 10_010):
            _, info = env.reset(seed=seed)
            nom, true = env.unwrapped.nominal_params, env.unwrapped.true_params
            assert nom.n_joints == 6 and true.arm.alpha == nom.arm.alpha and true.arm.a != nom.arm.a
            expected = random_arm(np.random.default_rng(seed), None)  # the same stream, before the ceiling check
            assert nom.arm.speed_limit == expected.arm.speed_limit
            arms.append(nom.arm)
        assert arms[0] == arms[2] and arms[0] != arms[1]
    finally:
        env.close()


@pytest.mark.parametrize("robot", ROBOT_NAMES)
@pytest.mark.parametrize(
    "spec", ["qp-oracle", "qp", "clik", "jmpi", "oracle-full", "nnbc", "nnbc:j0=nominal", "nnbc-plus"]
)
def test_every_controller_runs_on_every_robot(robot, spec):
    env = gym.make(f"{ROBOT_IDS[robot]}-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE)
    try:
        rec, _ = rollout(env, policies.make(spec, env, seed=0), 10_000)
        assert rec["status"] == "ok", rec.get("error")
        assert np.isfinite(rec["max_error_m"])
    finally:
        env.close()


@pytest.mark.parametrize("robot", ROBOT_NAMES)
def test_known_model_ceiling_tracks_the_circle(robot):
    """qp-oracle (the known-model ceiling) tracks every robot's 20 s circle from its start within the paper's
    6 mm (kinematic, 5% wear, held-out seed)."""
    env = gym.make(f"{ROBOT_IDS[robot]}-Circle-v0", dynamics="kinematic")
    try:
        rec, _ = rollout(env, policies.make("qp-oracle", env, seed=0), 10_004)
        assert rec["max_error_m"] < 0.006
    finally:
        env.close()


def test_worn_draws_use_the_arms_length_slots():
    """model_error perturbs every non-zero a and d, the tool, r, b and d of any arm (the PUMA's 8 lengths)."""
    for arm, count in ((PUMA560, 8), (UR5, 10), (PANDA, 11)):
        p = RobotParams.nominal(arm)
        assert len(p.perturbed_fields) == count
        worn = p.perturbed(np.random.default_rng(0), 0.05)
        changed = [n for n in p.perturbed_fields if getattr(worn, n) != getattr(p, n)]
        assert changed == list(p.perturbed_fields)
        assert worn.arm.masses == arm.masses and worn.arm.alpha == arm.alpha
        assert worn.hash() != p.hash()


@pytest.mark.parametrize("robot", ["random", "random-scaled"])
def test_a_memoised_draw_is_the_draw_and_leaves_the_generator_where_it_would_be(robot, monkeypatch):
    """The drawn families memoise a draw on the generator's state: a hit returns the same arm and start and
    leaves the generator in the state the draw itself would have left (a fresh, unmemoised draw checks it)."""
    from mobman_env.robots import sources

    src = robot_source(robot)
    first = np.random.default_rng(10_020)
    arm, q0, built = src.draw(first)
    after = first.random(3)
    hit_rng = np.random.default_rng(10_020)
    assert src.draw(hit_rng) == (arm, q0, built) and np.array_equal(hit_rng.random(3), after)
    monkeypatch.setattr(sources, "_DRAWS", {})
    fresh = np.random.default_rng(10_020)
    assert src.draw(fresh) == (arm, q0, built) and np.array_equal(fresh.random(3), after)


def test_a_scaled_arms_catalogue_is_its_design_before_scaling():
    """The scaled family's catalogue (the nominal robot a model-based controller is given) is the design before the
    scale factor: the factor is an error of the catalogue (in 0.3 the catalogue held the scaled arm, so the
    condition tested nothing for the nominal-model laws). The random family's catalogue is the arm built."""
    factors = []
    for seed in range(3):
        env = gym.make("WheeledScaledArm-Circle-v0", dynamics="kinematic", model_error=0.0)
        env.reset(seed=seed)
        nominal, true = env.unwrapped.nominal_params.arm, env.unwrapped.true_params.arm
        ratios = [getattr(true, f)[i] / getattr(nominal, f)[i] for f, i in nominal.length_slots if f != "tool"]
        ratios.append(true.tool / nominal.tool)
        assert max(ratios) - min(ratios) < 1e-12  # one factor for every length
        assert 0.7 <= ratios[0] <= 1.4 and abs(ratios[0] - 1.0) > 1e-3
        factors.append(ratios[0])
        env.close()
    assert len(set(factors)) == 3
    env = gym.make("WheeledRandomArm-Circle-v0", dynamics="kinematic", model_error=0.0)
    env.reset(seed=0)
    assert env.unwrapped.nominal_params.arm == env.unwrapped.true_params.arm
    env.close()

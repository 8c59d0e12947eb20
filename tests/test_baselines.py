"""The baselines of benchmark protocol v1 (issue 12): `clik`, `clik-full`, `qp`, `qp-oracle`, `broyden`, `rls`.

Accuracy claims are assertions on development seeds (0-999, as the brief of the work asked: these controllers
were built and their defaults chosen on seeds 0-19); the figures of the docs come from `mobman-eval` on
reported seeds. Kinematic mode, full 20 s episodes unless stated.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from test_nnbc_plus import assert_every_field_documented

import mobman_env  # noqa: F401  (registers the ids)
import policies
from mobman_env import kinematics as K
from mobman_env.params import RobotParams
from policies.base import EnvFacts, policy_seed
from policies.laws.broyden_rls import BroydenConfig, RLSConfig
from policies.laws.estimators import BroydenEstimator, RLSEstimator
from policies.laws.jmpi import CLIKConfig, JMPIConfig, OracleConfig
from policies.laws.nnbc import damped_pinv_apply
from policies.laws.nnbc_plus import NNBCPlusConfig
from policies.laws.qp import QP, QPConfig, daqp_solve_qp

DEV_SEEDS = range(0, 3)
DEV_SEEDS_20 = range(0, 20)
TOLERANCE = 0.006  # m, the paper's bound and the benchmark's success line


def rollout(env, policy, seed: int) -> dict:
    """One episode; max error over the episode and before the first joint-limit hit (m), limit hits."""
    obs, info = env.reset(seed=seed)
    policy.reset(obs, info, seed=policy_seed(seed))
    max_err, pre_limit, hit = 0.0, 0.0, False
    while True:
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        err = info["tracking_error"]
        max_err = max(max_err, err)
        hit = hit or info["joint_limit_hits"] > 0
        if not hit:
            pre_limit = max(pre_limit, err)
        if terminated or truncated:
            return {"max": max_err, "pre_limit": pre_limit, "hits": info["joint_limit_hits"]}


def run(spec: str, task: str, seeds, **env_kwargs) -> list[dict]:
    env = gym.make(f"WheeledPuma-{task}-v0", dynamics="kinematic", **env_kwargs)
    try:
        policy = policies.make(spec, env)
        return [rollout(env, policy, s) for s in seeds]
    finally:
        env.close()


def mm(results, key="max"):
    return [round(r[key] * 1e3, 3) for r in results]


# --- clik ----------------------------------------------------------------------------------------------------
def test_clik_full_tracks_circle_with_an_exact_model_until_a_joint_limit():
    """With model_error 0 the nominal model is the true one: clik-full is the oracle-full law, < 1 mm before
    any joint-limit hit (measured 0.03 mm on seeds 0-4; 0.45 mm over the whole episode)."""
    results = run("clik-full", "Circle", DEV_SEEDS, model_error=0.0)
    assert max(r["pre_limit"] for r in results) < 0.001, mm(results, "pre_limit")


def test_clik_is_the_oracle_law_on_the_nominal_model():
    """Same command as the oracle when the oracle's provider returns the nominal robot, and as JMPI given
    CLIK's gain (one law: model source and gain are its only parameters)."""
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    try:
        obs, _ = env.reset(seed=1)
        for _ in range(30):
            obs, *_ = env.step(env.action_space.sample() * 0.1)
        facts = EnvFacts.from_env(env)
        nominal = env.unwrapped.nominal_params
        for full in (False, True):
            clik = policies.laws.jmpi.CLIK(facts, CLIKConfig(full=full), nominal_params=nominal)
            oracle = policies.laws.jmpi.Oracle(facts, OracleConfig(full=full), params_provider=lambda: nominal)
            jmpi = policies.laws.jmpi.JMPI(facts, JMPIConfig(full=full, gamma=20.0), nominal_params=nominal)
            for pol in (clik, oracle, jmpi):
                pol.reset(obs)
            u = clik.predict(obs)[0]
            np.testing.assert_array_equal(u, oracle.predict(obs)[0])
            np.testing.assert_array_equal(u, jmpi.predict(obs)[0])
            assert clik.config.gamma == 20.0 and JMPIConfig().gamma == 0.0
    finally:
        env.close()


# --- qp --------------------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_qp_oracle_is_the_ceiling_on_every_circle_seed():
    """The known-model ceiling succeeds on all 20 development seeds of Circle-v0 with the env's joint limits
    enforced, and never reaches a limit (the dampers hold joint 1 off its stop; `oracle` loses episodes there).
    Measured: max error 0.035-0.052 mm on seeds 0-5."""
    results = run("qp-oracle", "Circle", DEV_SEEDS_20)
    assert all(r["max"] <= TOLERANCE for r in results), mm(results)
    assert np.median([r["max"] for r in results]) < 0.0005, mm(results)
    assert all(r["hits"] == 0 for r in results), [r["hits"] for r in results]


@pytest.mark.parametrize("task", ["Circle", "Line"])
def test_qp_on_the_nominal_model_tracks_with_five_percent_wear(task):
    """Measured 0.37-1.34 mm on Circle-v0 seeds 0-3 (5% model error): the feedback corrects the model."""
    results = run("qp", task, DEV_SEEDS)
    assert all(r["max"] <= TOLERANCE for r in results), mm(results)


@pytest.fixture
def mid_episode():
    """An env, its facts and an observation 0.5 s into a Circle-v0 episode (seed 2)."""
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    obs, _ = env.reset(seed=2)
    oracle = policies.make("oracle-full", env)
    oracle.reset(obs)
    for _ in range(50):
        obs, *_ = env.step(oracle.predict(obs)[0])
    yield env, EnvFacts.from_env(env), obs
    env.close()


def test_qp_without_active_bounds_is_the_pseudo_inverse(mid_episode):
    """No posture term and no bound active: the QP's answer is the least-norm u with J u = v, up to the slack's
    1/slack_weight regularisation (known answer: J^+ v)."""
    env, facts, obs = mid_episode
    params = env.unwrapped.true_params
    pol = QP(facts, QPConfig(posture_gain=0.0), params_provider=lambda: params)
    pol.reset(obs)
    u = pol.predict(obs)[0] * facts.scale
    q = np.asarray(obs["joint_pos"][:6], float)
    J = K.whole_body_jacobian(params, q, float(obs["base_yaw"][0]))
    v = np.asarray(obs["target_vel"], float) + 20.0 * (np.asarray(obs["target_pos"], float) - obs["ee_pos"])
    expected = damped_pinv_apply(J, v, 0.02, 0.02)
    assert np.all(np.abs(expected) < 0.9 * facts.scale)  # no speed bound active
    np.testing.assert_allclose(u, expected, rtol=1e-4, atol=1e-6)  # float32 actions: ~1e-7 relative
    # the slack is the regularisation residual: about (1/slack_weight) / sigma^2 = 2.5e-5 of v here
    assert np.linalg.norm(pol.last_slack) < 1e-4 * np.linalg.norm(v)


def test_qp_velocity_dampers_follow_the_neo_formula(mid_episode):
    """ub_i = min(speed limit, xi (d - stop) / (influence - stop)) within the influence distance d of a limit;
    beyond the stop distance the damper pushes away; far from the limits the bounds are the speed limits."""
    env, facts, obs = mid_episode
    c = QPConfig(influence=0.5, stop=0.05, damper_gain=1.0)
    pol = QP(facts, c, nominal_params=RobotParams.nominal())
    pol.reset(obs)
    upper = np.asarray(RobotParams.nominal().joint_upper)
    lower = np.asarray(RobotParams.nominal().joint_lower)
    q = 0.5 * (upper + lower)
    lb, ub = pol.bounds(q)
    np.testing.assert_array_equal(ub, facts.scale)
    np.testing.assert_array_equal(lb, -facts.scale)
    q[0] = upper[0] - 0.25  # joint 1, 0.25 rad below its upper limit
    q[2] = lower[2] + 0.02  # joint 3 inside the stop distance of its lower limit
    lb, ub = pol.bounds(q)
    assert ub[0] == pytest.approx((0.25 - 0.05) / (0.5 - 0.05))
    assert lb[0] == -facts.scale[0]
    assert lb[2] == pytest.approx(-(0.02 - 0.05) / (0.5 - 0.05)) and lb[2] > 0  # pushed away from the limit
    np.testing.assert_array_equal(ub[6:], facts.scale[6:])  # wheels: no position limit


# --- broyden, rls --------------------------------------------------------------------------------------------
def test_broyden_secant_update_and_step_gate():
    rng = np.random.default_rng(0)
    est = BroydenEstimator(8, step=1.0, min_speed=0.01)
    J0 = rng.standard_normal((3, 8))
    est.init(J0)
    J_true = J0 + 0.3 * rng.standard_normal((3, 8))
    x = rng.standard_normal(8)
    est.update(x, J_true @ x)
    np.testing.assert_allclose(est.J @ x, J_true @ x, rtol=1e-12)  # the secant condition
    w = rng.standard_normal(8)
    w -= (w @ x) / (x @ x) * x
    np.testing.assert_allclose((est.J - J0) @ w, 0.0, atol=1e-12)  # nothing changes orthogonal to x
    before = est.J.copy()
    est.update(1e-3 * x / np.linalg.norm(x), np.ones(3))  # ||x|| = 1 mrad/s < min_speed: skipped
    np.testing.assert_array_equal(est.J, before)
    assert est.n_skipped == 1


def test_rls_recovers_a_jacobian_and_follows_a_change():
    rng = np.random.default_rng(1)
    est = RLSEstimator(8, forgetting=0.95, q_jacobian=0.0, p0=1.0, p_max=100.0)
    J1 = rng.standard_normal((3, 8))
    est.init(np.zeros((3, 8)))
    for _ in range(200):
        x = rng.standard_normal(8)
        est.update(x, J1 @ x)
    # the prior (J = 0, P = I) keeps a weight of about 0.95^200 = 3.5e-5: J1 to 1e-4 (entries ~1)
    np.testing.assert_allclose(est.J, J1, atol=1e-4)
    J2 = J1 + 0.2 * rng.standard_normal((3, 8))  # the robot changes: forgetting lets the estimate follow
    for _ in range(200):
        x = rng.standard_normal(8)
        est.update(x, J2 @ x)
    # likewise the data of J1
    np.testing.assert_allclose(est.J, J2, atol=1e-4)
    assert est.P.trace() <= 100.0 * 8 + 1e-9


@pytest.mark.parametrize("task", ["Circle", "Line"])
def test_rls_tracks_at_default_conditions(task):
    """Measured on seeds 0-2 (5% model error, forgetting 0.9): Circle-v0 1.2-2.8 mm, Line-v0 3.0-3.6 mm (10/10
    of seeds 0-9 on both)."""
    results = run("rls", task, DEV_SEEDS)
    assert all(r["max"] <= TOLERANCE for r in results), mm(results)


def test_broyden_needs_more_excitation_than_the_shared_default():
    """Broyden refreshes J only along the measured x, which the path's own motion dominates: with the shared
    0.05 rad/s dither it loses Circle-v0 (0/10 of seeds 0-9, median max error 10.4 mm, median relative J error
    0.54), with 0.2 rad/s it wins 8/10 (median 5.1 mm). Asserted on seed 0 (17.6 mm -> 4.3 mm) with a margin: the
    larger dither halves the error."""
    default = run("broyden", "Circle", [0])[0]["max"]
    excited = run("broyden:dither=0.2", "Circle", [0])[0]["max"]
    assert default > TOLERANCE
    assert excited < 0.5 * default, (default, excited)


def test_estimating_controllers_share_the_scaffolding():
    """broyden and rls run nnbc-plus's probe: the same 16 probe commands at the same `probe_speed` (nnbc-plus's
    default is 0.02 rad/s since v4, theirs 0.05) and the same measurement (they read joint_vel, nnbc-plus the
    joint angles' differences since v5: the probe's commands then differ in float32's last bit), then an estimate
    exposed as jacobian_estimate (None during the probe), of the kind their formulation says."""
    env = gym.make("WheeledPuma-Line-v0", dynamics="kinematic")
    n_probe = 2 * EnvFacts.from_env(env).n_actuators  # one + and one - step per actuator
    try:
        actions = {}
        specs = ("nnbc-plus:measurement=velocity", "broyden:probe_speed=0.02", "rls:probe_speed=0.02")
        for spec in (*specs, "rls:formulation=paper"):
            pol = policies.make(spec, env)
            obs, _ = env.reset(seed=0)
            pol.reset(obs, seed=1)
            acts = []
            for k in range(n_probe + 3):
                assert (pol.jacobian_estimate is None) == (k <= n_probe), (spec, k)
                a, _ = pol.predict(obs)
                acts.append(a)
                obs, *_ = env.step(a)
            J = pol.jacobian_estimate
            assert J.shape == (3, 8) and J is not pol.J_hat
            assert pol.jacobian_kind == ("paper" if "paper" in spec else "whole_body")
            actions[spec] = np.array(acts[:n_probe])
    finally:
        env.close()
    for spec in ("broyden:probe_speed=0.02", "rls:probe_speed=0.02"):
        np.testing.assert_array_equal(actions[spec], actions["nnbc-plus:measurement=velocity"])


def test_configs_are_documented_and_validated():
    for cls in (BroydenConfig, RLSConfig, QPConfig, NNBCPlusConfig, CLIKConfig):
        assert_every_field_documented(cls)
    assert BroydenConfig().gamma == RLSConfig().gamma == QPConfig().gamma == NNBCPlusConfig().gamma == 20.0
    assert OracleConfig().gamma == CLIKConfig().gamma == 20.0
    assert isinstance(RLSConfig(gamma=15).gamma, float)


@pytest.mark.parametrize(
    "spec, fragment",
    [
        ("qp:stop=0.6", "stop .* must be smaller than QPConfig.influence"),
        ("qp:solver=quadprog", "solver must be one of daqp, proxqp"),
        ("qp:slack_weight=0", "slack_weight must be a finite number > 0"),
        ("qp-oracle:gama=3", r"unknown option\(s\) \['gama'\].*QPConfig accepts: gamma"),
        ("broyden:step=0", "BroydenConfig.step must be a finite number > 0 and <= 1"),
        ("rls:forgetting=1.5", "RLSConfig.forgetting must be a finite number > 0 and <= 1"),
        ("rls:gamma=-1", "RLSConfig.gamma must be a finite number >= 0"),
        ("clik:gamma=-2", "CLIKConfig.gamma must be a finite number >= 0"),
        ("clik-full:mu=1", r"unknown option\(s\) \['mu'\]"),
    ],
)
def test_bad_specs_name_the_value_and_the_accepted_range(spec, fragment):
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    try:
        with pytest.raises(ValueError, match=fragment):
            policies.make(spec, env)
    finally:
        env.close()


def test_direct_daqp_call_equals_qpsolvers():
    """`daqp_solve_qp` hands DAQP the arrays `qpsolvers.solve_qp(..., solver="daqp")` builds: the same solution
    bit for bit on random problems of the QP's shape (8 speeds + 3 slacks, 3 equalities, boxes, some active)."""
    import qpsolvers

    rng = np.random.default_rng(10_500)
    P = np.diag(np.r_[np.ones(8), np.full(3, 1e6)])
    A = np.zeros((3, 11))
    A[:, 8:] = np.eye(3)
    for _ in range(200):
        A[:, :8] = rng.normal(size=(3, 8))
        q, b = rng.normal(size=11), rng.normal(size=3)
        lb = np.r_[-rng.uniform(0.1, 3.0, 8), np.full(3, -np.inf)]
        ub = np.r_[rng.uniform(0.1, 3.0, 8), np.full(3, np.inf)]
        expected = qpsolvers.solve_qp(P, q, A=A, b=b, lb=lb, ub=ub, solver="daqp")
        got = daqp_solve_qp(P, q, A=A, b=b, lb=lb, ub=ub)
        assert expected is not None and np.array_equal(got, expected)
    infeasible = daqp_solve_qp(P, np.zeros(11), A=A, b=b, lb=np.ones(11), ub=-np.ones(11))
    assert infeasible is None


def test_qp_needs_exactly_one_model_source():
    facts = EnvFacts(dt=0.01, action_scale=(3, 3, 3, 5, 5, 5, 10, 10), obs_keys=())
    with pytest.raises(ValueError, match="exactly one model source"):
        QP(facts)
    with pytest.raises(ValueError, match="exactly one model source"):
        QP(facts, nominal_params=RobotParams.nominal(), params_provider=RobotParams.nominal)
    assert QP(facts, params_provider=RobotParams.nominal).name == "qp-oracle"


def test_qp_falls_back_to_the_clipped_pseudo_inverse_when_the_solver_fails(mid_episode):
    env, facts, obs = mid_episode
    params = env.unwrapped.true_params
    pol = QP(facts, QPConfig(posture_gain=0.0), params_provider=lambda: params)
    pol.reset(obs)
    expected = pol.predict(obs)[0]
    pol._solve_qp = lambda *args, **kwargs: None  # a solver that finds no solution
    got = pol.predict(obs)[0]
    assert pol.qp_failures == 1
    np.testing.assert_allclose(got, expected, rtol=1e-4, atol=1e-6)  # no bound active: the same least-norm u

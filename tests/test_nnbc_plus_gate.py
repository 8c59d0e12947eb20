"""`nnbc-plus` options of issue 16 v2 (`innov_gate`, `gate_rms`, `gate_steps`, `gate_inflate`, `rate_time`,
`body_frame`): unit tests on linear plants (y = J x; for `body_frame`, a J turning with the heading; so with the
whole-body estimate: a linear plant has no platform), and the options' parsing.

Both options are off by default (the default controller's actions are unchanged); their measured effect on the
conditions of issue 16 is in the module docstring of `policies.nnbc_plus`.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from test_nnbc_plus import plant_obs

import mobman_env
import policies
from policies.base import EnvFacts
from policies.estimators import KalmanEstimator
from policies.nnbc_plus import NNBCPlus, NNBCPlusConfig

N, DT = 8, 0.01


def make_estimator(**options) -> KalmanEstimator:
    """The Kalman filter `nnbc-plus` builds with these options, for N actuators at DT."""
    facts = EnvFacts(dt=DT, action_scale=(1.0,) * N, obs_keys=())
    est = NNBCPlus(facts, NNBCPlusConfig(formulation="whole_body", **options)).estimator
    assert isinstance(est, KalmanEstimator)
    return est


def feed(est: KalmanEstimator, J: np.ndarray, steps: int, rng: np.random.Generator, jolt: float = 0.0) -> None:
    """steps pairs of y = J x + 1 mm/s of noise (x random, 0.5 rad/s per actuator), y offset by `jolt` m/s on
    every axis."""
    for _ in range(steps):
        x = 0.5 * rng.standard_normal(N)
        est.update(x, J @ x + 0.001 * rng.standard_normal(3) + jolt)


@pytest.mark.parametrize("kind", ["innov_gate", "gate_rms"])
def test_the_gate_keeps_a_transient_out_of_the_estimate_and_still_learns_a_real_change(kind):
    rng = np.random.default_rng(3)
    J = 0.3 * rng.standard_normal((3, N))
    errors = {}
    for gate in (0.0, 3.0):
        est = make_estimator(**{kind: gate}, gate_steps=10)
        est.init(J + 0.01 * rng.standard_normal((3, N)))
        feed(est, J, 300, np.random.default_rng(4))
        before = np.linalg.norm(est.J - J) / np.linalg.norm(J)
        # a jolt: y = J x broken by 0.2 m/s for 8 steps (the physics platform's transients: 16-440 mm/s)
        feed(est, J, 8, np.random.default_rng(5), jolt=0.2)
        errors[gate] = np.linalg.norm(est.J - J) / np.linalg.norm(J)
        assert before < 0.01, before
        if gate:
            assert est.n_rejected >= 8  # (the RMS gate also rejects a noise outlier or two)
    # without the gate the filter learns the jolt; with it J_hat does not move
    assert errors[0.0] > 0.1, errors
    assert errors[3.0] < 0.02, errors

    # a real change of J: rejected gate_steps times, then learnt (J_hat follows the new J)
    est = make_estimator(**{kind: 3.0}, gate_steps=10, gate_inflate=10.0)
    est.init(J)
    feed(est, J, 300, np.random.default_rng(6))
    J2 = J + 0.2 * rng.standard_normal((3, N))
    feed(est, J2, 200, np.random.default_rng(7))
    assert est.n_rejected >= 10
    assert np.linalg.norm(est.J - J2) / np.linalg.norm(J2) < 0.02


def test_the_rate_decays_with_rate_time_and_stays_without_it():
    """With no information (x = 0) the constant-rate model carries J_hat along J_dot_hat for ever; with
    rate_time = tau the rate decays as exp(-t / tau), so J_hat moves about tau |J_dot_hat| in all."""
    rate = np.full((3, N), 0.5)
    moved = {}
    for tau in (0.0, 0.05):
        est = make_estimator(rate_time=tau)
        est.init(np.zeros((3, N)))
        est.X[:, N:] = rate
        for _ in range(100):  # 1 s
            est.update(np.zeros(N), np.zeros(3))
        moved[tau] = float(np.abs(est.J).max())
    assert moved[0.0] == pytest.approx(0.5, rel=1e-9)  # 1 s at 0.5 m/rad/s
    a = np.exp(-DT / 0.05)  # per step; J_hat moves by dt times the sum of the decaying rates
    assert moved[0.05] == pytest.approx(0.5 * DT * (1 - a**100) / (1 - a), rel=1e-9), moved
    np.testing.assert_allclose(est.Jdot, rate * np.exp(-1.0 / 0.05), rtol=1e-6)


def test_body_frame_learns_the_platform_frame_jacobian_and_controls_with_the_world_one():
    """A linear plant whose Jacobian turns with the heading: J(t) = R(phi(t)) J_b, phi = 0.5 t (rad). With
    body_frame the estimator's J converges to the constant J_b, and J_hat (the control law's, world frame) to
    R(phi) J_b; without it the estimator's J is the world one."""
    n, dt = 8, 0.01
    facts = EnvFacts(dt=dt, action_scale=(3.0,) * 6 + (10.0, 10.0), obs_keys=mobman_env.OBS_KEYS)
    Jb = 0.3 * np.random.default_rng(5).standard_normal((3, n))

    def world(phi: float) -> np.ndarray:
        c, s = np.cos(phi), np.sin(phi)
        return np.vstack([c * Jb[0] - s * Jb[1], s * Jb[0] + c * Jb[1], Jb[2]])

    est_err = {}
    for body in (False, True):
        policy = NNBCPlus(facts, NNBCPlusConfig(formulation="whole_body", body_frame=body), seed=1)
        q, r, u = np.zeros(n), np.zeros(3), np.zeros(n)
        for k in range(400):
            t = k * dt
            J = world(0.5 * t)
            obs = {
                "ee_pos": r.copy(), "ee_vel": J @ u, "arm_base_pos": np.zeros(2), "arm_base_vel": np.zeros(2),
                "joint_pos": q.copy(), "joint_vel": u.copy(), "target_pos": 0.02 * np.array([np.sin(t), 0, 0]),
                "target_vel": 0.02 * np.array([np.cos(t), 0, 0]), "base_yaw": np.array([0.5 * t]),
                "time": np.array([t]),
            }  # fmt: skip
            action, _ = policy.predict(obs)
            u = np.asarray(action, float) * facts.scale
            q, r = q + dt * u, r + dt * J @ u
        est_err[body] = np.linalg.norm(policy.estimator.J - Jb) / np.linalg.norm(Jb)
        assert np.linalg.norm(policy.J_hat - J) < 0.05 * np.linalg.norm(J)
        np.testing.assert_allclose(policy.jacobian_estimate, policy.J_hat)
    assert est_err[True] < 0.05 < est_err[False], est_err  # (after 4 s the world J has turned by 2 rad)
    with pytest.raises(ValueError, match="body_frame"):
        NNBCPlusConfig(formulation="whole_body", body_frame=True, measurement="position")


def test_the_options_parse_from_a_spec_and_are_validated():
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    try:
        pol = policies.make(
            "nnbc-plus:formulation=whole_body,innov_gate=3,gate_rms=5,gate_steps=5,gate_inflate=10,rate_time=0.05,"
            "body_frame=true",
            env,
            seed=0,
        )
    finally:
        env.close()
    c = pol.config
    assert (c.innov_gate, c.gate_rms, c.gate_steps, c.gate_inflate, c.rate_time) == (3.0, 5.0, 5, 10.0, 0.05)
    assert c.body_frame is True and "base_yaw" in pol.uses_keys
    assert pol.estimator._gate2 == 27.0 and pol.estimator._gate_rms2 == 25.0 and pol.estimator._gate_steps == 5
    assert pol.estimator._rate_decay == pytest.approx(np.exp(-0.2))
    default = NNBCPlusConfig()
    assert (default.innov_gate, default.gate_rms, default.rate_time, default.body_frame) == (0, 0, 0, False)
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="gate_steps"):
            NNBCPlusConfig(gate_steps=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="gate_inflate"):
        NNBCPlusConfig(gate_inflate=0.5)


def test_wheel_drift_lets_the_wheels_take_over_once_the_arm_has_drifted():
    """A linear plant whose six arm columns (each about 0.5 m/rad) together outweigh the wheels' (0.2): on a
    long straight line the minimum-norm command moves the arm, which drifts from its start; with wheel_drift the
    wheels' weight grows with that drift and the arm drifts less."""
    n, dt = 8, 0.01
    facts = EnvFacts(dt=dt, action_scale=(3.0,) * 6 + (10.0, 10.0), obs_keys=mobman_env.OBS_KEYS)
    rng = np.random.default_rng(2)
    J = np.hstack([0.3 * rng.standard_normal((3, 6)), [[0.2, 0.0], [0.0, 0.2], [0.0, 0.0]]])  # wheels: x and y
    drift = {}
    for wd in (0.0, 0.1):  # (no posture pull: the drift is the wheel weight's alone to stop)
        policy = NNBCPlus(facts, NNBCPlusConfig(formulation="whole_body", wheel_drift=wd, posture_gain=0.0), seed=1)
        q, r, u = np.zeros(n), np.zeros(3), np.zeros(n)
        errors = []
        for k in range(800):
            t = k * dt
            target, target_vel = np.array([0.1 * t, 0.0, 0.0]), np.array([0.1, 0.0, 0.0])
            obs = plant_obs(q, r, u, J, t, target, target_vel)
            action, _ = policy.predict(obs)
            u = np.asarray(action, float) * facts.scale
            q, r = q + dt * u, r + dt * J @ u
            errors.append(np.linalg.norm(r - np.array([0.1 * (t + dt), 0.0, 0.0])))
        drift[wd] = float(np.abs(q[:6]).max())
        assert max(errors[100:]) < 2e-3, (wd, max(errors[100:]))
    assert drift[0.1] < 0.85 * drift[0.0], drift  # (0.43 against 0.55 rad: the weight is capped at 16)

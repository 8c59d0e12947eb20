"""`nnbc-plus` estimator options of issue 16 v2 (`innov_gate`, `gate_steps`, `gate_inflate`, `rate_time`): unit
tests of `policies.estimators.KalmanEstimator` on a linear plant y = J x, and the options' parsing.

Both options are off by default (the default controller's actions are unchanged); their measured effect on the
conditions of issue 16 is in the module docstring of `policies.nnbc_plus`.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policies
from policies.estimators import KalmanEstimator
from policies.nnbc_plus import NNBCPlusConfig

N, DT = 8, 0.01


def make_estimator(**options) -> KalmanEstimator:
    c = NNBCPlusConfig(**options)
    return KalmanEstimator(
        N,
        DT,
        q_jacobian=c.q_jacobian,
        q_rate=c.q_rate,
        meas_std=c.meas_std,
        innov_clip=c.innov_clip,
        innov_rate=c.innov_rate,
        p0_jacobian=c.p0_jacobian,
        p0_rate=c.p0_rate,
        forgetting=c.forgetting,
        p_max=c.p_max,
        midpoint=False,
        noise_rate=c.noise_rate,
        innov_gate=c.innov_gate,
        gate_steps=c.gate_steps,
        gate_inflate=c.gate_inflate,
        rate_time=c.rate_time,
    )


def feed(est: KalmanEstimator, J: np.ndarray, steps: int, rng: np.random.Generator, jolt: float = 0.0) -> None:
    """steps pairs of y = J x + 1 mm/s of noise (x random, 0.5 rad/s per actuator), y offset by `jolt` m/s on
    every axis."""
    for _ in range(steps):
        x = 0.5 * rng.standard_normal(N)
        est.update(x, J @ x + 0.001 * rng.standard_normal(3) + jolt)


def test_the_gate_keeps_a_transient_out_of_the_estimate_and_still_learns_a_real_change():
    rng = np.random.default_rng(3)
    J = 0.3 * rng.standard_normal((3, N))
    errors = {}
    for gate in (0.0, 3.0):
        est = make_estimator(innov_gate=gate, gate_steps=10)
        est.init(J + 0.01 * rng.standard_normal((3, N)))
        feed(est, J, 300, np.random.default_rng(4))
        before = np.linalg.norm(est.J - J) / np.linalg.norm(J)
        # a jolt: y = J x broken by 0.2 m/s for 8 steps (the physics platform's transients: 16-440 mm/s)
        feed(est, J, 8, np.random.default_rng(5), jolt=0.2)
        errors[gate] = np.linalg.norm(est.J - J) / np.linalg.norm(J)
        assert before < 0.01, before
        if gate:
            assert est.n_rejected == 8
    # without the gate the filter learns the jolt; with it J_hat does not move
    assert errors[0.0] > 0.1, errors
    assert errors[3.0] < 0.02, errors

    # a real change of J: rejected gate_steps times, then learnt (J_hat follows the new J)
    est = make_estimator(innov_gate=3.0, gate_steps=10, gate_inflate=10.0)
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


def test_the_options_parse_from_a_spec_and_are_validated():
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    try:
        pol = policies.make("nnbc-plus:innov_gate=3,gate_steps=5,gate_inflate=10,rate_time=0.05", env, seed=0)
    finally:
        env.close()
    c = pol.config
    assert (c.innov_gate, c.gate_steps, c.gate_inflate, c.rate_time) == (3.0, 5, 10.0, 0.05)
    assert pol.estimator._gate2 == 27.0 and pol.estimator._gate_steps == 5
    assert pol.estimator._rate_decay == pytest.approx(np.exp(-0.2))
    default = NNBCPlusConfig()
    assert (default.innov_gate, default.rate_time) == (0.0, 0.0)  # off by default
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="gate_steps"):
            NNBCPlusConfig(gate_steps=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="gate_inflate"):
        NNBCPlusConfig(gate_inflate=0.5)

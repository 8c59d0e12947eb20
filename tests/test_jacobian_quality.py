"""Jacobian-estimate quality (issue 12): the pure metrics of eval.metrics and what eval.rollout records.

The metrics are computed by eval from the true robot, never by the policy; controllers only expose their
estimate (`jacobian_estimate`, `jacobian_kind`).
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from conftest import SHORT_CIRCLE

import mobman_env  # noqa: F401  (registers the ids)
import policies
from eval import metrics as M
from eval.rollout import JACOBIAN_ARRAY_KEYS, JACOBIAN_KEYS, RECORD_KEYS, rollout
from mobman_env import kinematics as K


# --- known answers of the pure functions -----------------------------------------------------------------
def test_relative_error_known_answers():
    J = np.array([[3.0, 0, 0, 0], [0, 4.0, 0, 0], [0, 0, 0, 0]])
    assert M.jacobian_relative_error(J, J) == 0.0
    assert M.jacobian_relative_error(2 * J, J) == pytest.approx(1.0)
    assert M.jacobian_relative_error(np.zeros_like(J), J) == pytest.approx(1.0)
    J_hat = J.copy()
    J_hat[2, 3] = 2.5  # ||J|| = 5
    assert M.jacobian_relative_error(J_hat, J) == pytest.approx(0.5)
    batch = M.jacobian_relative_error(np.stack([J, 2 * J]), np.stack([J, J]))
    np.testing.assert_allclose(batch, [0.0, 1.0])


def test_row_space_angle_known_answers():
    e = np.eye(4)
    J = e[:3]  # rows span x, y, z of R^4
    assert M.row_space_angle(J, J) == 0.0
    assert M.row_space_angle(7.0 * J[[2, 0, 1]], J) == pytest.approx(0.0, abs=1e-15)  # same space, other basis
    for theta in (1e-9, 1e-3, 0.3, 1.2, math.pi / 2):
        J_hat = J.copy()
        J_hat[2] = math.cos(theta) * e[2] + math.sin(theta) * e[3]  # z rotated towards w by theta
        assert M.row_space_angle(J_hat, J) == pytest.approx(theta, rel=1e-9, abs=1e-15)
    rank2 = J.copy()
    rank2[2] = 0.0
    assert M.row_space_angle(rank2, J) == pytest.approx(math.pi / 2)  # a missing direction
    assert math.isnan(M.row_space_angle(np.zeros((3, 4)), J))
    with pytest.raises(ValueError, match="same shape"):
        M.row_space_angle(np.zeros((3, 4)), np.zeros((3, 5)))


def test_row_space_angle_matches_scipy_on_random_matrices():
    scipy_linalg = pytest.importorskip("scipy.linalg")
    rng = np.random.default_rng(0)
    J = rng.standard_normal((50, 3, 8))
    J_hat = J + rng.uniform(0.0, 1.0, (50, 1, 1)) * rng.standard_normal((50, 3, 8))
    got = M.row_space_angle(J_hat, J)
    expected = [scipy_linalg.subspace_angles(a.T, b.T).max() for a, b in zip(J_hat, J)]
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12)


def test_jacobian_quality_summarises_finite_steps():
    q = M.jacobian_quality(np.array([np.nan, 0.1, 0.3, 0.2]), np.array([np.nan, 0.01, 0.02, 0.05]))
    assert q == pytest.approx(
        {
            "jacobian_rel_error_median": 0.2,
            "jacobian_rel_error_max": 0.3,
            "jacobian_angle_median_rad": 0.02,
            "jacobian_angle_max_rad": 0.05,
        }
    )
    empty = M.jacobian_quality(np.full(3, np.nan), np.full(3, np.nan))
    assert set(empty.values()) == {None}


# --- what the rollout records ------------------------------------------------------------------------------
class TrueJacobianPolicy:
    """Exposes the true robot's Jacobian scaled by `factor` (a test object: it reads the env's true model)."""

    jacobian_kind = "whole_body"

    def __init__(self, env, factor: float):
        self.env, self.factor, self._obs = env, factor, None

    def reset(self, obs, info=None, *, seed=None):
        self._obs = obs

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        self._obs = observation
        return np.zeros(8, dtype=np.float32), state

    @property
    def jacobian_estimate(self):
        base = self.env.unwrapped
        q = np.asarray(self._obs["joint_pos"][:6], float)
        return self.factor * K.whole_body_jacobian(base.true_params, q, float(self._obs["base_yaw"][0]))


@pytest.fixture
def short_env():
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic", path=SHORT_CIRCLE)
    yield env
    env.close()


def test_rollout_records_known_jacobian_quality(short_env):
    rec, arrays = rollout(short_env, TrueJacobianPolicy(short_env, 2.0), 0)
    assert rec["status"] == "ok", rec["error"]
    assert set(JACOBIAN_KEYS) <= set(RECORD_KEYS) and set(JACOBIAN_KEYS) <= set(rec)
    assert rec["jacobian_kind"] == "whole_body"
    assert rec["jacobian_rel_error_median"] == pytest.approx(1.0) and rec["jacobian_rel_error_max"] == pytest.approx(
        1.0
    )
    assert rec["jacobian_angle_max_rad"] < 1e-6
    assert arrays["jacobian_rel_error"].shape == (rec["n_steps"],)


def test_rollout_records_the_estimating_controllers_only(short_env):
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    try:
        rec, arrays = rollout(env, policies.make("nnbc-plus", env), 0)
    finally:
        env.close()
    assert rec["status"] == "ok", rec["error"]
    rel = arrays["jacobian_rel_error"]
    # nan during the 16 probe steps, then a value after every predict (the 17th fits J_hat(0))
    assert np.isnan(rel[:16]).all() and np.isfinite(rel[16:]).all()
    # measured on Circle-v0 seed 0: median 1.4%, max 7.7% relative error, largest row-space angle 1.0 deg
    assert rec["jacobian_rel_error_median"] < 0.05 and rec["jacobian_angle_max_rad"] < math.radians(5)
    nnbc, _ = rollout(short_env, policies.make("nnbc", short_env), 0)
    assert nnbc["jacobian_kind"] == "paper" and nnbc["jacobian_rel_error_max"] is not None
    for spec in ("zero", "clik", "qp-oracle"):
        rec, arrays = rollout(short_env, policies.make(spec, short_env), 0)
        assert rec["status"] == "ok", rec["error"]
        assert all(rec[k] is None for k in JACOBIAN_KEYS), spec
        assert not set(JACOBIAN_ARRAY_KEYS) & set(arrays)


def test_a_bad_jacobian_kind_fails_the_episode_not_the_run(short_env):
    pol = TrueJacobianPolicy(short_env, 1.0)
    pol.jacobian_kind = "full"
    rec, _ = rollout(short_env, pol, 0)
    assert rec["status"] == "failed" and "jacobian_kind is 'full'" in rec["error"]

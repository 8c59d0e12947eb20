"""`nnbc-plus`'s structured estimate (`formulation="structured"`, `policies.laws.structured`): a synthetic arm on a
platform that slips, the composition of J, the option's checks, and the physics 5 s circle it was built for
(development seeds)."""

from __future__ import annotations

import math
from typing import TypeVar

import gymnasium as gym
import numpy as np
import pytest

import mobman_env
import policies
from policies.base import EnvFacts
from policies.laws.estimators import KalmanEstimator
from policies.laws.nnbc_plus import NNBCPlus, NNBCPlusConfig
from policies.laws.structured import StructuredEstimator

N, DT = 8, 0.01
E = TypeVar("E")
FACTS = EnvFacts(dt=DT, action_scale=(3.0,) * 6 + (10.0, 10.0), obs_keys=mobman_env.OBS_KEYS)


class SlippingPlatform:
    """An arm with a constant platform-frame Jacobian A on a platform whose wheels map to its velocity by the
    constant M (3 x 2: forward, sideways, yaw rate per wheel speed), except while `slip` adds a sideways
    velocity the wheels did not command."""

    def __init__(self, seed: int):
        rng = np.random.default_rng(seed)
        self.A = 0.3 * rng.standard_normal((3, 6))
        self.M = np.array([[0.1, 0.1], [-0.03, 0.03], [-0.3, 0.3]])
        self.yaw, self.lever = 0.3, np.array([0.4, 0.1])

    def step(self, x: np.ndarray, slip: float) -> dict:
        """Hold the actuator speeds x for one step; the observation at its end (velocities at that instant)."""
        for advance in (True, False):
            fwd, side, omega = self.M @ x[6:]
            side += slip
            c, s = math.cos(self.yaw), math.sin(self.yaw)
            base_vel = np.array([c * fwd - s * side, s * fwd + c * side])
            arm = self.A @ x[:6]
            arm_w = np.array([c * arm[0] - s * arm[1], s * arm[0] + c * arm[1], arm[2]])
            lx, ly = self.lever
            lever_rate = arm_w[:2] + omega * np.array([-ly, lx])
            if advance:  # (explicit Euler: the state at the step's end)
                self.yaw += DT * omega
                self.lever = self.lever + DT * lever_rate
        return {
            "ee_pos": np.r_[self.lever, 0.5], "ee_vel": np.r_[base_vel + lever_rate, arm_w[2]],
            "arm_base_pos": np.zeros(2), "arm_base_vel": base_vel, "base_yaw": np.array([self.yaw]),
            "joint_vel": x.copy(),
        }  # fmt: skip

    def jacobian(self) -> np.ndarray:
        """The whole-body J without slip at the current heading and lever."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        lx, ly = self.lever
        J = np.zeros((3, N))
        J[0, :6], J[1, :6], J[2, :6] = c * self.A[0] - s * self.A[1], s * self.A[0] + c * self.A[1], self.A[2]
        J[0, 6:] = c * self.M[0] - s * self.M[1] - ly * self.M[2]
        J[1, 6:] = s * self.M[0] + c * self.M[1] + lx * self.M[2]
        return J


def estimator(kind: type[E], formulation: str) -> E:
    """The estimator `nnbc-plus` builds with its default gains and this formulation, for N actuators at DT."""
    est = NNBCPlus(FACTS, NNBCPlusConfig(formulation=formulation)).estimator
    assert isinstance(est, kind)
    return est


def test_slip_does_not_reach_the_structured_estimate_but_corrupts_the_whole_body_one():
    plant = SlippingPlatform(0)
    structured = estimator(StructuredEstimator, "structured")
    whole = estimator(KalmanEstimator, "whole_body")
    rng = np.random.default_rng(1)
    obs = plant.step(np.zeros(N), 0.0)
    structured.observe(obs)
    structured.init(plant.jacobian())
    whole.init(plant.jacobian())
    errors: dict[str, list[float]] = {"structured": [], "whole": []}
    for k in range(600):
        x = 0.3 * rng.standard_normal(N)
        obs = plant.step(x, slip=0.05 if 400 <= k < 410 else 0.0)  # a 10-step slip of 50 mm/s
        structured.observe(obs)
        structured.update(x, obs["ee_vel"])
        whole.update(x, obs["ee_vel"])
        if k in (399, 410):
            J = plant.jacobian()
            for name, est in (("structured", structured), ("whole", whole)):
                errors[name].append(float(np.linalg.norm(est.J - J) / np.linalg.norm(J)))
    # before the slip both are right; the slip moves the whole-body estimate, not the structured one
    assert errors["structured"][0] < 0.02 and errors["whole"][0] < 0.02, errors
    assert errors["structured"][1] < 0.02 < 0.05 < errors["whole"][1], errors
    np.testing.assert_allclose(structured.platform.M, plant.M, atol=5e-3)  # the wheel map, learnt


def test_the_composed_rate_is_the_derivative_of_the_composed_jacobian():
    """J_dot from A_dot, the heading's rate and the lever's motion: against a finite difference of J along a
    plant with a constant A (so A_dot = 0) that turns and moves its arm."""
    plant = SlippingPlatform(2)
    est = estimator(StructuredEstimator, "structured")
    x = np.r_[0.2 * np.ones(6), 0.5, 1.5]  # turning
    est.observe(plant.step(x, 0.0))
    est.init(plant.jacobian())
    est.platform.rows = plant.M.tolist()  # (the learnt map, exact here)
    Js, Jds = [], []
    for _ in range(3):
        est.observe(plant.step(x, 0.0))
        Js.append(est.J.copy())
        Jds.append(est.Jdot.copy())
    np.testing.assert_allclose((Js[2] - Js[0]) / (2 * DT), Jds[1], atol=2e-3)


def test_the_structured_formulation_is_checked_and_uses_the_platform_keys():
    with pytest.raises(ValueError, match="structured"):
        NNBCPlusConfig(formulation="structured", measurement="position")
    with pytest.raises(ValueError, match="platform_std"):
        NNBCPlusConfig(platform_std=0.0)
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    try:
        with pytest.raises(ValueError, match="structured"):
            policies.make("broyden:formulation=structured", env, seed=0)
        pol = policies.make("nnbc-plus:formulation=structured", env, seed=0)
    finally:
        env.close()
    assert isinstance(pol.estimator, StructuredEstimator) and pol.jacobian_kind == "whole_body"
    assert {"arm_base_vel", "base_yaw"} <= set(pol.uses_keys)


def test_tracks_the_5s_physics_circle_that_the_whole_body_estimate_loses():
    """The condition `circle-5s` of issue 16 in physics mode, development seed 3 (about 1 s)."""
    from mobman_env.env import PAPER_CIRCLE

    env = gym.make("WheeledPuma-Circle-v0", dynamics="physics", path={**PAPER_CIRCLE, "duration": 5.0})
    try:
        obs, info = env.reset(seed=3)
        policy = NNBCPlus(EnvFacts.from_env(env), NNBCPlusConfig(formulation="structured"), seed=3)
        policy.reset(obs, info, seed=3)
        worst = 0.0
        for _ in range(500):
            action, _ = policy.predict(obs)
            obs, _, terminated, truncated, info = env.step(action)
            worst = max(worst, info["tracking_error"])
            if terminated or truncated:
                break
    finally:
        env.close()
    assert worst <= 0.006, f"max error {worst * 1e3:.1f} mm"

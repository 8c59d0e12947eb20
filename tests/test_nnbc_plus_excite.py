"""`nnbc-plus` excitation options of issue 16 (`info_dither`, `info_freq`, `dither_freq`): unit tests on linear
plants (y = J x, so with the whole-body estimate: a linear plant has no platform) and on the excitation signals.

All are off by default (the default controller's actions are unchanged); their measured effect on the
conditions of issue 16 is in the module docstring of `policies.nnbc_plus`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_nnbc_plus import plant_obs

import mobman_env
from policies.base import EnvFacts
from policies.nnbc_plus import NNBCPlus, NNBCPlusConfig

N, DT = 8, 0.01
FACTS = EnvFacts(dt=DT, action_scale=(3.0,) * 6 + (10.0, 10.0), obs_keys=mobman_env.OBS_KEYS)


def run_plant(config: NNBCPlusConfig, seed: int, steps: int = 400) -> tuple[float, float]:
    """A linear plant whose Jacobian changes in directions a straight path does not use, J(t) = J0 + sin(2 t) B,
    tracked along x at 0.1 m/s: (relative error of J_hat at the end, max tracking error after step 50, m)."""
    J0 = 0.3 * np.random.default_rng(7).standard_normal((3, N))
    B = 0.3 * np.random.default_rng(8).standard_normal((3, N))
    policy = NNBCPlus(FACTS, config, seed=seed)
    q, r, u = np.zeros(N), np.zeros(3), np.zeros(N)
    errors = []
    J = J0
    for k in range(steps):
        t = k * DT
        J = J0 + math.sin(2.0 * t) * B
        obs = plant_obs(q, r, u, J, t, np.array([0.1 * t, 0.0, 0.0]), np.array([0.1, 0.0, 0.0]))
        action, _ = policy.predict(obs)
        u = np.asarray(action, float) * FACTS.scale
        q, r = q + DT * u, r + DT * J @ u
        errors.append(np.linalg.norm(r - np.array([0.1 * (t + DT), 0.0, 0.0])))
    return float(np.linalg.norm(policy.estimator.J - J) / np.linalg.norm(J)), float(max(errors[50:]))


def test_directed_excitation_learns_what_the_path_leaves_unexcited_at_a_cost_in_tracking():
    """The null-space dither cannot excite J's row space and the path excites one direction of it: where J
    changes in the others, J_hat goes stale (18-20% here). `info_dither` excites the filter's least certain
    direction and keeps J_hat within about 5%, but it moves the end-effector (0.5 -> 1 mm here)."""
    for seed in range(2):
        err0, track0 = run_plant(NNBCPlusConfig(formulation="whole_body"), seed)
        err1, track1 = run_plant(NNBCPlusConfig(formulation="whole_body", info_dither=0.05), seed)
        assert err1 < 0.4 * err0, (err0, err1)
        assert track0 < track1 < 2e-3, (track0, track1)


def test_the_directed_excitation_follows_the_top_eigenvector_and_comes_back():
    policy = NNBCPlus(FACTS, NNBCPlusConfig(formulation="whole_body", info_dither=0.05), seed=0)
    policy._reset(plant_obs(np.zeros(N), np.zeros(3), np.zeros(N), np.zeros((3, N)), 0.0, np.zeros(3), np.zeros(3)))
    top = np.zeros(N)
    top[3] = 1.0
    P = policy.P
    P[:N, :N] = np.diag(np.full(N, 1e-4)) + 1e-2 * np.outer(top, top)  # the filter is unsure along actuator 3
    pairs = [policy._directed(k) + policy._directed(k + 1) for k in range(0, 40, 2)]
    d = policy._directed(40)
    np.testing.assert_allclose(np.abs(d), 0.05 * top, atol=1e-9)  # power iteration: on the top eigenvector
    np.testing.assert_allclose(pairs, 0.0, atol=1e-15)  # every pair sums to zero: the end-effector comes back
    smooth = NNBCPlus(FACTS, NNBCPlusConfig(formulation="whole_body", info_dither=0.05, info_freq=5.0), seed=0)
    smooth._reset(plant_obs(np.zeros(N), np.zeros(3), np.zeros(N), np.zeros((3, N)), 0.0, np.zeros(3), np.zeros(3)))
    smooth.P[:N, :N] = P[:N, :N]
    steps = np.array([smooth._directed(k) for k in range(60)])
    assert np.abs(steps).max() <= 0.05 + 1e-12
    assert np.abs(np.diff(steps[20:], axis=0)).max() <= 0.05 * 2 * math.pi * 5.0 * DT + 1e-9  # smooth


def test_the_smooth_dither_bounds_the_step_to_step_change():
    """Random signs change an actuator's dither by up to 2 dither per step (10 rad/s^2 at the default); the
    sinusoids of `dither_freq` by at most dither 2 pi f dt, f from dither_freq (actuator 0) to twice it (the
    last)."""
    freq = 2.0
    policy = NNBCPlus(FACTS, NNBCPlusConfig(formulation="whole_body", dither_freq=freq), seed=0)
    policy._reset(plant_obs(np.zeros(N), np.zeros(3), np.zeros(N), np.zeros((3, N)), 0.0, np.zeros(3), np.zeros(3)))
    a = policy.config.dither
    rows = np.vstack([policy._sinusoids(), policy._sinusoids()])  # 5.12 s, continuous across the blocks
    assert np.abs(np.diff(rows, axis=0)).max() <= a * 2 * math.pi * 2 * freq * DT + 1e-12
    assert np.abs(rows).max() <= a
    crossings = np.count_nonzero(np.diff(np.sign(rows), axis=0), axis=0)  # 2 f T zero crossings
    assert abs(crossings[0] - 2 * freq * 5.12) <= 2 and abs(crossings[-1] - 4 * freq * 5.12) <= 2, crossings


def test_the_excitation_options_are_off_by_default_and_validated():
    c = NNBCPlusConfig()
    assert (c.info_dither, c.info_freq, c.dither_freq) == (0.0, 0.0, 0.0)
    for name in ("info_dither", "info_freq", "dither_freq"):
        with pytest.raises(ValueError, match=name):
            NNBCPlusConfig(**{name: -1.0})  # type: ignore[arg-type]

"""`nnbc-plus` v5 (issue 38): the claims of its changes, on development seeds 0-3 (0-999 are tuning seeds; nothing
here is a reported figure), each on the native vector env (`policies.make(spec, vector_env)`: a few seconds).

* joint speeds are not the regressor (`measurement="angles"`): noise on `joint_vel` does not reach the estimate;
* joint stops are learnt once hit (`stop_margin`): a joint is not driven into its stop again and again;
* the dither can be low-passed (`dither_time`, off by default: it costs episodes under the dev track's noise):
  the commands' acceleration at the default condition falls from 55 times `qp`'s to 10 times, and heavy sensor
  noise no longer makes the estimate diverge;
* v5.1: the Kalman filter's measurement noise R starts at the probe's residual variance (`probe_noise_start`),
  not at its floor: heavy velocity noise is not learnt into J_hat while R climbs; and the lag bank holds six
  time constants log-spaced over the dev range (`LAG_TAUS`): a lag between two of v5's three is not mistaken.
"""

from __future__ import annotations

import numpy as np
import pytest

import policies
from eval.rollout import make_vector_env, rollout_batch

DEV_SEEDS = 0  # development seeds DEV_SEEDS .. DEV_SEEDS + 3
N = 4


def episodes(spec: str, env_id: str, **env_kwargs) -> list[dict]:
    """The records of `spec` on development seeds 0-3 of `env_id` (kinematic, 5% wear unless told)."""
    obs_noise = env_kwargs.pop("obs_noise", None)
    venv = make_vector_env(env_id, N, "kinematic", env_kwargs.pop("model_error", 0.05), obs_noise, env_kwargs)
    try:
        return [rec for rec, _ in rollout_batch(venv, policies.make(spec, venv), DEV_SEEDS)]
    finally:
        venv.close()


def max_errors_mm(recs: list[dict]) -> list[float]:
    return [round(r["max_error_m"] * 1e3, 2) for r in recs]


@pytest.mark.parametrize("spec", ["nnbc-plus", "nnbc-plus-wb"])
def test_noise_on_the_joint_speeds_does_not_reach_the_estimate(spec):
    """Issue 38: 0.05 rad/s of noise on `joint_vel` (an errors-in-variables regression: v4 regressed J on the
    noisy speeds) lost every one of these episodes (v4: 77, 23, 38 and 30 mm on PUMA Circle, development seeds
    0-3). v5 regresses on the joint angles' differences (encoders), turned into the speeds at t_k under the
    chosen actuator model: the episodes track within the paper's 6 mm, and the same law on `joint_vel`
    (`measurement="velocity"`) does not."""
    now = episodes(spec, "WheeledPuma-Circle-v0", obs_noise_joint_vel=0.05)
    before = episodes(f"{spec}:measurement=velocity", "WheeledPuma-Circle-v0", obs_noise_joint_vel=0.05)
    assert max(r["max_error_m"] for r in now) <= 0.006, max_errors_mm(now)
    assert np.median([r["max_error_m"] for r in before]) > 0.006, max_errors_mm(before)


def test_a_joint_stop_is_learnt_once_hit_ur5_line():
    """Issue 38: on the UR5's Line the elbow reaches its stop; v4 released it once the posture pull had moved it
    away and drove it back in: 44 limit hits on development seed 0. v5 keeps the stop's angle for the episode
    and damps the joint's approach to it (`stop_margin`): a few hits (the ones that reveal the stop)."""
    now = episodes("nnbc-plus", "WheeledUR5-Line-v0")
    before = episodes("nnbc-plus:stop_margin=0", "WheeledUR5-Line-v0")
    hits_now = [r["joint_limit_hits"] for r in now]
    hits_before = [r["joint_limit_hits"] for r in before]
    assert max(hits_now) <= 5 and sum(hits_before) > 4 * sum(hits_now), (hits_now, hits_before)


HEAVY15 = {"obs_noise": 0.003, "obs_noise_vel": 0.03, "obs_noise_yaw": 0.0045}  # 1.5x the held-out noise-heavy


def test_a_low_passed_dither_makes_the_commands_smooth():
    """Issue 38: the white random-sign dither (0.05 rad/s, new signs every step) is most of the commands'
    acceleration: 16 rad/s^2 RMS at `default`, 55x `qp`'s. Low-passed (`dither_time` 0.05 s): a few rad/s^2 on
    these episodes, with every one still tracked within the paper's 6 mm."""
    now = episodes("nnbc-plus:dither_time=0.05", "WheeledPuma-Circle-v0")
    white = episodes("nnbc-plus", "WheeledPuma-Circle-v0")
    accel_now = [r["cmd_accel_rms"] for r in now]
    accel_white = [r["cmd_accel_rms"] for r in white]
    assert np.median(accel_now) < 4.0 < 10.0 < np.median(accel_white), (accel_now, accel_white)
    assert max(r["max_error_m"] for r in now) <= 0.006, max_errors_mm(now)


def test_heavy_sensor_noise_does_not_make_it_diverge():
    """Issue 38: at 1.5x the held-out `noise-heavy` condition (3 mm, 0.03 m/s, 4.5 mrad) v4 diverged (PUMA Circle,
    development seeds 0-3: 83-949 mm; v5, R starting at its floor: 103-1788 mm). v5's low-passed dither
    (`dither_time` 0.05 s) kept the estimate near J, and v5.1's start of R at the probe's residual variance does
    with the white dither too: the median max error stays under the issue's 20 mm (no divergence)."""
    for spec in ("nnbc-plus", "nnbc-plus:dither_time=0.05"):
        now = episodes(spec, "WheeledPuma-Circle-v0", **HEAVY15)
        assert np.median([r["max_error_m"] for r in now]) < 0.020, (spec, max_errors_mm(now))
    v5 = episodes("nnbc-plus:probe_noise_start=false", "WheeledPuma-Circle-v0", **HEAVY15)
    assert np.median([r["max_error_m"] for r in v5]) > 0.1, max_errors_mm(v5)


def test_the_probe_residual_variance_is_the_noise_of_y():
    """`probe_residual_variance` from the probe's sums (A = sum x x^T, B = sum y x^T, sum |y|^2) and its fit J is
    the variance of one component of y's noise: 2,000 pairs of y = J x + noise (0.02 m/s) give 4e-4 within 5%;
    noiseless pairs give 0."""
    from policies.kernels import model_free as K

    rng = np.random.default_rng(0)
    n, m = 8, 2000
    J = rng.normal(size=(3, n))
    x = rng.normal(scale=0.05, size=(m, n))
    for std, want in ((0.02, 4e-4), (0.0, 0.0)):
        y = x @ J.T + rng.normal(scale=std, size=(m, 3)) if std else x @ J.T
        A, B = x.T @ x, y.T @ x
        fit = np.linalg.solve(A, B.T).T
        f = np.concatenate([A.ravel(), B.ravel(), [np.sum(y * y)], fit.ravel()])
        got = K.probe_residual_variance(f, n, m, 0, n * n, n * n + 3 * n, n * n + 3 * n + 1)
        assert got == pytest.approx(want, rel=0.05, abs=1e-12), got


@pytest.mark.parametrize("spec", ["nnbc-plus", "nnbc-plus-wb"])
def test_heavy_velocity_noise_is_not_learnt_into_the_estimate(spec):
    """Issue 38 (v5.1): protocol v2's noise-heavy condition (2 mm, 0.02 m/s, 3 mrad) on the PUMA's Lemniscate.
    With R starting at its floor (meas_std^2, v5) the filter trusts every noisy reading for the ~333 steps its
    noise estimate needs to climb, and learns the noise into J_hat (nnbc-plus: 156, 17, 36 and 40 mm); started at
    the probe's residual variance the episodes track within 6 mm."""
    kw = dict(obs_noise=0.002, obs_noise_vel=0.02, obs_noise_yaw=0.003)
    now = episodes(spec, "WheeledPuma-Lemniscate-v0", **kw)
    before = episodes(f"{spec}:probe_noise_start=false", "WheeledPuma-Lemniscate-v0", **kw)
    assert max(r["max_error_m"] for r in now) <= 0.006, max_errors_mm(now)
    assert np.median([r["max_error_m"] for r in before]) > 0.006, max_errors_mm(before)


def test_the_lag_bank_spans_the_dev_range_and_a_lag_between_v5s_models_is_tracked():
    """Issue 38 (v5.1): v5's bank (0.02, 0.05, 0.2 s) mistook a 100 ms lag for one of its models and the law
    diverged on the PUMA (development seeds 0-3: Circle 1,545 mm on seed 3, Lemniscate 363 and 71 mm on seeds 1
    and 2). The bank is six time constants spaced evenly in log over the declared dev range 20-200 ms, with the
    dev track's 50 ms among them; 100 and 150 ms (between two models) are tracked within 6 mm."""
    from policies.laws.nnbc_plus import LAG_TAUS

    assert LAG_TAUS[0] == pytest.approx(0.02) and LAG_TAUS[-1] == pytest.approx(0.2) and len(LAG_TAUS) == 6
    assert np.allclose(np.diff(np.log(LAG_TAUS)), np.log(10) / 5)
    assert min(abs(t - 0.05) for t in LAG_TAUS) < 0.001
    for tau in (0.1, 0.15):
        for env_id in ("WheeledPuma-Circle-v0", "WheeledPuma-Lemniscate-v0"):
            recs = episodes("nnbc-plus", env_id, actuator_tau=tau)
            assert max(r["max_error_m"] for r in recs) <= 0.006, (tau, env_id, max_errors_mm(recs))

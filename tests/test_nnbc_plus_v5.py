"""`nnbc-plus` v5 (issue 38): the claims of its changes, on development seeds 0-3 (0-999 are tuning seeds; nothing
here is a reported figure), each on the native vector env (`policies.make(spec, vector_env)`: a few seconds).

* joint speeds are not the regressor (`measurement="angles"`): noise on `joint_vel` does not reach the estimate;
* joint stops are learnt once hit (`stop_margin`): a joint is not driven into its stop again and again;
* the dither can be low-passed (`dither_time`, off by default: it costs episodes under the dev track's noise):
  the commands' acceleration at the default condition falls from 55 times `qp`'s to 10 times, and heavy sensor
  noise no longer makes the estimate diverge.
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


def test_with_a_low_passed_dither_heavy_sensor_noise_does_not_make_it_diverge():
    """Issue 38: at 1.5x the held-out `noise-heavy` condition (3 mm, 0.03 m/s, 4.5 mrad) v4 diverged (PUMA Circle,
    development seeds 0-3: 83-949 mm; v5's default, with the white dither: 103-1788 mm). With the low-passed
    dither (`dither_time` 0.05 s) the estimate stays near J: the episodes are not tracked within 6 mm, but the
    median max error stays under the issue's 20 mm (no divergence)."""
    now = episodes("nnbc-plus:dither_time=0.05", "WheeledPuma-Circle-v0", **HEAVY15)
    white = episodes("nnbc-plus", "WheeledPuma-Circle-v0", **HEAVY15)
    assert np.median([r["max_error_m"] for r in now]) < 0.020, max_errors_mm(now)
    assert np.median([r["max_error_m"] for r in white]) > 0.1, max_errors_mm(white)

"""Known-answer tests of eval.metrics on hand-made arrays."""

import math

import numpy as np
import pytest

from eval import metrics as M


def _paths():
    # 5 samples; r_a deviates from r_d by a known vector at each sample
    r_d = np.zeros((5, 3))
    dev = np.array([[0, 0, 0], [0.003, 0, 0], [0, -0.004, 0], [0, 0, 0.002], [0.003, 0.004, 0]], float)
    return r_d, r_d - dev, np.array([0.0, 0.003, 0.004, 0.002, 0.005])


def test_error_norm_max_rms_final():
    r_d, r_a, expected = _paths()
    err = M.error_norm(r_d, r_a)
    np.testing.assert_allclose(err, expected, atol=1e-15)
    assert M.max_error(err) == pytest.approx(0.005)
    assert M.rms_error(err) == pytest.approx(math.sqrt((0.003**2 + 0.004**2 + 0.002**2 + 0.005**2) / 5))
    assert M.final_error(err) == pytest.approx(0.005)
    assert M.axis_max_error(r_d, r_a) == pytest.approx([0.003, 0.004, 0.002])


def test_effort_is_integral_of_squared_action():
    a = np.zeros((4, 8))
    a[0, 0] = 1.0  # ||a||^2 = 1
    a[1, :] = 0.5  # ||a||^2 = 8 * 0.25 = 2
    assert M.effort(a, dt=0.01) == pytest.approx(0.03)
    assert M.effort(np.zeros((0, 8)), 0.01) == 0.0


def test_peak_speeds_use_the_action_scale():
    scale = [3, 3, 3, 5, 5, 5, 10, 10]
    a = np.zeros((3, 8))
    a[0, 3] = -0.8  # joint 4: 4 rad/s
    a[1, 1] = 0.9  # joint 2: 2.7 rad/s
    a[2, 7] = -0.25  # right wheel: 2.5 rad/s
    joint, wheel = M.peak_speeds(a, scale)
    assert joint == pytest.approx(4.0)
    assert wheel == pytest.approx(2.5)


def test_timing_stats():
    us = np.arange(1, 101, dtype=float)
    med, p99 = M.timing_stats(us)
    assert med == pytest.approx(50.5)
    assert p99 == pytest.approx(np.percentile(us, 99))


@pytest.mark.parametrize(
    "max_err, status, tipped, expected",
    [
        (0.006, "ok", False, True),  # the bound itself counts
        (0.0061, "ok", False, False),
        (0.001, "failed", False, False),  # a failed episode is never a success
        (0.001, "ok", True, False),
        (None, "failed", False, False),
        (math.nan, "ok", False, False),
    ],
)
def test_success(max_err, status, tipped, expected):
    assert M.is_success(max_err, 0.006, status=status, tipped_over=tipped) is expected


def test_episode_metrics_known_answer():
    r_d, r_a, _ = _paths()
    a = np.full((4, 8), 0.5)
    m = M.episode_metrics(r_d, r_a, a, dt=0.1, action_scale=[3, 3, 3, 5, 5, 5, 10, 10], tolerance=0.006)
    assert m["max_error_m"] == pytest.approx(0.005)
    assert m["effort"] == pytest.approx(4 * 2.0 * 0.1)
    assert m["peak_joint_speed"] == pytest.approx(2.5)
    assert m["peak_wheel_speed"] == pytest.approx(5.0)
    assert m["success"] is True
    assert M.episode_metrics(r_d, r_a, a, 0.1, [1] * 8, tolerance=0.004)["success"] is False


def test_aggregate_groups_counts_failures_and_ignores_them_in_statistics():
    base = {"env": "E", "dynamics": "kinematic", "model_error": 0.05, "obs_noise": 0.0}
    recs = [
        {**base, "policy": "a", "status": "ok", "success": True, "max_error_m": 0.001, "tipped_over": False},
        {**base, "policy": "a", "status": "ok", "success": False, "max_error_m": 0.010, "tipped_over": False},
        {**base, "policy": "a", "status": "ok", "success": True, "max_error_m": 0.004, "tipped_over": False},
        {**base, "policy": "a", "status": "failed", "success": False, "max_error_m": None},
        {**base, "policy": "b", "status": "ok", "success": True, "max_error_m": 0.002, "tipped_over": False},
    ]
    rows = M.aggregate(recs)
    assert [r["policy"] for r in rows] == ["a", "b"]
    a = rows[0]
    assert a["n"] == 4 and a["n_failed"] == 1
    assert a["success_rate"] == pytest.approx(0.5)
    assert a["max_error_m"]["median"] == pytest.approx(0.004)
    assert a["max_error_m"]["mean"] == pytest.approx(0.005)
    assert a["max_error_m"]["std"] == pytest.approx(np.std([0.001, 0.010, 0.004]))
    assert a["effort"]["median"] is None  # no episode recorded it
    assert rows[1]["success_rate"] == 1.0 and rows[1]["n_failed"] == 0

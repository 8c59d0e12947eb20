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


def test_command_smoothness_known_answers():
    """u = a * scale from rest: a step to 1 rad/s at k = 0 and held has one jump (1/dt) among n steps, and its
    second difference a +1/dt^2 then -1/dt^2 pair."""
    dt, n = 0.01, 100
    a = np.zeros((n, 2))
    a[:, 0] = 0.5  # 0.5 x scale 2 = 1 rad/s from the first step on
    accel, jerk = M.command_smoothness(a, dt, [2.0, 1.0])
    assert accel == pytest.approx(math.sqrt(1.0 / n) / dt, rel=1e-12)
    assert jerk == pytest.approx(math.sqrt(2.0 / n) / dt**2, rel=1e-12)
    # a ramp u_k = c k dt has a constant acceleration c (after the start) and no jerk but at the start
    ramp = (np.arange(n) * dt * 3.0)[:, None]
    accel, _ = M.command_smoothness(ramp, dt, [1.0])
    assert accel == pytest.approx(3.0 * math.sqrt((n - 1) / n), rel=1e-12)
    assert M.command_smoothness(np.zeros((0, 2)), dt, [1.0, 1.0]) == (0.0, 0.0)


def test_limit_margin_and_converge_time():
    q = np.array([[0.0, 0.5], [0.9, -0.2], [0.3, 0.1]])
    assert M.limit_margin(q, [-1.0, -1.0], [1.0, 1.0]) == pytest.approx(0.1)
    assert M.limit_margin(np.array([[1.2]]), [-1.0], [1.0]) == pytest.approx(-0.2)  # beyond the limit: negative
    err = np.array([0.0, 0.01, 0.002, 0.007, 0.001, 0.0])
    assert M.converge_time(err, 0.1, 0.006) == pytest.approx(0.4)  # stays within from sample 4 on
    assert M.converge_time(np.array([0.0, 0.001]), 0.1, 0.006) == 0.0
    assert M.converge_time(np.array([0.0, 0.01]), 0.1, 0.006) is None  # ends outside


def test_clean_success_and_the_tails_in_the_aggregate():
    recs = [
        {"env": "E", "policy": "p", "status": "ok", "max_error_m": e, "success": e <= 0.006, "clean_success": c}
        for e, c in ((0.001, True), (0.002, False), (0.003, True), (0.004, True), (0.05, False))
    ]
    (row,) = M.aggregate(recs)
    assert row["success_rate"] == 0.8 and row["clean_success_rate"] == 0.6
    assert row["clean_success_rate_ci95"] == M.wilson_interval(3, 5)
    assert row["max_error_m"]["worst"] == 0.05 and row["max_error_m"]["p90"] == pytest.approx(
        np.percentile([0.001, 0.002, 0.003, 0.004, 0.05], 90)
    )
    assert len(row["success_curve_ci95"]) == len(row["success_curve"])
    for p, band in zip(row["success_curve"], row["success_curve_ci95"]):
        assert band == M.wilson_interval(round(p * 5), 5) and band[0] <= p <= band[1]


def test_probability_of_improvement_known_answers():
    """P(X < Y) on a lower-is-better score, ties half, averaged over tasks; the bootstrap interval holds the
    point estimate and collapses when every pair agrees."""
    p, ci = M.probability_of_improvement([[1.0, 2.0, 3.0]], [[4.0, 5.0, 6.0]])
    assert p == 1.0 and ci == [1.0, 1.0]
    p, ci = M.probability_of_improvement([[1.0, 2.0]], [[1.0, 2.0]])
    assert p == 0.5 and ci[0] <= 0.5 <= ci[1]
    # two tasks: 1.0 on the first, 0.0 on the second -> 0.5; a failed episode (inf) loses to every finite one
    p, _ = M.probability_of_improvement([[1.0], [9.0]], [[2.0], [3.0]])
    assert p == 0.5
    p, _ = M.probability_of_improvement([[math.inf]], [[5.0]])
    assert p == 0.0
    assert M.probability_of_improvement([[]], [[1.0]]) is None

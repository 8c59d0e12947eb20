"""Known-answer tests of eval.metrics' schema-2 statistics: IQM, its stratified bootstrap CI, Wilson intervals,
success-vs-tolerance curves and steady-state errors."""

import math

import numpy as np
import pytest

from eval import metrics as M


def test_iqm_known_answers():
    assert M.iqm([1, 2, 3, 4, 5, 6, 7, 8]) == pytest.approx(4.5)  # cut 2 each end: mean(3, 4, 5, 6)
    assert M.iqm([10, 1, 2, 3, 100]) == pytest.approx(5.0)  # n = 5: cut 1 each end: mean(2, 3, 10)
    assert M.iqm([7.0]) == 7.0
    assert M.iqm([None, math.nan, 2.0, math.inf]) == 2.0  # non-finite values are dropped
    assert M.iqm([]) is None


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 7, 10, 20, 21, 33])
def test_iqm_is_scipy_trim_mean(n):
    stats = pytest.importorskip("scipy.stats")
    x = np.random.default_rng(n).lognormal(size=n)
    assert M.iqm(x) == pytest.approx(stats.trim_mean(x, 0.25), rel=1e-12)


def test_iqm_ci_is_fixed_and_contains_the_iqm():
    x = np.random.default_rng(3).lognormal(-6, 1, size=20)
    ci = M.iqm_ci95([x])
    assert ci == M.iqm_ci95([x])  # a pure function: the bootstrap seed is fixed
    assert ci[0] < M.iqm(x) < ci[1]
    assert M.iqm_ci95([x], seed=M.BOOTSTRAP_SEED + 1) != ci
    assert M.iqm_ci95([[0.004] * 6]) == [0.004, 0.004]
    assert M.iqm_ci95([[], [None]]) is None


def test_iqm_ci_resamples_within_strata():
    # two strata of four: every stratified resample has four 0s and four 1s, so its IQM is exactly 0.5;
    # a pooled (unstratified) bootstrap would give intervals around 0.5 of width ~0.7
    ci = M.iqm_ci95([[0.0] * 4, [1.0] * 4])
    assert ci == [0.5, 0.5]
    pooled = M.iqm_ci95([[0.0] * 4 + [1.0] * 4])
    assert pooled[1] - pooled[0] > 0.5


def test_iqm_ci_agrees_with_scipy_percentile_bootstrap():
    stats = pytest.importorskip("scipy.stats")
    x = np.random.default_rng(11).normal(1.0, 0.2, size=60)
    ours = M.iqm_ci95([x])
    theirs = stats.bootstrap(
        (x,),
        lambda s, axis: stats.trim_mean(s, 0.25, axis=axis),
        n_resamples=4000,
        method="percentile",
        rng=np.random.default_rng(0),
    ).confidence_interval
    # different random streams: the ends agree to a small fraction of the interval's width (~0.12)
    assert ours[0] == pytest.approx(theirs.low, abs=0.015)
    assert ours[1] == pytest.approx(theirs.high, abs=0.015)


@pytest.mark.parametrize(
    "k, n, expected",
    [
        (5, 10, [0.236593, 0.763407]),  # textbook values (e.g. Newcombe 1998)
        (0, 10, [0.0, 0.277533]),
        (10, 10, [0.722467, 1.0]),
    ],
)
def test_wilson_interval(k, n, expected):
    assert M.wilson_interval(k, n) == pytest.approx(expected, abs=1e-6)


@pytest.mark.parametrize("k, n", [(1, 20), (17, 20), (3, 7), (50, 80)])
def test_wilson_interval_is_scipys(k, n):
    stats = pytest.importorskip("scipy.stats")
    ci = stats.binomtest(k, n).proportion_ci(method="wilson")
    assert M.wilson_interval(k, n) == pytest.approx([ci.low, ci.high], abs=1e-12)


def test_wilson_interval_without_episodes():
    assert M.wilson_interval(0, 0) is None


def test_success_curve_grid_is_logarithmic_and_fixed():
    grid = np.array(M.SUCCESS_CURVE_TOLERANCES)
    assert len(grid) == 31
    assert grid[0] == pytest.approx(1e-4) and grid[-1] == pytest.approx(0.1) and grid[10] == pytest.approx(1e-3)
    np.testing.assert_allclose(np.diff(np.log10(grid)), 0.1, atol=1e-12)


def test_success_curve_counts_failures_as_failures():
    recs = [
        {"status": "ok", "max_error_m": 0.0002},
        {"status": "ok", "max_error_m": 0.001},  # exactly on a grid point: counts (<=)
        {"status": "ok", "max_error_m": 0.05, "tipped_over": True},
        {"status": "failed", "max_error_m": None},
    ]
    tol = [1e-4, 0.0002, 0.001, 0.01, 0.1]
    assert M.success_curve(recs, tol) == [0.0, 0.25, 0.5, 0.5, 0.5]
    curve = M.success_curve(recs)
    assert len(curve) == 31 and curve == sorted(curve)  # non-decreasing in the tolerance
    assert M.success_curve([]) == []


def test_steady_errors_skip_the_transient():
    dt = 0.01
    err = np.full(201, 0.001)
    err[:50] = 0.05  # a transient over t < 0.5 s
    err[120] = 0.002
    mx, rms = M.steady_errors(err, dt, 0.5)
    assert mx == pytest.approx(0.002)
    tail = err[50:]
    assert rms == pytest.approx(math.sqrt(np.mean(tail**2)))
    assert M.steady_errors(err, dt, 0.0)[0] == pytest.approx(0.05)
    assert all(math.isnan(v) for v in M.steady_errors(err[:30], dt, 0.5))  # ended before the settle time


def test_steady_errors_include_the_settle_sample_despite_rounding():
    err = np.zeros(101)
    err[30] = 1.0  # sample 30 is at t = 0.3 s, which 30 * 0.01 only approximates
    assert M.steady_errors(err, 0.01, 0.3)[0] == 1.0
    assert M.steady_errors(err, 0.01, 0.31)[0] == 0.0


def test_episode_metrics_have_steady_errors():
    r_d = np.zeros((101, 3))
    r_a = np.zeros((101, 3))
    r_a[:10, 0] = 0.01
    m = M.episode_metrics(r_d, r_a, np.zeros((100, 8)), 0.01, [1] * 8, settle_time=0.1)
    assert m["max_error_m"] == pytest.approx(0.01)
    assert m["steady_max_error_m"] == 0.0 and m["steady_rms_error_m"] == 0.0


def _rec(env, err, status="ok"):
    ok = status == "ok"
    return {
        "env": env,
        "policy": "p",
        "dynamics": "kinematic",
        "model_error": 0.05,
        "obs_noise": 0.0,
        "status": status,
        "max_error_m": err if ok else None,
        "steady_max_error_m": err / 2 if ok else None,
        "steady_rms_error_m": err / 4 if ok else None,
        "success": ok and err <= 0.006,
    }


def test_aggregate_schema_2_fields():
    recs = [_rec("A", e) for e in (0.001, 0.002, 0.003, 0.004, 0.01)] + [_rec("A", 0.0, "failed")]
    (row,) = M.aggregate(recs)
    assert row["success_rate"] == pytest.approx(4 / 6)
    assert row["success_rate_ci95"] == pytest.approx(M.wilson_interval(4, 6))
    assert row["max_error_m"]["iqm"] == pytest.approx(0.003)  # over the 5 ok episodes: mean(2, 3, 4) mm
    lo, hi = row["max_error_m"]["iqm_ci95"]
    assert lo <= 0.003 <= hi
    assert row["steady_max_error_m"]["iqm"] == pytest.approx(0.0015)
    assert row["steady_rms_error_m"]["median"] == pytest.approx(0.00075)
    assert len(row["success_curve"]) == len(M.SUCCESS_CURVE_TOLERANCES)
    assert row["success_curve"][-1] == pytest.approx(5 / 6)  # the failed episode fails at every tolerance


def test_aggregate_strata_key_pools_tasks_stratified():
    recs = [_rec("A", 0.001)] * 4 + [_rec("B", 0.009)] * 4
    pooled = M.aggregate(recs, group_keys=("policy",), strata_key="env")
    assert pooled[0]["max_error_m"]["iqm_ci95"] == pytest.approx([0.005, 0.005])
    unstratified = M.aggregate(recs, group_keys=("policy",))
    lo, hi = unstratified[0]["max_error_m"]["iqm_ci95"]
    assert hi - lo > 0.004

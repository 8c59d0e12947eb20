"""`mobman_env.feasibility`: is an episode's path within the true robot's actuator limits? (protocol v3's
`feasible` flag)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mobman_env  # noqa: F401  (registers the ids)
from mobman_env import feasibility as F

DEV_SEEDS = range(5)


def _ladder(duration: float) -> dict:
    return {"path": {"type": "random", "size": 0.3, "n_terms": 5, "duration": duration}}


def test_the_least_norm_solve_is_numpys_damped_least_norm():
    rng = np.random.default_rng(0)
    for m in (8, 9):
        jac, scale, v = rng.normal(size=(3, m)), rng.uniform(1, 10, m), rng.normal(size=3)
        w = np.empty(m)
        peak, which = F._least_norm(jac, scale, m, v, 1e-3, w)
        A = jac * scale
        expected = A.T @ np.linalg.solve(A @ A.T + 1e-6 * np.eye(3), v)
        np.testing.assert_allclose(w, expected, rtol=1e-10, atol=1e-13)
        assert peak == pytest.approx(np.abs(expected).max()) and which == int(np.abs(expected).argmax())


@pytest.mark.parametrize(
    "env_id", ["WheeledPuma-Circle-v0", "WheeledPuma-Line-v0", "WheeledPuma-Lemniscate-v0", "WheeledPanda-Random-v0"]
)
@pytest.mark.parametrize("wear_rate, bound", [(0.0, 1e-4), (0.005, 4e-4)])
def test_the_tasks_are_feasible_and_the_reference_law_tracks_the_true_robot(env_id, wear_rate, bound):
    """The four 20 s tasks need a fraction of the limits; the reference law, knowing the true robot, tracks them to
    a tenth of a millimetre: the check integrates the robot it judges. Under wear drift the lengths move under the
    law (about 0.005 x 1 m per second, not fed forward), so it lags by about that speed over its gain (0.25 mm)."""
    env = gym.make(env_id, dynamics="kinematic", wear_rate=wear_rate)
    for seed in DEV_SEEDS:
        env.reset(seed=seed)
        f = F.check_env(env)
        assert f.feasible and f.peak_ratio < 0.5, f
        assert f.reference_error < bound, f
    env.close()


def test_halving_the_duration_doubles_the_peak_and_the_fast_rung_is_infeasible():
    ratios = {}
    for d in (5.0, 2.5):
        env = gym.make("WheeledPuma-Random-v0", dynamics="kinematic", **_ladder(d))
        ratios[d] = []
        for seed in DEV_SEEDS:
            env.reset(seed=seed)
            ratios[d].append(F.check_env(env).peak_ratio)
        env.close()
    quotient = np.array(ratios[2.5]) / np.array(ratios[5.0])
    assert np.all((quotient > 1.6) & (quotient < 2.6)), quotient  # speeds scale with 1 / duration
    assert sum(r > 1.0 - F.FEASIBILITY_MARGIN for r in ratios[2.5]) >= 3  # most of the 2.5 s rung


def test_rows_of_a_vector_env_are_checked_as_single_envs():
    kw = {"dynamics": "kinematic", "model_error": 0.1, **_ladder(5.0)}
    venv = gym.make_vec("WheeledUR5-Random-v0", num_envs=4, vectorization_mode="vector_entry_point", **kw)
    venv.reset(seed=100)
    rows = F.check_rows(venv.unwrapped._batch, range(4))
    venv.close()
    env = gym.make("WheeledUR5-Random-v0", **kw)
    for i in range(4):
        env.reset(seed=100 + i)
        assert F.check_env(env) == rows[i]
    env.close()


@pytest.mark.parametrize("margin", [-0.1, 1.0, float("nan")])
def test_a_margin_outside_0_1_is_refused(margin):
    env = gym.make("WheeledPuma-Circle-v0", dynamics="kinematic")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="margin"):
        F.check_env(env, margin)
    env.close()


def test_a_ladder_rung_drawn_feasible_is_feasible_deterministic_and_the_same_in_the_vector_env():
    """`max_peak` redraws a random path from the episode's generator until the reference law stays within it: the
    2.5 s rung (most of its plain draws infeasible, above) becomes feasible on every dev seed, a seed gives the same
    path twice, and row i of a vector env reset with seed s draws what a single env reset with s + i draws."""
    from eval.conditions import CONDITIONS, LADDER_MAX_PEAK

    kw = {"dynamics": "kinematic", **CONDITIONS["ladder-2.5s"].env_kwargs}
    assert kw["path"]["max_peak"] == LADDER_MAX_PEAK == 1.0 - F.FEASIBILITY_MARGIN
    env = gym.make("WheeledPuma-Random-v0", **kw)
    specs = []
    for seed in range(8):
        env.reset(seed=seed)
        assert F.check_env(env).feasible, seed
        specs.append(env.unwrapped.path.to_spec())
    env.reset(seed=3)
    assert env.unwrapped.path.to_spec() == specs[3]
    venv = gym.make_vec("WheeledPuma-Random-v0", num_envs=4, vectorization_mode="vector_entry_point", **kw)
    venv.reset(seed=0)
    assert [venv.unwrapped._batch.paths[i].to_spec() for i in range(4)] == specs[:4]
    venv.close()
    env.close()


@pytest.mark.parametrize(
    "path, match",
    [
        ({"type": "random", "seed": 3, "max_peak": 0.9}, r"cannot be combined with a fixed seed; give one of them"),
        ({"type": "random", "max_peak": 0.0}, r"max_peak"),
        ({"type": "random", "max_peak": 11.0}, r"max_peak"),
        ({"type": "circle", "max_peak": 0.9}, r"unknown key\(s\) \['max_peak'\]"),
    ],
)
def test_a_bad_max_peak_is_refused_naming_it(path, match):
    with pytest.raises(ValueError, match=match):
        gym.make("WheeledPuma-Random-v0", dynamics="kinematic", path=path)

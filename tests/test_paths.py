"""Paths: analytic derivatives vs finite differences, spec round trips, the paper's formula, bad specs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mobman_env import TASKS
from mobman_env.paths import FIELD_RANGES, PATH_TYPES, path_from_spec, validate_spec

START = np.array([0.1, -0.2, 1.2])
SPECS = [dict(s, seed=5) if s["type"] == "random" else s for s in TASKS.values()] + [
    {"type": "circle", "radius": 0.2, "tilt": 0.3, "yaw": 0.7, "duration": 7.0},
    {"type": "line", "length": 1.0, "direction": [1.0, 2.0, 0.5], "duration": 5.0},
]


@pytest.mark.parametrize("spec", SPECS, ids=lambda s: s["type"])
def test_derivatives_match_finite_differences(spec):
    path = path_from_spec(spec, START)
    h = 1e-5
    for t in np.linspace(0.01, path.duration - 0.01, 17):
        v_fd = (path.position(t + h) - path.position(t - h)) / (2 * h)
        a_fd = (path.velocity(t + h) - path.velocity(t - h)) / (2 * h)
        np.testing.assert_allclose(path.velocity(t), v_fd, atol=1e-7)
        np.testing.assert_allclose(path.acceleration(t), a_fd, atol=1e-6)
        p, v = path.position_velocity(t)
        np.testing.assert_allclose(p, path.position(t), atol=1e-15)
        np.testing.assert_allclose(v, path.velocity(t), atol=1e-15)


@pytest.mark.parametrize("spec", SPECS, ids=lambda s: s["type"])
def test_rest_to_rest_and_round_trip(spec):
    path = path_from_spec(spec, START)
    np.testing.assert_allclose(path.position(0.0), START, atol=1e-12)
    assert np.linalg.norm(path.velocity(0.0)) < 1e-12 and np.linalg.norm(path.velocity(path.duration)) < 1e-12
    again = path_from_spec(path.to_spec(), START)
    assert again.to_spec() == path.to_spec()
    for t in np.linspace(0, path.duration, 9):
        np.testing.assert_allclose(again.position(t), path.position(t), atol=1e-12)
    assert set(path.to_spec()) == set(validate_spec(path.to_spec()))


def test_circle_is_the_papers_formula():
    path = path_from_spec(TASKS["WheeledPuma-Circle-v0"], START)
    l, T = 0.4, 20.0
    for t in np.linspace(0, T, 41):
        ph = 2 * math.pi * math.sin(0.5 * math.pi * t / T) ** 2
        expected = START + [
            l * math.cos(ph) - l,
            l * math.cos(math.pi / 6) * math.sin(ph),
            l * math.sin(math.pi / 6) * math.sin(ph),
        ]
        np.testing.assert_allclose(path.position(t), expected, atol=1e-12)
    pts = np.array([path.position(t) for t in np.linspace(0, T, 2001)])
    extent = pts.max(0) - pts.min(0)
    np.testing.assert_allclose(extent, [0.8, 0.8 * math.cos(math.pi / 6), 0.8 * math.sin(math.pi / 6)], atol=1e-4)


def test_lemniscate_and_random_sizes():
    lem = path_from_spec(TASKS["WheeledPuma-Lemniscate-v0"], START)
    pts = np.array([lem.position(t) for t in np.linspace(0, 20, 4001)])
    assert abs(np.ptp(pts[:, 0]) - 0.6) < 1e-3  # width along yaw = pi, i.e. along x
    rng = np.random.default_rng(0)
    for _ in range(5):
        rnd = path_from_spec({"type": "random"}, START, rng)
        pts = np.array([rnd.position(t) for t in np.linspace(0, 20, 2001)])
        assert np.all(np.ptp(pts, axis=0) <= 0.3 + 1e-6)
        assert np.ptp(pts, axis=0).max() > 0.1


@pytest.mark.parametrize(
    "spec, match",
    [
        ({"type": "spiral"}, "unknown path type 'spiral'; known: circle, line, lemniscate, random"),
        ({"type": "circle", "radius": -1}, "radius must be a finite number > 0"),
        ({"type": "circle", "radius": "big"}, "radius must be a finite number > 0 and <= 20, got 'big'"),
        ({"type": "circle", "radius": "0.4"}, "radius must be a finite number > 0 and <= 20, got '0.4'"),
        ({"type": "circle", "radius": True}, "radius must be a finite number > 0 and <= 20, got True"),
        (
            {"type": "circle", "tilt": 0.5 + 1j},
            r"tilt must be a finite number >= -6.28319 and <= 6.28319, got \(0.5\+1j\)",
        ),
        (
            {"type": "line", "length": 1e308},
            r"line path: length must be a finite number > 0 and <= 50, got 1e\+308 \(m\)",
        ),
        ({"type": "line", "direction": "x"}, "line path: direction must be 3 finite numbers .*, got 'x'"),
        ({"type": "line", "direction": [1, True, 0]}, "line path: direction must be 3 finite numbers"),
        ({"type": "random", "n_terms": 10**7}, "random path: n_terms must be an integer >= 1 and <= 20, got 10000000"),
        ({"type": "random", "n_terms": 3.0}, "random path: n_terms must be an integer >= 1 and <= 20, got 3.0"),
        ({"type": "random", "seed": True}, "random path: seed must be an integer >= 0"),
        ({"type": "circle", "raduis": 0.3}, r"unknown key\(s\) \['raduis'\]; accepted"),
        ({"type": "line", "direction": [0, 0, 0]}, "direction must be non-zero"),
        ({"type": "line", "direction": [1, 0]}, "direction must be 3 finite numbers"),
        ({"type": "random", "seed": -3}, "seed must be an integer >= 0"),
        (
            {"type": "circle", "duration": float("nan")},
            r"duration must be a finite number >= 0.01 and <= 3600, got nan \(s\)",
        ),
        ({"type": "circle", "duration": 3600.5}, r"duration must be a finite number >= 0.01 and <= 3600, got 3600.5"),
        ("circle", "must be a dict"),
    ],
)
def test_bad_specs_name_the_problem(spec, match):
    with pytest.raises(ValueError, match=match):
        path_from_spec(spec, START)


def test_random_spec_without_seed_needs_rng():
    with pytest.raises(ValueError, match="no 'seed'"):
        path_from_spec({"type": "random"}, START)
    # every listed type builds from its type alone (a random one draws its seed from the rng) at the start
    for kind in PATH_TYPES:
        path = path_from_spec({"type": kind}, START, np.random.default_rng(1))
        assert path.to_spec()["type"] == kind
        np.testing.assert_allclose(path.position(0.0), START, atol=1e-12)


@pytest.mark.parametrize("kind", PATH_TYPES)
def test_every_field_has_a_range_inclusive_at_its_ends(kind):
    """Each numeric field accepts its documented ends (the low end when closed) and refuses just beyond them,
    naming the range; the end values build a path whose positions are finite."""
    for key, accepted in FIELD_RANGES[kind].items():
        if accepted is None:  # the line's direction: 3 numbers, checked above
            continue
        step = 1 if accepted.integer else 1e-6 * max(1.0, abs(accepted.high))
        ends = [accepted.high] + ([] if accepted.open_low else [accepted.low])
        for v in ends:
            spec = {"type": kind, key: int(v) if accepted.integer else float(v)}
            if kind == "random" and key != "max_peak":  # max_peak draws from a generator, never with a seed
                spec.setdefault("seed", 1)
            path = path_from_spec(spec, START, np.random.default_rng(0))
            assert np.all(np.isfinite(path.position(0.5 * path.duration))), (key, v)
        beyond = [accepted.high + step, accepted.low if accepted.open_low else accepted.low - step]
        for v in beyond:
            with pytest.raises(ValueError, match=f"{kind} path: {key} must be "):
                validate_spec({"type": kind, key: int(v) if accepted.integer else float(v)})

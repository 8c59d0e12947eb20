"""Shared fixtures. Every env made here is closed by its fixture."""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
os.environ.setdefault("MPLBACKEND", "Agg")

import pytest

import mobman_env

#: a short task for fast tests: the paper's circle shape, 1 s
SHORT_CIRCLE = {"type": "circle", "radius": 0.1, "tilt": 0.5235987755982988, "yaw": 3.141592653589793, "duration": 1.0}


@pytest.fixture
def make_env():
    """Factory fixture: `make_env(**kwargs)` builds a WheeledPumaEnv and closes it after the test."""
    envs = []

    def _make(**kwargs):
        env = mobman_env.WheeledPumaEnv(**kwargs)
        envs.append(env)
        return env

    yield _make
    for env in envs:
        env.close()

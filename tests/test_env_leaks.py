"""No leaks: the true robot is reachable through the env's documented door `true_params` only.

A guard replaces the env class's `true_params` and `nominal_params` with properties that raise; then every
public attribute of the env (and, recursively, of the mobman objects, dicts and lists it holds) either goes
through that guard or holds no robot model and no generated URDF path. `sim` (the PyBullet body and the
kinematic state hold the true robot) must go through the guard too.
"""

from __future__ import annotations

import glob
import inspect
import os
import tempfile
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from conftest import SHORT_CIRCLE

from mobman_env import RobotParams, WheeledPumaEnv
from mobman_env.sim import URDF_DIR_PREFIX

DOORS = ("true_params", "nominal_params")


@pytest.fixture
def guard(monkeypatch):
    """Make the doors raise; returns the list of door names that were read."""
    touched: list[str] = []

    def door(name: str) -> property:
        def get(self):
            touched.append(name)
            raise AssertionError(f"read {name}")

        return property(get)

    for name in DOORS:
        monkeypatch.setattr(WheeledPumaEnv, name, door(name))
    return touched


def _walk(value: Any, where: str, seen: set, leaks: list, guarded: list, depth: int = 0) -> None:
    if id(value) in seen or depth > 6:
        return
    seen.add(id(value))
    if isinstance(value, RobotParams):
        leaks.append(where)
        return
    if isinstance(value, (str, os.PathLike)):
        if URDF_DIR_PREFIX in str(value):
            leaks.append(where)
        return
    if isinstance(value, dict):
        for k, v in value.items():
            _walk(v, f"{where}[{k!r}]", seen, leaks, guarded, depth + 1)
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _walk(v, f"{where}[{i}]", seen, leaks, guarded, depth + 1)
    elif type(value).__module__.startswith("mobman_env"):
        for name in dir(value):
            if name.startswith("_"):
                continue
            try:
                v = getattr(value, name)
            except AssertionError:  # went through the guard
                guarded.append(f"{where}.{name}")
                continue
            except AttributeError:  # not readable (e.g. Sim.params, which names the door instead)
                continue
            if inspect.isroutine(v):
                continue
            _walk(v, f"{where}.{name}", seen, leaks, guarded, depth + 1)


@pytest.mark.parametrize("dynamics", ["kinematic", "physics"])
def test_every_public_path_to_the_true_robot_goes_through_the_guard(guard, dynamics):
    env = gym.make("WheeledPuma-Circle-v0", dynamics=dynamics, path=SHORT_CIRCLE, render_mode="rgb_array")
    try:
        _, info = env.reset(seed=4)
        _, _, _, _, info2 = env.step(np.zeros(8, np.float32))
        env.render()
        leaks: list[str] = []
        guarded: list[str] = []
        _walk(env.unwrapped, "env", set(), leaks, guarded)
        _walk([info, info2], "info", set(), leaks, guarded)
        assert leaks == [], f"reachable without the guard: {leaks}"
        assert {"env.true_params", "env.nominal_params", "env.sim"} <= set(guarded), guarded
        with pytest.raises(AssertionError, match="read true_params"):
            env.get_wrapper_attr("sim")  # through the wrappers as well
        # the generated URDF is gone once loaded: nothing of it on disk to read
        mine = glob.glob(os.path.join(tempfile.gettempdir(), f"{URDF_DIR_PREFIX}{os.getpid()}-*", "*"))
        assert mine == []
    finally:
        env.close()


@pytest.mark.parametrize("kwargs", [{"dynamics": "physics"}, {"dynamics": "kinematic", "render_mode": "rgb_array"}])
def test_the_sim_keeps_the_robot_private(kwargs):
    env = WheeledPumaEnv(path=SHORT_CIRCLE, **kwargs)
    try:
        env.reset(seed=0)
        with pytest.raises(AttributeError, match=r"env.unwrapped.true_params"):
            env.sim.params  # noqa: B018
        # the documented doors work as before
        assert env.true_params != env.nominal_params and env.nominal_params == RobotParams.nominal()
    finally:
        env.close()

"""The engine's numerics contract (DESIGN "Release 0.3"): one kernel, compiled, BLAS-free.

* robot i of a vector env equals a single env reset with seed S + i, bit for bit, at N = 1, 7 and 64;
* the bits do not depend on the BLAS kernel (`OPENBLAS_CORETYPE` varied in subprocesses) and are those of the
  same source run as plain Python (`NUMBA_DISABLE_JIT=1`), for every robot in both modes;
* physics mode's end-effector and its velocity, computed by the engine from PyBullet's joint states and base
  pose, are PyBullet's own (`getLinkState` with forward kinematics and velocity) within 1e-9 m and m/s over
  whole episodes;
* the compile cache works from a read-only install (numba falls back to a user-wide cache folder).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pybullet
import pytest

import mobman_env
from mobman_env import engine as E

ROOT = Path(__file__).resolve().parents[1]
#: robot, task, dynamics, seed, steps, env kwargs: every robot, both modes, every option the kernel has
EPISODES = (
    ("WheeledPuma-Circle-v0", "kinematic", 10_000, 60, {}),
    ("WheeledUR5-Line-v0", "kinematic", 10_001, 60, {"wear_rate": 0.01, "obs_delay": 2}),
    (
        "WheeledPanda-Random-v0",
        "kinematic",
        10_002,
        60,
        {"obs_noise": 1e-3, "obs_noise_yaw": 1e-3, "actuator_tau": 0.05},
    ),
    ("WheeledRandomArm-Lemniscate-v0", "kinematic", 10_003, 60, {"obs_noise_joint_vel": 0.01}),
    ("WheeledPuma-Line-v0", "physics", 10_004, 40, {"actuator_tau": 0.05, "obs_noise_vel": 0.01}),
    ("WheeledPanda-Circle-v0", "physics", 10_005, 40, {}),
)


def _episode_digest(env_id: str, dynamics: str, seed: int, steps: int, kwargs: dict) -> str:
    """SHA-256 of every observation, reward, termination and float of `info` of one episode under fixed actions."""
    env = gym.make(env_id, dynamics=dynamics, **kwargs)
    h = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    actions = np.random.default_rng(seed).uniform(-1.2, 1.2, (steps, env.action_space.shape[0])).astype(np.float32)
    for a in actions:
        for v in obs.values():
            h.update(np.ascontiguousarray(v).tobytes())
        h.update(np.asarray(info["ee_pos_true"], float).tobytes())
        obs, reward, terminated, truncated, info = env.step(a)
        h.update(np.array([reward, info["tracking_error"], terminated, truncated], float).tobytes())
    env.close()
    return h.hexdigest()


_DIGESTS = textwrap.dedent(
    """
    import json, sys
    sys.path.insert(0, {tests!r})
    from test_engine import EPISODES, _episode_digest
    print(json.dumps([_episode_digest(*e) for e in EPISODES]))
    """
)


def _digests_in_subprocess(**env: str) -> list[str]:
    import json

    code = _DIGESTS.format(tests=str(Path(__file__).parent))
    proc = subprocess.run(
        [sys.executable, "-c", code],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def digests() -> list[str]:
    return [_episode_digest(*e) for e in EPISODES]


@pytest.mark.slow
def test_plain_python_gives_the_compiled_bits(digests):
    """The same source run as plain Python (`NUMBA_DISABLE_JIT=1`) gives the same bits, every robot, both modes."""
    assert _digests_in_subprocess(NUMBA_DISABLE_JIT="1") == digests


@pytest.mark.slow
@pytest.mark.parametrize("coretype", ["Haswell", "Sandybridge"])
def test_the_bits_do_not_depend_on_the_blas_kernel(digests, coretype):
    """OpenBLAS's kernel (`OPENBLAS_CORETYPE`, set only in the subprocess) changes nothing: the engine has no
    matrix product."""
    assert _digests_in_subprocess(OPENBLAS_CORETYPE=coretype) == digests


def _flat(obs: dict) -> np.ndarray:
    return np.concatenate([np.asarray(v).reshape(len(v) if np.ndim(v) == 2 else 1, -1) for v in obs.values()], axis=1)


@pytest.mark.parametrize("n", [1, 7, 64])
def test_robot_i_of_a_vector_env_is_the_single_env(n):
    """Whole episodes (with an autoreset inside) of every robot i at N = 1, 7, 64 equal the single env's, bit for
    bit, under noise, delay, lag and wear."""
    kwargs = {"obs_noise": 1e-3, "obs_noise_yaw": 2e-3, "obs_delay": 1, "actuator_tau": 0.03, "wear_rate": 0.01}
    path = {"type": "random", "size": 0.2, "n_terms": 4, "duration": 0.5}
    venv = gym.make_vec(
        "WheeledUR5-Random-v0",
        num_envs=n,
        vectorization_mode="vector_entry_point",
        dynamics="kinematic",
        path=path,
        **kwargs,
    )
    steps = 70  # one episode of 50 steps, the autoreset step, then 19 steps of the next episode
    actions = np.random.default_rng(n).uniform(-1.3, 1.3, (steps, n, 8)).astype(np.float32)
    obs, _ = venv.reset(seed=10_000)
    v_obs, v_rew = [_flat(obs)], []
    for a in actions:
        obs, rew, *_ = venv.step(a)
        v_obs.append(_flat(obs))
        v_rew.append(rew)
    for i in sorted({0, n // 2, n - 1}):
        env = gym.make("WheeledUR5-Random-v0", dynamics="kinematic", path=path, **kwargs)
        o, _ = env.reset(seed=10_000 + i)
        s_obs, s_rew = [_flat({k: v[None] for k, v in o.items()})[0]], []
        for a in actions[:, i]:
            o, r, te, tr, _ = env.step(a)
            s_obs.append(_flat({k: v[None] for k, v in o.items()})[0])
            s_rew.append(r)
            if te or tr:
                break
        k = len(s_rew)
        assert k == 50
        np.testing.assert_array_equal(np.array(v_obs)[: k + 1, i], np.array(s_obs))
        np.testing.assert_array_equal(np.array(v_rew)[:k, i], np.array(s_rew))
        # after the autoreset step, the next episode is the single env's reset() with its generator continuing
        o, _ = env.reset()
        np.testing.assert_array_equal(np.array(v_obs)[k + 1, i], _flat({kk: v[None] for kk, v in o.items()})[0])


@pytest.mark.parametrize("env_id", ["WheeledPuma-Lemniscate-v0", "WheeledPanda-Line-v0", "WheeledRandomArm-Circle-v0"])
def test_physics_end_effector_is_pybullets(env_id):
    """The engine's end-effector position and velocity from PyBullet's joint states and base pose equal
    `getLinkState(..., computeLinkVelocity=1, computeForwardKinematics=1)` within 1e-9 m and 1e-9 m/s over a whole
    (2 s) episode of random motion."""
    env = gym.make(env_id, path={"type": "circle", "radius": 0.3, "duration": 2.0}).unwrapped
    env.reset(seed=10_010)
    sim = env.sim
    rng = np.random.default_rng(0)
    worst_p = worst_v = 0.0
    n = 0
    while True:
        _, _, term, trunc, _ = env.step(rng.uniform(-0.6, 0.6, env.n_actuators).astype(np.float32))
        ls = pybullet.getLinkState(sim.body, sim.ee_id, 1, 1, physicsClientId=sim.client_id)
        s = env.state()
        worst_p = max(worst_p, float(np.abs(s.ee_pos - np.array(ls[0])).max()))
        worst_v = max(worst_v, float(np.abs(s.ee_vel - np.array(ls[6])).max()))
        n += 1
        if term or trunc:
            break
    env.close()
    assert n == 200
    assert worst_p < 1e-9, worst_p
    assert worst_v < 1e-9, worst_v


def test_the_layouts_add_up():
    """The `io` and `st` column layouts are contiguous and do not overlap (the kernels compute them in closed form)."""
    for m in (7, 8, 9):
        assert E.io_noise(m) == m
        assert E.io_phys(m) == E.io_noise(m) + E.n_sensor(m)
        assert E.io_out(m) == E.io_phys(m) + 2 * m + 13
        assert E.io_vals(m) == E.io_out(m) + E.O_U + m
        assert E.io_len(m) == E.io_vals(m) + E.n_sensor(m)
        assert E.obs_size(m) == len(np.concatenate([np.zeros(s.shape) for s in _obs_space(m).values()]))


def _obs_space(m: int) -> dict:
    robot = {8: "puma560", 9: "panda"}.get(m)
    if robot is None:
        return {k: np.zeros(v) for k, v in zip(mobman_env.OBS_KEYS, (3, 3, 2, 2, 1, m, m, 3, 3, 1))}
    return dict(mobman_env.WheeledPumaEnv(dynamics="kinematic", robot=robot).observation_space.spaces)


@pytest.mark.slow
def test_the_compile_cache_works_from_a_read_only_install(tmp_path):
    """An install whose package folder cannot be written: the kernels still load, and numba keeps their machine
    code in the user's cache folder (a second process loads it instead of compiling). For a user, the package's
    folders are made read-only; root writes through any mode bits, so there the folder's `__pycache__` is made a
    file, which no one can write into (the same failure numba meets in a read-only site-packages)."""
    site = tmp_path / "site"
    shutil.copytree(ROOT / "mobman_env", site / "mobman_env", ignore=shutil.ignore_patterns("__pycache__"))
    home = tmp_path / "home"
    home.mkdir()
    code = (
        "import time, numpy as np; t = time.perf_counter(); import mobman_env.engine as E; E.warm(); "
        "import gymnasium as gym, mobman_env; env = gym.make('WheeledPuma-Circle-v0', dynamics='kinematic'); "
        "env.reset(seed=0); env.step(np.zeros(8, np.float32)); print(E.__file__, time.perf_counter() - t)"
    )
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(PYTHONPATH=str(site), HOME=str(home), XDG_CACHE_HOME=str(home / ".cache"), PYTHONDONTWRITEBYTECODE="1")
    folders = [p for p in (site, *site.rglob("*")) if p.is_dir()]
    if os.geteuid() == 0:
        for p in folders:
            (p / "__pycache__").write_text("not a folder")
    else:
        for p in folders:
            p.chmod(0o555)

    def run() -> str:
        proc = subprocess.run(
            [sys.executable, "-c", code], env=env, cwd=home, capture_output=True, text=True, timeout=600, check=False
        )
        assert proc.returncode == 0, proc.stderr[-3000:]
        return proc.stdout

    try:
        assert str(site) in run()
        assert not list(site.rglob("*.nbi")), "numba wrote into the read-only package"
        assert list(home.rglob("*.nbi")), "no user-wide numba cache was written"
        stamp = {p: p.stat().st_mtime_ns for p in home.rglob("*.nbc")}
        run()
        assert {p: p.stat().st_mtime_ns for p in home.rglob("*.nbc")} == stamp, "the second process compiled again"
    finally:
        for p in folders:
            p.chmod(0o755)

"""`WheeledPumaVectorEnv`: N kinematic-mode robots stepped by one call of the engine, a native
`gymnasium.vector.VectorEnv`.

    envs = gym.make_vec("mobman_env:WheeledPuma-Circle-v0", num_envs=1024,
                        vectorization_mode="vector_entry_point", dynamics="kinematic")

Robot i is a `WheeledPumaEnv(dynamics="kinematic", ...)` reset with seed S + i (`reset(seed=S)`; a list of N
seeds sets them one by one): it owns its own `numpy.random.Generator`, drawn in the single env's order (the arm for
`robot="random"`, the true robot, the random path's seed, sensor noise), and its state lives in row i of the same
`mobman_env.batch.RobotBatch` the single env holds one row of, stepped by the same kernel
(`mobman_env.engine.kinematic`, scalar code per robot). So its observations, rewards, terminations,
truncations and `info` equal the single env's bit for bit by construction (`tests/test_vector_env.py` checks it
at N = 1, 7 and 64).

Batching, as Gymnasium's `SyncVectorEnv` does it: the observation is a dict of (N, k) float32 arrays (views into one
(N, 18 + 2 (n + 2)) array made fresh each step); rewards (N,) float64; terminations and truncations (N,) bool;
`info` holds each key as an array of N entries with a boolean mask `_key` (nested dicts such as `reward_terms`
recursively), `ee_pos_true` as (N, 3). Autoreset: `autoreset_mode` = `AutoresetMode.NEXT_STEP` (Gymnasium 1.x's
default, in `metadata["autoreset_mode"]`): the step after robot i's episode ended resets it (its action ignored,
reward 0, not terminated nor truncated, the reset's `info` keys in that row) with no options and its generator
continuing, as a single env's `reset()`. `AutoresetMode.SAME_STEP` resets at once and puts the last observation and
info in `info["final_obs"]` / `info["final_info"]` (what the SB3 adapter, `train.vec_env`, uses).

Reset options apply to every robot reset by that call (as `SyncVectorEnv` passes them to each env); autoresets use
the constructor values, or, with `episode_sampler=f` (a constructor argument of this class only), the options
`f(rng)` draws for each row's episode from the row's own generator, before the episode's draws (a reset without
options uses it too): a training distribution of paths and conditions, one draw per episode and row
(`train.dev_env`). A sampler's options are checked as each row draws them. Every argument (seeds, options, actions) is checked for every row before any row's state
changes: a refused call leaves the vector env as it was. Rendering is not offered (render_mode must be None):
render one robot with a single env.

Registered as every id's `vector_entry_point`, so `gym.make_vec(id, N)` without a mode uses it too (Gymnasium
then refuses `vector_kwargs` and `wrappers`: pass `vectorization_mode="sync"` for its `SyncVectorEnv` with them).
Physics mode: `make_vector_env(num_envs, dynamics="physics", ...)` (the registered vector entry point) returns a
`PhysicsVectorEnv`, a `gymnasium.vector.SyncVectorEnv` of single envs (a PyBullet world per robot: contacts are
not batched) that checks every row's action before stepping any.

Robots: every robot of the catalogue and the random family (`robot="random"`: each reset draws row i's arm from
its generator, the arms differ row by row; the draw and its kinematic ceiling check cost about 0.2 s per
candidate, `mobman_env.robots.sources`). A step's results are read from the batch's `io` by their `info` names
(`RobotBatch.named("io")`, the columns of `mobman_env.engine.io_columns`). Imports gymnasium, numpy and
`mobman_env` modules only.
"""

from __future__ import annotations

from typing import Any, cast

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from mobman_env import engine as E
from mobman_env import env as single
from mobman_env.batch import RobotBatch
from mobman_env.params import RobotParams

AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
#: the most robots one vector env holds: its arrays take about 1.5 KiB per robot (1.5 GiB at this bound)
MAX_NUM_ENVS = 1_000_000


def make_vector_env(num_envs: int = 1, dynamics: str = "physics", **kwargs: Any) -> gym.vector.VectorEnv:
    """The registered vector entry point: the native `WheeledPumaVectorEnv` in kinematic mode, a
    `PhysicsVectorEnv` (a checked `SyncVectorEnv` of `WheeledPumaEnv`s) in physics mode (`autoreset_mode` is
    passed to either)."""
    if dynamics == "kinematic":
        return WheeledPumaVectorEnv(num_envs, **kwargs)
    if dynamics not in single.DYNAMICS_MODES:
        raise ValueError(f"unknown dynamics mode {dynamics!r}; accepted: {', '.join(single.DYNAMICS_MODES)}")
    mode = kwargs.pop("autoreset_mode", AutoresetMode.NEXT_STEP)
    kwargs.pop("max_episode_steps", None)
    n = _num_envs(num_envs)
    single.WheeledPumaEnv(dynamics=dynamics, **kwargs).close()  # the arguments checked once, before N worlds
    return PhysicsVectorEnv(
        [lambda: single.WheeledPumaEnv(dynamics=dynamics, **kwargs) for _ in range(n)], autoreset_mode=mode
    )


def _num_envs(num_envs: Any) -> int:
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or not 1 <= num_envs <= MAX_NUM_ENVS:
        raise ValueError(
            f"num_envs must be an integer in [1, {MAX_NUM_ENVS:,}], got {num_envs!r} (each robot holds about 1.5 KiB "
            "of arrays; for more robots, step several vector envs)"
        )
    return int(num_envs)


def check_seeds(seed: Any, n: int) -> list[int | None]:
    """The N seeds of a vector reset (`None`, one int S: S + i, or a list of N ints or None), checked before
    anything is reseeded."""
    hint = f"reset(seed=...) takes None, one integer S >= 0 (robot i gets S + i) or a list of {n} integers >= 0 or None"
    if seed is None:
        return [None] * n
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_)):
        if seed < 0:
            raise ValueError(f"seed must be >= 0, got {seed!r}; {hint}")
        return [int(seed) + i for i in range(n)]
    if isinstance(seed, (str, bytes, float, bool, np.bool_, np.floating)) or not hasattr(seed, "__len__"):
        raise ValueError(f"seed {seed!r} is not accepted; {hint}")
    seeds = list(np.asarray(seed, dtype=object).tolist() if isinstance(seed, np.ndarray) else seed)
    if len(seeds) != n:
        raise ValueError(f"reset(seed=...) got {len(seeds)} seeds for {n} robots; {hint}")
    for i, s in enumerate(seeds):
        if s is None:
            continue
        if isinstance(s, (bool, np.bool_)) or not isinstance(s, (int, np.integer)) or s < 0:
            raise ValueError(f"seed[{i}] = {s!r} is not accepted (robot {i}); {hint}")
    return [None if s is None else int(s) for s in seeds]


class WheeledPumaVectorEnv(gym.vector.VectorEnv):
    """N kinematic-mode `WheeledPumaEnv`s stepped together (see the module docstring).

    Args:
        num_envs: N, the number of robots, in [1, `MAX_NUM_ENVS`].
        autoreset_mode: `AutoresetMode.NEXT_STEP` (default) or `AutoresetMode.SAME_STEP`.
        **kwargs: the arguments of `WheeledPumaEnv` (validated by it), with `dynamics` "kinematic" and
            `render_mode` None.
    """

    def __init__(self, num_envs: int = 1, autoreset_mode: Any = AutoresetMode.NEXT_STEP, **kwargs: Any):
        n = _num_envs(num_envs)
        mode = AutoresetMode(autoreset_mode) if isinstance(autoreset_mode, str) else autoreset_mode
        if mode not in AUTORESET_MODES:
            raise ValueError(
                f"autoreset_mode {autoreset_mode!r} is not supported; accepted: {[m.value for m in AUTORESET_MODES]}"
            )
        kwargs.pop("max_episode_steps", None)  # make_vec passes the spec's
        sampler = kwargs.pop("episode_sampler", None)
        if sampler is not None and not callable(sampler):
            raise ValueError(
                f"episode_sampler must be a callable (row's numpy Generator) -> reset options dict, got {sampler!r}"
            )
        if kwargs.get("dynamics", "kinematic") != "kinematic":
            raise ValueError(
                f"WheeledPumaVectorEnv steps kinematic mode only, got dynamics={kwargs['dynamics']!r}; use "
                "mobman_env.vector.make_vector_env (or gym.make_vec) for a SyncVectorEnv in physics mode"
            )
        if kwargs.get("render_mode") is not None:
            raise ValueError(
                f"WheeledPumaVectorEnv does not render (render_mode={kwargs['render_mode']!r}); use render_mode=None "
                "and render one robot with a single WheeledPumaEnv"
            )
        kwargs["dynamics"] = "kinematic"
        # the template validates every argument as the single env does and holds the resolved values (kinematic
        # mode without a render mode opens no PyBullet client)
        self._template = tpl = single.WheeledPumaEnv(**kwargs)
        self.num_envs = n
        self.autoreset_mode = mode
        self.metadata = {"autoreset_mode": mode, "render_modes": [], "render_fps": tpl.control_freq}
        self.render_mode = None
        self.single_observation_space = tpl.observation_space
        self.single_action_space = tpl.action_space
        self.observation_space = batch_space(tpl.observation_space, n)
        self.action_space = batch_space(tpl.action_space, n)
        self._m = tpl.n_actuators
        self._batch = RobotBatch(n, self._m - 2, tpl.dt, tpl.reward_weights, tpl.error_bound)
        self._nominals: list[RobotParams] = [tpl.nominal_params] * n
        self._hashes = np.full(n, "", dtype=object)  # each robot's true robot's hash (info), set at its resets
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._sampler = sampler
        self._autoreset = np.zeros(n, dtype=bool)
        self._started = False
        self._closed = False

    # --- the documented doors (as the single env's) ------------------------------------------------------
    @property
    def nominal_params(self) -> RobotParams:
        """The catalogue robot: what a model-based controller may know (the same for every robot of a fixed arm;
        for `robot="random"` the one before the first reset: see `nominal_params_of`)."""
        return self._template.nominal_params

    def nominal_params_of(self, i: int) -> RobotParams:
        """Robot i's nominal robot (its episode's drawn design for `robot="random"`)."""
        return self._nominals[i]

    def true_params(self, i: int) -> RobotParams:
        """Robot i's true robot at its current time (for oracles and tests only)."""
        if self._batch.params0[i] is None:
            return self._nominals[i]
        return self._batch.true_params(i)

    def true_actuator_tau(self, i: int) -> float:
        """Robot i's actuator lag time constant this episode, s (for oracles and tests only; see the single env's
        `true_actuator_tau`)."""
        if not self._started:
            return self._template.true_actuator_tau
        return float(self._batch.prm[i, E.PRM.actuator_tau])

    @property
    def dt(self) -> float:
        """The control period, s."""
        return self._template.dt

    @property
    def action_scale(self) -> np.ndarray:
        """Speed limits of the n + 2 actuators, rad/s (the same for every robot, as the single env's)."""
        return self._template.action_scale

    # --- gym API -------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        self._check_open()
        n = self.num_envs
        seeds = check_seeds(seed, n)
        tpl = self._template
        settings = None  # every row draws its own episode options (`episode_sampler`)
        if options is not None or self._sampler is None:
            settings = tpl._episode_settings(options, tpl.nominal_params, "kinematic")  # checked before any reseed
        for i, s in enumerate(seeds):
            if s is not None or self._rngs[i] is None:
                self._rngs[i], _ = seeding.np_random(s)
        flat = self._batch.new_obs()
        infos = self._reset_rows(self._batch.rows, settings, flat, {})
        self._autoreset[:] = False
        self._started = True
        return self._obs_dict(flat), infos

    def step(self, actions: Any):
        self._check_open()
        if not self._started:
            raise RuntimeError("call reset() before step()")
        b, n, m = self._batch, self.num_envs, self._m
        a = np.asarray(actions)
        if a.dtype.kind not in "fiu":
            raise ValueError(f"actions must be real numbers (a float array of shape ({n}, {m})), got {a.dtype}")
        if a.shape != (n, m):
            raise ValueError(
                f"actions must have shape ({n}, {m}) (per robot: {m - 2} arm joints, left wheel, right wheel), "
                f"got shape {a.shape}"
            )
        next_step = self.autoreset_mode == AutoresetMode.NEXT_STEP
        resetting = self._autoreset if next_step else np.zeros(n, dtype=bool)
        rows = b.rows if not resetting.any() else np.flatnonzero(~resetting)
        if not np.isfinite(a).all():  # before any robot's noise is drawn or state moves
            bad = int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0])
            raise ValueError(
                f"actions must be finite; NaN or inf in robot {bad}: {a[bad].tolist()} (no robot was stepped)"
            )
        b.io[:, b.IO.action : b.IO.action + m] = a
        b.draw_noise(rows, self._rngs)
        flat = b.new_obs()
        b.step_kinematic(rows, flat)
        out = b.named("io")  # the results by their `info` names (`engine.io_columns`)
        rewards = out["reward"].copy()
        terminated = out["terminated"] != 0.0
        truncated = out["truncated"] != 0.0
        moving = ~resetting
        infos = self._step_info(out, moving)
        if resetting.any():
            rewards[resetting] = 0.0
            terminated[resetting] = truncated[resetting] = False
        if next_step:
            if resetting.any():
                infos = self._reset_rows(np.flatnonzero(resetting), None, flat, infos)
            self._autoreset = terminated | truncated
        else:  # SAME_STEP
            done = terminated | truncated
            if done.any():
                idx = np.flatnonzero(done)
                final_obs = np.full(n, None, dtype=object)
                final_info = np.full(n, None, dtype=object)
                for i in idx:
                    final_obs[i] = {k: flat[i, sl].copy() for k, sl in self._template._obs_slices}
                    final_info[i] = _row_info(infos, int(i))
                infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
                infos["final_info"], infos["_final_info"] = final_info, done.copy()
                infos = self._reset_rows(idx, None, flat, infos)
        return self._obs_dict(flat), rewards, terminated, truncated, infos

    def close_extras(self, **kwargs: Any) -> None:
        self._closed = True
        self._template.close()

    # --- internals -----------------------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("the vector env is closed; make a new one with gym.make_vec(...)")

    def _obs_dict(self, flat: np.ndarray) -> dict[str, np.ndarray]:
        return {k: flat[:, sl] for k, sl in self._template._obs_slices}

    def _step_info(self, out: np.ndarray, moving: np.ndarray) -> dict[str, Any]:
        """The batched info of a step from the batch's named `io` (rows `moving`; the others get masks False)."""
        info = {
            "ee_pos_true": out["ee_pos_true"].copy(),
            "tracking_error": out["tracking_error"].copy(),
            "reward_terms": {"tracking": out["tracking"].copy(), "effort": out["effort"].copy()},
            "action_clipped": out["action_clipped"] != 0.0,
            "n_clipped": out["n_clipped"].astype(int),
            "joint_limit_hits": out["joint_limit_hits"].astype(int),
            "tipped_over": np.zeros(self.num_envs, dtype=bool),
            "true_params_hash": self._hashes.copy(),
        }
        return _masked(info, moving)

    def _sampled_settings(self, i: int) -> tuple:
        """Row i's episode settings from the reset options `episode_sampler` draws from its generator (before the
        episode's own draws, so the row's stream stays one fixed sequence)."""
        tpl = self._template
        assert self._sampler is not None and self._rngs[i] is not None
        return tpl._episode_settings(self._sampler(self._rngs[i]), tpl.nominal_params, "kinematic")

    def _reset_rows(self, rows: np.ndarray, settings: tuple | None, flat: np.ndarray, infos: dict) -> dict:
        """Start new episodes in `rows` as each single env's reset (its generator as it stands); their
        observations go into `flat`, their reset info into `infos`."""
        tpl, b = self._template, self._batch
        if settings is None and self._sampler is None:
            settings = tpl._episode_settings(None, tpl.nominal_params, "kinematic")
        specs, poses, starts = [], [], []
        for i in rows.tolist():
            spec, q0, pose, cond = settings or self._sampled_settings(i)
            self._nominals[i], q = b.begin_episode(i, self._rngs[i], tpl._source, tpl.nominal_params, q0, pose, cond)
            specs.append(spec)
            poses.append(pose)
            starts.append(q)
        ee = b.ee_kinematic(rows)
        for j, i in enumerate(rows.tolist()):
            b.set_path(i, specs[j], ee[j], self._rngs[i], tpl.control_freq)
        b.draw_noise(rows, self._rngs)
        b.observe_kinematic(rows, flat)
        self._hashes[rows] = [b.hashes[i] for i in rows.tolist()]
        for j, i in enumerate(rows.tolist()):
            info = {
                "task": b.task(i, ee[j], starts[j], poses[j]),
                "true_params_hash": b.hashes[i],
                "ee_pos_true": ee[j].copy(),
                "tracking_error": 0.0,
                "n_clipped": 0,
                "joint_limit_hits": 0,
            }
            infos = self._add_info(infos, info, i)
        return infos


class PhysicsVectorEnv(gym.vector.SyncVectorEnv):
    """Gymnasium's `SyncVectorEnv` of physics-mode `WheeledPumaEnv`s that checks every row's action (real numbers,
    the shape, finite) before it steps any robot, naming the row, so a refused step leaves every world as it was.
    It offers the vector env's doors too: `dt`, `action_scale`, `nominal_params`, `true_params(i)`."""

    def step(self, actions: Any):
        a = np.asarray(actions)
        n = self.num_envs
        m = self.single_action_space.shape[0]  # type: ignore[index]
        if a.dtype.kind not in "fiu" or a.shape != (n, m):
            raise ValueError(
                f"actions must be real numbers of shape ({n}, {m}) (per robot: {m - 2} arm joints, left wheel, right "
                f"wheel), got dtype {a.dtype}, shape {a.shape}"
            )
        bad = np.flatnonzero(~np.isfinite(a.astype(float)).all(axis=1))
        if bad.size:
            raise ValueError(
                f"actions must be finite; NaN or inf in robot {int(bad[0])}: {a[bad[0]].tolist()} (no robot was stepped)"
            )
        return super().step(actions)

    def _robot(self, i: int) -> single.WheeledPumaEnv:
        return cast(single.WheeledPumaEnv, self.envs[i].unwrapped)

    @property
    def dt(self) -> float:
        return float(self._robot(0).dt)

    @property
    def action_scale(self) -> np.ndarray:
        return np.asarray(self._robot(0).action_scale, dtype=float)

    @property
    def nominal_params(self) -> RobotParams:
        return self._robot(0).nominal_params

    def nominal_params_of(self, i: int) -> RobotParams:
        return self._robot(i).nominal_params

    def true_params(self, i: int) -> RobotParams:
        return self._robot(i).true_params

    def true_actuator_tau(self, i: int) -> float:
        return self._robot(i).true_actuator_tau


def _masked(info: dict[str, Any], mask: np.ndarray) -> dict[str, Any]:
    """Batched info arrays with Gymnasium's masks: `_key` is `mask` (the rows the values belong to); the other
    rows hold zeros (None in object arrays), as `SyncVectorEnv` leaves them."""
    out: dict[str, Any] = {}
    full = bool(mask.all())
    for key, value in info.items():
        if isinstance(value, dict):
            out[key] = _masked(value, mask)
        else:
            if not full:
                value[~mask] = None if value.dtype == object else 0
            out[key] = value
        out["_" + key] = mask.copy()
    return out


def _row_info(infos: dict[str, Any], i: int) -> dict[str, Any]:
    """Row i of batched info (the keys whose mask is set), as the single env's info dict."""
    row: dict[str, Any] = {}
    for key, value in infos.items():
        if key.startswith("_"):
            continue
        if isinstance(value, dict):
            row[key] = _row_info(value, i)
        elif infos.get("_" + key, np.zeros(i + 1, dtype=bool))[i]:
            v = value[i]
            row[key] = v.item() if isinstance(v, np.generic) else v
    return row

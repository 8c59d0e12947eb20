"""`WheeledPumaVectorEnv`: N kinematic-mode robots stepped in one numpy pass, a native `gymnasium.vector.VectorEnv`.

    envs = gym.make_vec("mobman_env:WheeledPuma-Circle-v0", num_envs=1024,
                        vectorization_mode="vector_entry_point", dynamics="kinematic")

Robot i is a `WheeledPumaEnv(dynamics="kinematic", ...)` reset with seed S + i (`reset(seed=S)`; a list of N
seeds sets them one by one): it owns its own `numpy.random.Generator`, drawn in the single env's order (true robot,
random path seed, sensor noise), and every floating-point operation of its step is the single env's, in the same
order (`mobman_env.vector_kinematics`), so its observations, rewards, terminations, truncations and the metric
fields of `info` are equal to the single env's bit for bit (`tests/test_vector_env.py`: whole episodes of the 4
tasks, several seeds and every env option).

Batching, as Gymnasium's `SyncVectorEnv` does it: the observation is a dict of (N, k) float32 arrays (views into one
(N, 33) array made fresh each step); rewards (N,) float64; terminations and truncations (N,) bool; `info` holds
each key as an array of N entries with a boolean mask `_key` (nested dicts such as `reward_terms` recursively),
`ee_pos_true` as (N, 3). Autoreset: `autoreset_mode` = `AutoresetMode.NEXT_STEP` (Gymnasium 1.x's default, in
`metadata["autoreset_mode"]`): the step after robot i's episode ended resets it (its action ignored, reward 0,
not terminated nor truncated, the reset's `info` keys in that row) with no options and its generator continuing,
as a single env's `reset()`. `AutoresetMode.SAME_STEP` resets at once and puts the last observation and info in
`info["final_obs"]` / `info["final_info"]` (what the SB3 adapter, `policies.sb3_vec_env`, uses).

Reset options apply to every robot reset by that call (as `SyncVectorEnv` passes them to each env); autoresets use
the constructor values. Rendering is not offered (render_mode must be None): render one robot with a single env.

Registered as every id's `vector_entry_point`, so `gym.make_vec(id, N)` without a mode uses it too (Gymnasium
then refuses `vector_kwargs` and `wrappers`: pass `vectorization_mode="sync"` for its `SyncVectorEnv` with them).
Physics mode: `make_vector_env(num_envs, dynamics="physics", ...)` (the registered vector entry point) returns a
`gymnasium.vector.SyncVectorEnv` of single envs: a PyBullet world per robot, contacts cannot be batched in numpy.

Robots: any fixed arm of the catalogue (`robot` "puma560", "ur5", "panda": n joints, standard or modified DH,
theta offsets, n + 2 actuators, all sized from the robot description) runs natively, bit-identical to its single
env (tested over episodes of every task for the UR5 and the Panda, wear, noise and delay included). The PUMA ids
keep release 0.1's numbers. `robot="random"` (`SYNC_ROBOTS`) falls back, in kinematic mode too, to a
`SyncVectorEnv` of single envs: each reset draws a new arm (its own DH twists, limits, start) and checks it with
the kinematic ceiling (about 0.2 s per candidate and 3.9 candidates per arm, `mobman_env.robots.sources`),
more than a whole 20 s episode's kinematic steps cost (about 90 us each), so batching the steps would save little; the native class refuses
it with that fix. (The delay holds every reading entry, `sensors.sensor_count` of the robot's actuators: 27 for
the PUMA, 29 for the Panda, as in the single env.)

Speed (`mobman-eval speed`): the robot-steps per second at N = 1, 64, 1024 are measured there; sensor noise loops
over the robots' generators (one draw per robot and step), the rest is one pass. Imports gymnasium, numpy and
`mobman_env` modules only.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from mobman_env import env as single
from mobman_env import vector_kinematics as VK
from mobman_env.params import RobotParams
from mobman_env.paths import path_from_spec
from mobman_env.sensors import sensor_count

AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
#: the per-robot lengths of the kinematic model that wear scales (a and d are (N, n) arrays, the rest (N,))
_WORN = ("a", "d", "tool", "wheel_radius", "half_track", "mount_offset")
#: and the constant one
_LENGTHS = (*_WORN, "shoulder_height")
#: the robots whose vector env is a SyncVectorEnv of single envs in kinematic mode too (see the module docstring)
SYNC_ROBOTS = ("random",)


def make_vector_env(num_envs: int = 1, dynamics: str = "physics", **kwargs: Any) -> gym.vector.VectorEnv:
    """The registered vector entry point: the native `WheeledPumaVectorEnv` in kinematic mode, a
    `SyncVectorEnv` of `WheeledPumaEnv`s in physics mode and for the robots of `SYNC_ROBOTS` (`autoreset_mode` is
    passed to either)."""
    if dynamics == "kinematic" and kwargs.get("robot", "puma560") not in SYNC_ROBOTS:
        return WheeledPumaVectorEnv(num_envs, **kwargs)
    if dynamics not in single.DYNAMICS_MODES:
        raise ValueError(f"unknown dynamics mode {dynamics!r}; accepted: {', '.join(single.DYNAMICS_MODES)}")
    mode = kwargs.pop("autoreset_mode", AutoresetMode.NEXT_STEP)
    kwargs.pop("max_episode_steps", None)
    return gym.vector.SyncVectorEnv(
        [lambda: single.WheeledPumaEnv(dynamics=dynamics, **kwargs) for _ in range(_num_envs(num_envs))],
        autoreset_mode=mode,
    )


def _num_envs(num_envs: Any) -> int:
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
    return int(num_envs)


class _Episodes:
    """The per-robot episode state of N robots, as arrays (row i: robot i)."""

    def __init__(self, n: int, n_joints: int):
        self.q = np.zeros((n, n_joints + 2))
        self.pose = np.zeros((n, 3))
        self.u = np.zeros((n, n_joints + 2))
        self.cos_yaw = np.zeros(n)
        self.sin_yaw = np.zeros(n)
        shapes = {k: (n, n_joints) if k in ("a", "d") else (n,) for k in _LENGTHS}
        self.lengths0 = {k: np.zeros(shapes[k]) for k in _LENGTHS}
        self.lengths = {k: np.zeros(shapes[k]) for k in _LENGTHS}
        self.params0: list[Any] = [None] * n  # each robot's true robot at t = 0
        self.wear = np.zeros(n)
        self.noise = np.zeros((n, 3))  # obs_noise, obs_noise_vel, obs_noise_joint_vel
        self.delay = np.zeros(n, dtype=int)
        self.steps = np.zeros(n, dtype=int)
        self.n_steps = np.ones(n, dtype=int)
        self.n_clipped = np.zeros(n, dtype=int)
        self.limit_hits = np.zeros(n, dtype=int)
        self.start = np.zeros((n, 3))
        self.paths: list[Any] = [None] * n
        self.hashes = np.full(n, "", dtype=object)
        self.n_sensor = sensor_count(n_joints + 2)
        self.history = np.zeros((n, 1, self.n_sensor), dtype=np.float32)  # delay ring buffers


class WheeledPumaVectorEnv(gym.vector.VectorEnv):
    """N kinematic-mode `WheeledPumaEnv`s stepped together (see the module docstring).

    Args:
        num_envs: N, the number of robots (>= 1).
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
        kwargs.pop("max_episode_steps", None)  # make_vec passes the spec's (None for every mobman id)
        if kwargs.get("dynamics", "kinematic") != "kinematic":
            raise ValueError(
                f"WheeledPumaVectorEnv steps kinematic mode only, got dynamics={kwargs['dynamics']!r}; use "
                "mobman_env.vector.make_vector_env (or gym.make_vec) for a SyncVectorEnv in physics mode"
            )
        if kwargs.get("robot", "puma560") in SYNC_ROBOTS:
            raise ValueError(
                f"WheeledPumaVectorEnv steps fixed arms only, got robot={kwargs['robot']!r} (a new arm per reset); use "
                "mobman_env.vector.make_vector_env (or gym.make_vec) for a SyncVectorEnv of single envs"
            )
        if kwargs.get("render_mode") is not None:
            raise ValueError(
                f"WheeledPumaVectorEnv does not render (render_mode={kwargs['render_mode']!r}); use render_mode=None "
                "and render one robot with a single WheeledPumaEnv"
            )
        kwargs["dynamics"] = "kinematic"
        # the template validates every argument as the single env does and holds the resolved values
        self._template = tpl = single.WheeledPumaEnv(**kwargs)
        tpl.sim.close()  # its PyBullet client is never used: nothing here renders
        self.num_envs = n
        self.autoreset_mode = mode
        self.metadata = {"autoreset_mode": mode, "render_modes": [], "render_fps": tpl.control_freq}
        self.render_mode = None
        self.single_observation_space = tpl.observation_space
        self.single_action_space = tpl.action_space
        self.observation_space = batch_space(tpl.observation_space, n)
        self.action_space = batch_space(tpl.action_space, n)
        self._nominal = tpl.nominal_params
        self._n = nj = self._nominal.n_joints
        _, _, self._ca, self._sa = self._nominal.dh_constants
        self._offset = self._nominal.theta_offset
        self._modified = self._nominal.arm.modified
        self._lower = np.array(self._nominal.joint_lower)
        self._upper = np.array(self._nominal.joint_upper)
        self._scale = tpl.action_scale
        self._dt = tpl.dt
        self._w_track = tpl.reward_weights["tracking"]
        self._w_effort = tpl.reward_weights["effort"]
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._ep = _Episodes(n, nj)
        self._groups: list[tuple[Any, np.ndarray]] | None = None
        self._autoreset = np.zeros(n, dtype=bool)
        self._started = False
        self._closed = False

    # --- the documented doors (as the single env's) ------------------------------------------------------
    @property
    def nominal_params(self) -> RobotParams:
        """The catalogue robot: what a model-based controller may know (the same for every robot)."""
        return self._nominal

    def true_params(self, i: int) -> RobotParams:
        """Robot i's true robot at its current time (for oracles and tests only)."""
        ep = self._ep
        p0 = ep.params0[i]
        if p0 is None:
            return self._nominal
        if ep.wear[i] == 0.0:
            return p0
        return p0.scaled(1.0 + ep.wear[i] * (ep.steps[i] * self._dt))

    @property
    def dt(self) -> float:
        """The control period, s."""
        return self._dt

    @property
    def action_scale(self) -> np.ndarray:
        """Speed limits of the n + 2 actuators, rad/s (the same for every robot, as the single env's)."""
        return self._scale

    # --- gym API -------------------------------------------------------------------------------------------
    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        self._check_open()
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)  # type: ignore[arg-type]
            if len(seeds) != n:
                raise ValueError(f"reset(seed=...) needs one int, None or a list of {n} seeds, got {len(seeds)}")
        for i, s in enumerate(seeds):
            if isinstance(s, bool):
                raise ValueError(f"seed must be None or an integer >= 0, got {s!r}")
            if s is not None or self._rngs[i] is None:
                self._rngs[i], _ = seeding.np_random(s)
        rows = np.arange(n)
        obs_flat, infos = self._reset_rows(rows, options)
        self._autoreset[:] = False
        self._started = True
        return self._obs_dict(obs_flat), infos

    def step(self, actions: Any):
        self._check_open()
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = self._actions(actions)
        n = self.num_envs
        rewards = np.zeros(n)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        infos: dict[str, Any] = {}
        resetting = self._autoreset if self.autoreset_mode == AutoresetMode.NEXT_STEP else np.zeros(n, dtype=bool)
        moving = ~resetting
        flat = np.empty((n, len(self._template._obs_low)), dtype=np.float32)
        if moving.all():
            rows = None
        else:
            rows = np.flatnonzero(moving)
        if rows is None or rows.size:
            sel = slice(None) if rows is None else rows
            r, te, tr, f, info = self._step_rows(sel, a if rows is None else a[rows])
            rewards[sel], terminated[sel], truncated[sel], flat[sel] = r, te, tr, f
            infos = _scatter_info(info, moving, n)
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            if resetting.any():
                idx = np.flatnonzero(resetting)
                f, infos = self._reset_rows(idx, None, infos)
                flat[idx] = f
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
                f, infos = self._reset_rows(idx, None, infos)
                flat[idx] = f
        return self._obs_dict(flat), rewards, terminated, truncated, infos

    def close_extras(self, **kwargs: Any) -> None:
        self._closed = True
        self._template.close()

    # --- internals -----------------------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("the vector env is closed; make a new one with gym.make_vec(...)")

    def _actions(self, actions: Any) -> np.ndarray:
        a = np.asarray(actions)
        k = self._n + 2
        if a.dtype.kind not in "fiu":
            raise ValueError(
                f"actions must be real numbers (a float array of shape ({self.num_envs}, {k})), got {a.dtype}"
            )
        a = a.astype(np.float64, copy=False)
        if a.shape != (self.num_envs, k):
            raise ValueError(
                f"actions must have shape ({self.num_envs}, {k}) (per robot: {self._n} arm joints, left wheel, "
                f"right wheel), got shape {a.shape}"
            )
        bad = ~np.isfinite(a)
        if bad.any():
            raise ValueError(f"actions must be finite; NaN or inf in robot(s) {np.flatnonzero(bad.any(1)).tolist()}")
        return a

    def _obs_dict(self, flat: np.ndarray) -> dict[str, np.ndarray]:
        return {k: flat[:, sl] for k, sl in self._template._obs_slices}

    def _state(self, sel: Any) -> tuple[np.ndarray, ...]:
        """Noise-free sensor quantities of the rows `sel`: ee (m, 3), ee_vel, pc (2), pc_vel."""
        ep = self._ep
        lengths = {k: v[sel] for k, v in ep.lengths.items()}
        pose, u = ep.pose[sel], ep.u[sel]
        th = ep.q[sel, : self._n]
        if self._offset is not None:  # as the single env: q + offset only for an arm with offsets
            th = th + self._offset
        ee, J, J_pc, pc = VK.ee_and_jacobian(
            lengths, self._ca, self._sa, th, self._modified, pose, ep.cos_yaw[sel], ep.sin_yaw[sel]
        )
        return ee, VK._bmv(J, u), pc, VK._bmv(J_pc, u)

    def _observation(self, sel: Any, t: np.ndarray, state: tuple, r_d: np.ndarray, v_d: np.ndarray) -> np.ndarray:
        """The float32 observations of rows `sel` (noise drawn, delay applied), as the single env's."""
        ep = self._ep
        ee, ee_vel, pc, pc_vel = state
        jv = ep.u[sel]
        rows = np.arange(self.num_envs)[sel]
        noise = ep.noise[rows]
        noisy = np.flatnonzero((noise > 0.0).any(1))
        if noisy.size:
            ee, ee_vel, pc, pc_vel, jv = ee.copy(), ee_vel.copy(), pc.copy(), pc_vel.copy(), jv.copy()
            for j in noisy:
                rng = self._rngs[rows[j]]
                s_pos, s_vel, s_jv = noise[j]
                if s_pos > 0.0:
                    ee[j] = ee[j] + s_pos * rng.standard_normal(3)
                    pc[j] = pc[j] + s_pos * rng.standard_normal(2)
                if s_vel > 0.0:
                    ee_vel[j] = ee_vel[j] + s_vel * rng.standard_normal(3)
                    pc_vel[j] = pc_vel[j] + s_vel * rng.standard_normal(2)
                if s_jv > 0.0:
                    jv[j] = jv[j] + s_jv * rng.standard_normal(self._n + 2)
        parts = [ee, ee_vel, pc, pc_vel, ep.pose[sel, 2:], ep.q[sel], jv, r_d, v_d, t[:, None]]
        flat = np.concatenate(parts, axis=1).astype(np.float32)
        np.clip(flat, self._template._obs_low, self._template._obs_high, out=flat)
        return flat

    def _delay(self, rows: np.ndarray, flat: np.ndarray, start: bool) -> None:
        """The single env's delay buffer: at reset fill it with the reading; after a step hand out the reading of
        `obs_delay` steps ago (ring buffer of delay + 1 slots indexed by the step count)."""
        ep = self._ep
        delay = ep.delay[rows]
        late = np.flatnonzero(delay > 0)
        if not late.size:
            return
        r, dl = rows[late], delay[late]
        if start:
            ep.history[r, :] = flat[late, None, : ep.n_sensor]
            return
        k = ep.steps[r]
        now = flat[late, : ep.n_sensor].copy()
        flat[late, : ep.n_sensor] = ep.history[r, (k + 1) % (dl + 1)]
        ep.history[r, k % (dl + 1)] = now

    def _targets(self, sel: Any, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """r_d(t), r_d_dot(t) of the rows `sel`: each robot's own path at its own time, grouped by path law."""
        ep = self._ep
        rows = np.arange(self.num_envs)[sel]
        r_d = np.empty((rows.size, 3))
        v_d = np.empty((rows.size, 3))
        pos = np.full(self.num_envs, -1)
        pos[rows] = np.arange(rows.size)
        for template, members in self._path_groups():
            m = members[pos[members] >= 0]
            if not m.size:
                continue
            at = pos[m]
            times = t[at]
            # robots usually share their step count: one time, without np.unique's sort
            for tk in times[:1] if (times == times[0]).all() else np.unique(times):
                hit = times == tk
                mm, aa = m[hit], at[hit]
                if template is None:  # random paths: each robot its own coefficients
                    coef = np.stack([ep.paths[i]._coef for i in mm])
                    amp, phase, kk = coef[:, 0], coef[:, 1], coef[:, 2]
                    ph, phd, _ = ep.paths[mm[0]]._phase(float(tk))
                    arg = kk * ph + phase
                    sin, cos = np.sin(arg), np.cos(arg)
                    p = (amp * (sin - np.sin(phase))).sum(2)
                    d1 = (amp * kk * cos).sum(2)
                    r_d[aa] = ep.start[mm] + p
                    v_d[aa] = d1 * phd
                else:
                    p, v = template.position_velocity(float(tk))
                    r_d[aa] = ep.start[mm] + p
                    v_d[aa] = v
        return r_d, v_d

    def _path_groups(self) -> list[tuple[Any, np.ndarray]]:
        """Robots grouped by path law: (a zero-start template of their spec, rows) or (None, rows) for random
        paths of one size and number of terms (their coefficients are per robot)."""
        if self._groups is None:
            groups: dict[str, tuple[Any, list[int]]] = {}
            for i, path in enumerate(self._ep.paths):
                spec = path.to_spec()
                if spec["type"] == "random":
                    key = repr(("random", spec["n_terms"], spec["duration"]))
                    groups.setdefault(key, (None, []))[1].append(i)
                else:
                    key = repr(sorted(spec.items()))
                    if key not in groups:
                        groups[key] = (path_from_spec(spec, np.zeros(3)), [])
                    groups[key][1].append(i)
            self._groups = [(tpl, np.array(rows)) for tpl, rows in groups.values()]
        return self._groups

    def _step_rows(self, sel: Any, a: np.ndarray):
        """One control step of the rows `sel` (all robots: slice(None)) with their actions `a` (N_sel, n + 2)."""
        ep = self._ep
        clipped = (np.abs(a) > 1.0).any(1)
        a = np.clip(a, -1.0, 1.0)
        ep.n_clipped[sel] += clipped
        u = a * self._scale
        nj = self._n
        q = ep.q[sel]
        q_arm = q[:, :nj]
        push = ((q_arm >= self._upper) & (u[:, :nj] > 0)) | ((q_arm <= self._lower) & (u[:, :nj] < 0))
        hits = push.sum(1)
        if push.any():
            u[:, :nj][push] = 0.0
        q = q + u * self._dt
        over = (q[:, :nj] > self._upper) | (q[:, :nj] < self._lower)
        if over.any():
            q[:, :nj] = np.clip(q[:, :nj], self._lower, self._upper)
            u[:, :nj][over] = 0.0
            hits = hits + over.sum(1)
        ep.limit_hits[sel] += hits
        pose, ep.cos_yaw[sel], ep.sin_yaw[sel] = VK.integrate_unicycle(
            ep.lengths["wheel_radius"][sel], ep.lengths["half_track"][sel], ep.pose[sel], u[:, nj:], self._dt
        )
        ep.pose[sel], ep.q[sel], ep.u[sel] = pose, q, u
        ep.steps[sel] += 1
        t = ep.steps[sel] * self._dt
        wear = ep.wear[sel]
        if (wear != 0.0).any():
            factor = 1.0 + wear * t
            for k in _WORN:  # `RobotParams.scaled`: float(length * factor); zero DH entries stay zero
                f = factor if ep.lengths0[k].ndim == 1 else factor[:, None]
                ep.lengths[k][sel] = ep.lengths0[k][sel] * f
        state = self._state(sel)
        r_d, v_d = self._targets(sel, t)
        diff = r_d - state[0]
        err = np.sqrt(VK._bdot(diff, diff))
        tracking = -self._w_track * err
        effort = -self._w_effort * VK._bdot(a, a)
        reward = tracking + effort
        bound = self._template.error_bound
        terminated = np.zeros(err.shape[0], dtype=bool) if bound is None else err > bound
        truncated = ep.steps[sel] >= ep.n_steps[sel]
        flat = self._observation(sel, t, state, r_d, v_d)
        self._delay(np.arange(self.num_envs)[sel], flat, start=False)
        false = np.zeros(err.shape[0], dtype=bool)
        info = {
            "ee_pos_true": state[0],
            "tracking_error": err,
            "reward_terms": {"tracking": tracking, "effort": effort},
            "action_clipped": clipped,
            "n_clipped": ep.n_clipped[sel].copy(),
            "joint_limit_hits": ep.limit_hits[sel].copy(),
            "tipped_over": false,
            "true_params_hash": ep.hashes[sel].copy(),
        }
        return reward, terminated, truncated, flat, info

    def _reset_rows(self, rows: np.ndarray, options: dict | None, infos: dict | None = None):
        """Start new episodes in `rows` as each single env's reset (its generator as it stands)."""
        tpl = self._template
        spec, q0, pose0, cond = tpl._episode_settings(options, self._nominal, "kinematic")
        assert q0 is not None  # a fixed arm has its start (the random family is in SYNC_ROBOTS)
        ep = self._ep
        params = []
        for i in rows:
            p = self._nominal.perturbed(self._rngs[i], cond["model_error"])
            params.append(p)
            ep.params0[i] = p
            for k, v in _lengths(p).items():
                ep.lengths0[k][i] = ep.lengths[k][i] = v
            ep.hashes[i] = p.hash()
        ep.q[rows] = q0
        ep.pose[rows] = pose0
        ep.u[rows] = 0.0
        ep.cos_yaw[rows], ep.sin_yaw[rows] = np.cos(pose0[2]), np.sin(pose0[2])
        ep.wear[rows] = cond["wear_rate"]
        ep.noise[rows] = (cond["obs_noise"], cond["obs_noise_vel"], cond["obs_noise_joint_vel"])
        delay = int(cond["obs_delay"])
        ep.delay[rows] = delay
        if delay + 1 > ep.history.shape[1]:
            grown = np.zeros((self.num_envs, delay + 1, ep.n_sensor), dtype=np.float32)
            grown[:, : ep.history.shape[1]] = ep.history
            ep.history = grown
        ep.steps[rows] = 0
        ep.n_clipped[rows] = 0
        ep.limit_hits[rows] = 0
        state = self._state(rows)
        ee = state[0]
        for j, i in enumerate(rows):
            path = path_from_spec(spec, ee[j], self._rngs[i])
            ep.paths[i] = path
            ep.start[i] = path.start
            ep.n_steps[i] = max(1, int(round(path.duration * tpl.control_freq)))
        self._groups = None
        t = np.zeros(rows.size)
        r_d, v_d = self._targets(rows, t)
        flat = self._observation(rows, t, state, r_d, v_d)
        self._delay(rows, flat, start=True)
        infos = {} if infos is None else infos
        for j, i in enumerate(rows):
            path = ep.paths[i]
            task = {
                "path": path.to_spec(),
                "start": [float(v) for v in ee[j]],
                "arm_joint_pos": [float(v) for v in q0],
                "base_pose": [float(v) for v in pose0],
                "duration": float(path.duration),
                "n_steps": int(ep.n_steps[i]),
            }
            info = {
                "task": task,
                "true_params_hash": ep.hashes[i],
                "ee_pos_true": ee[j].copy(),
                "tracking_error": 0.0,
                "n_clipped": 0,
                "joint_limit_hits": 0,
            }
            infos = self._add_info(infos, info, int(i))
        return flat, infos


def _lengths(p: RobotParams) -> dict[str, Any]:
    """The kinematic lengths of robot `p` by `_LENGTHS` key."""
    return {
        "a": p.dh_a,
        "d": p.dh_d,
        "tool": p.tool,
        "wheel_radius": p.wheel_radius,
        "half_track": p.half_track,
        "mount_offset": p.mount_offset,
        "shoulder_height": p.shoulder_height,
    }


def _scatter_info(info: dict[str, Any], mask: np.ndarray, n: int) -> dict[str, Any]:
    """Batched info arrays of the rows `mask` (values given for those rows only) as Gymnasium batches them."""
    out: dict[str, Any] = {}
    full = bool(mask.all())
    for key, value in info.items():
        if isinstance(value, dict):
            out[key] = _scatter_info(value, mask, n)
            continue
        if full:
            arr = value
        else:
            arr = np.zeros((n, *value.shape[1:]), dtype=value.dtype)
            if value.dtype == object:
                arr[:] = None
            arr[mask] = value
        out[key], out["_" + key] = arr, mask.copy()
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

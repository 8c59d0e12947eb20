"""`RobotBatch`: the episode state of N robots in the engine's arrays, and everything numpy does around the kernels.

The single env (`mobman_env.env.WheeledPumaEnv`) holds a batch of one robot, the vector env (`mobman_env.vector`)
a batch of N; both reset a row with `begin` + `set_path` and step through `mobman_env.engine`'s kernels, so robot
i of a vector env is a single env reset with seed S + i by construction: the same code on the same numbers.

Per row it keeps what the kernels do not need: the episode's true robot (`params0`, a `RobotParams`; wear
drifts the lengths from it), the path object, the hash of the robot and the row's noise plan (which entries of
the readings are noisy, in the order the noise is drawn from the row's generator: ee_pos (3) and arm_base_pos
(2) for `obs_noise`, ee_vel (3) and arm_base_vel (2) for `obs_noise_vel`, joint_vel (n + 2) for
`obs_noise_joint_vel`, base_yaw (1) for `obs_noise_yaw`; one `standard_normal` call per row and step, nothing
drawn for a noise-free row). The kernels scale the draws by the stds.

The engine's arrays are read here by the names of `mobman_env.engine`'s layouts (`PRM`, `state_columns`,
`io_columns`): the episode's `Conditions` go into `prm` under their own names (`begin`), a step's results come
out as a `StepResult` (`result`), and `named` gives any array as records with those names.

Imports numpy and `mobman_env` modules only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numpy as np

from mobman_env import engine as E
from mobman_env.params import RobotParams
from mobman_env.paths import path_from_spec


@dataclass(frozen=True)
class Conditions:
    """The per-episode conditions of a row: the env's constructor arguments of these names (validated by
    `mobman_env.env`), which a reset option of the same name overrides for one episode
    (`dataclasses.replace`). `RobotBatch.begin` writes each into the `prm` column of its name."""

    model_error: float = 0.05  # relative std of the true robot's lengths against the nominal ones
    obs_noise: float = 0.0  # m, std on ee_pos and arm_base_pos
    obs_noise_vel: float = 0.0  # m/s, std on ee_vel and arm_base_vel
    obs_noise_joint_vel: float = 0.0  # rad/s, std on joint_vel
    obs_noise_yaw: float = 0.0  # rad, std on base_yaw
    obs_delay: int = 0  # control steps
    wear_rate: float = 0.0  # 1/s, relative length change
    actuator_tau: float = 0.0  # s, the actuators' lag


#: how many times `RobotBatch.set_path` draws a path whose spec asks for `max_peak` (a 5-harmonic 0.3 m path in
#: 2.5 s is feasible to 0.9 on the PUMA in about 1 draw of 4: 64 leave about 1e-8 of episodes infeasible)
MAX_PATH_DRAWS = 64

#: the per-episode conditions a row holds (constructor arguments and reset options of the env), in order
CONDITIONS = tuple(f.name for f in fields(Conditions))


class StepResult(NamedTuple):
    """A row's results of its last kernel call (`RobotBatch.result`): the env's reward and flags and its `info`
    numbers, under their `info` names (and the `io_columns` names they are read from). Noise-free."""

    reward: float  # tracking + effort
    tracking: float  # the reward's tracking term, -w_tracking ||r_d - r_a||
    effort: float  # the reward's effort term, -w_effort ||a||^2
    tracking_error: float  # m
    ee_pos_true: np.ndarray  # (3,) m
    action_clipped: bool
    terminated: bool
    truncated: bool
    n_clipped: int  # this episode
    joint_limit_hits: int  # this episode
    tipped_over: bool


@dataclass
class RobotState:
    """What the sensors see (noise-free), world frame, SI units."""

    ee_pos: np.ndarray  # (3,) m
    ee_vel: np.ndarray  # (3,) m/s
    arm_base_pos: np.ndarray  # (2,) m, p_c
    arm_base_vel: np.ndarray  # (2,) m/s
    base_pose: np.ndarray  # (3,) x, y of P_0 (m), yaw (rad, continuous)
    joint_pos: np.ndarray  # (n + 2,) rad: n arm joints, left wheel, right wheel
    joint_vel: np.ndarray  # (n + 2,) rad/s
    roll_pitch: tuple[float, float]  # rad, of the platform


def noise_plan(m: int, cond: Conditions) -> np.ndarray | None:
    """The `io` columns of the row's standard normals, in draw order (see the module docstring); None when every
    std is 0."""
    r = E.sensor_columns(m)
    cols: list[int] = []
    if cond.obs_noise > 0.0:
        cols += [*range(r.ee_pos, r.ee_pos + 3), *range(r.arm_base_pos, r.arm_base_pos + 2)]
    if cond.obs_noise_vel > 0.0:
        cols += [*range(r.ee_vel, r.ee_vel + 3), *range(r.arm_base_vel, r.arm_base_vel + 2)]
    if cond.obs_noise_joint_vel > 0.0:
        cols += list(range(r.joint_vel, r.joint_vel + m))
    if cond.obs_noise_yaw > 0.0:
        cols += [r.base_yaw]
    return np.array(cols, dtype=np.intp) + E.io_columns(m).noise if cols else None


class RobotBatch:
    """The state of N robots' episodes (see the module docstring).

    Args:
        num: N.
        n_joints: n, the arm joints of every row (m = n + 2 actuators).
        dt: the control period, s.
        reward_weights: {"tracking": w_t, "effort": w_e}.
        error_bound: terminate a row when its error exceeds this (m); None: never.
    """

    def __init__(self, num: int, n_joints: int, dt: float, reward_weights: dict, error_bound: float | None):
        self.num = num
        self.m = m = n_joints + 2
        self.dt = float(dt)
        self.arm = np.zeros((num, E.ARM_ROWS, m))
        self.prm = np.zeros((num, E.P_LEN))
        self.st = np.zeros((num, E.s_len(m)))
        self.io = np.zeros((num, E.io_len(m)))
        self.hist = np.zeros((num, 1, E.n_sensor(m)), dtype=np.float32)
        #: the column layouts of `st` and `io` for these m actuators (`prm`'s is `engine.PRM`)
        self.S, self.IO = E.state_columns(m), E.io_columns(m)
        self.prm[:, E.PRM.w_tracking] = reward_weights["tracking"]
        self.prm[:, E.PRM.w_effort] = reward_weights["effort"]
        self.prm[:, E.PRM.error_bound] = math.inf if error_bound is None else error_bound
        # a path duration before the first reset (never 0: the timing divides)
        self.prm[:, E.PRM.path + 3] = 1.0
        self.rows = np.arange(num)
        self.params0: list[Any] = [None] * num  # each row's true robot at t = 0
        self.wear = np.zeros(num)
        self.paths: list[Any] = [None] * num
        self.hashes: list[str] = [""] * num
        self._noise: list[np.ndarray | None] = [None] * num
        self._noisy = np.zeros(num, dtype=bool)  # the rows with a noise plan

    # --- episodes -----------------------------------------------------------------------------------------
    def begin(self, i: int, params: RobotParams, q0: np.ndarray, pose: np.ndarray, cond: Conditions) -> None:
        """Start row i's episode: true robot `params` at joint angles q0 (m) and platform pose (x, y, yaw) at rest,
        under the conditions `cond`; its path comes with `set_path`."""
        m, P, S = self.m, E.PRM, self.S
        E.pack_robot(self.arm, self.prm, i, params)
        self.params0[i] = params
        self.hashes[i] = params.hash()
        p = self.prm[i]
        p[P.wear_rate] = self.wear[i] = cond.wear_rate
        p[P.actuator_tau] = cond.actuator_tau
        p[P.obs_delay] = cond.obs_delay
        p[P.obs_noise] = cond.obs_noise
        p[P.obs_noise_vel] = cond.obs_noise_vel
        p[P.obs_noise_joint_vel] = cond.obs_noise_joint_vel
        p[P.obs_noise_yaw] = cond.obs_noise_yaw
        plan = self._noise[i] = noise_plan(m, cond)
        p[P.noisy] = 0.0 if plan is None else 1.0
        self._noisy[i] = plan is not None  # row i only: a reset of N rows is linear in N (see `noisy`)
        s = self.st[i]
        s[:] = 0.0
        s[S.q : S.q + m] = q0
        s[S.x], s[S.y], s[S.yaw] = pose
        delay = int(cond.obs_delay)
        if delay + 1 > self.hist.shape[1]:
            grown = np.zeros((self.num, delay + 1, self.hist.shape[2]), dtype=np.float32)
            grown[:, : self.hist.shape[1]] = self.hist
            self.hist = grown

    def begin_episode(
        self, i: int, rng: np.random.Generator, source: Any, nominal: RobotParams, q0: Any, pose: Any, cond: Conditions
    ) -> tuple[RobotParams, np.ndarray]:
        """Draw row i's episode from its generator, in the env's fixed order (the arm and its start for a drawn
        robot family, then the worn true robot: the built robot worn, which for the scaled family is not its
        catalogue), and `begin` it; returns (the episode's nominal robot, its start
        (m angles)). The path (its seed is drawn next) comes with `set_path` once the start point is known."""
        drawn = source.draw(rng)
        built = nominal
        if drawn is not None:
            nominal, start, built = drawn
            q0 = np.concatenate([start, [0.0, 0.0]])
        params = built.perturbed(rng, cond.model_error)
        self.begin(i, params, q0, pose, cond)
        return nominal, np.asarray(q0, dtype=float)

    def task(self, i: int, start: Any, q0: Any, pose: Any) -> dict:
        """Row i's `info["task"]` at its reset: the path spec, its start, the joint vector, the base pose, the
        duration and the number of steps."""
        path = self.paths[i]
        return {
            "path": path.to_spec(),
            "start": [float(v) for v in start],
            "arm_joint_pos": [float(v) for v in q0],
            "base_pose": [float(v) for v in pose],
            "duration": float(path.duration),
            "n_steps": self.n_steps(i),
        }

    def set_path(self, i: int, spec: dict, start: Any, rng: np.random.Generator, control_freq: float) -> Any:
        """Row i's path from `spec`, anchored at `start` (a random spec without a seed draws one from `rng`);
        returns it. The episode lasts round(duration x control_freq) steps (at least 1). A random spec with
        `max_peak` is drawn again from `rng` while the reference law of `mobman_env.feasibility` needs more than
        `max_peak` of a speed limit on row i's true robot, at most `MAX_PATH_DRAWS` times (the last draw stays if
        none is feasible: its record then says so). The row must have begun (its start and robot are known)."""
        path = self._place_path(i, path_from_spec(spec, start, rng), control_freq)
        max_peak = spec.get("max_peak")
        if max_peak is not None:
            from mobman_env.feasibility import check_rows

            for _ in range(MAX_PATH_DRAWS - 1):
                if check_rows(self, [i])[0].peak_ratio <= max_peak:
                    break
                path = self._place_path(i, path_from_spec(spec, start, rng), control_freq)
        return path

    def _place_path(self, i: int, path: Any, control_freq: float) -> Any:
        self.paths[i] = path
        self.prm[i, E.PRM.path :] = path.coef
        self.prm[i, E.PRM.n_steps] = max(1, int(round(path.duration * control_freq)))
        return path

    def n_steps(self, i: int) -> int:
        return int(self.prm[i, E.PRM.n_steps])

    def steps(self, i: int) -> int:
        return int(self.st[i, self.S.steps])

    def true_params(self, i: int) -> RobotParams:
        """Row i's true robot at its current time (the episode's, drifted by its wear rate)."""
        p0 = self.params0[i]
        if self.wear[i] == 0.0:
            return p0
        return p0.scaled(1.0 + self.wear[i] * (self.steps(i) * self.dt))

    @property
    def noisy(self) -> np.ndarray:
        """The rows with a noise plan, ascending. Derived from a mask that `begin` sets for its own row: the list
        was once rebuilt over all N rows by every row's `begin`, so a reset of N robots did N^2 work (16,384
        robots took 59-113 s; tests/test_vector_env.py counts the work of a reset at two sizes)."""
        return np.flatnonzero(self._noisy)

    def draw_noise(self, rows: Any, rngs: Any) -> None:
        """The standard normals of this step's noise of the noisy rows among `rows` (each from its generator,
        `rngs[i]`), in each row's draw order; O(N)."""
        if not self._noisy.any():
            return
        chosen = self._noisy
        if len(rows) != self.num:
            chosen = np.zeros(self.num, dtype=bool)
            chosen[np.asarray(rows, dtype=np.intp)] = True
            chosen &= self._noisy
        io = self.io
        for i in np.flatnonzero(chosen).tolist():
            cols = self._noise[i]
            assert cols is not None  # a noisy row has a plan
            io[i, cols] = rngs[i].standard_normal(len(cols))

    # --- kinematic mode -----------------------------------------------------------------------------------------
    def ee_kinematic(self, rows: np.ndarray) -> np.ndarray:
        """r_a (k, 3) of the rows `rows` at their current state (a reset's start point, before its path is set)."""
        E.kinematic(self.arm, self.prm, self.st, self.io, self.new_obs(), self.hist, self.dt, rows, E.READ)
        return self.io[rows, self.IO.ee_pos_true : self.IO.ee_pos_true + 3].copy()

    def ee_physics(self, rows: np.ndarray) -> np.ndarray:
        """r_a (k, 3) of the rows `rows` from the PyBullet state in `io` (a reset's start point)."""
        E.physics(self.arm, self.prm, self.st, self.io, self.new_obs(), self.hist, self.dt, rows, E.READ)
        return self.io[rows, self.IO.ee_pos_true : self.IO.ee_pos_true + 3].copy()

    def observe_kinematic(self, rows: np.ndarray, obs: np.ndarray) -> None:
        """The observations of the rows `rows` at their current state into `obs` (a reset)."""
        E.kinematic(self.arm, self.prm, self.st, self.io, obs, self.hist, self.dt, rows, E.OBSERVE)

    def step_kinematic(self, rows: np.ndarray, obs: np.ndarray) -> int:
        """One step of the rows `rows` (their actions in `io[:, :m]`); -1, or the first row with a non-finite
        action (then nothing moved)."""
        return E.kinematic(self.arm, self.prm, self.st, self.io, obs, self.hist, self.dt, rows, E.STEP)

    def observe_physics(self, rows: np.ndarray, obs: np.ndarray, step: bool) -> None:
        """The observations of the rows `rows` from the PyBullet state in `io` into `obs`, after a step or at a
        reset."""
        E.physics(self.arm, self.prm, self.st, self.io, obs, self.hist, self.dt, rows, E.STEP if step else E.OBSERVE)

    def state(self, i: int) -> RobotState:
        """Row i's noise-free readings of the last kernel call (a reset or a step) as arrays."""
        m, S, r = self.m, self.S, E.sensor_columns(self.m)
        v = self.io[i, self.IO.readings : self.IO.readings + E.n_sensor(m)].copy()
        return RobotState(
            ee_pos=v[r.ee_pos : r.ee_pos + 3],
            ee_vel=v[r.ee_vel : r.ee_vel + 3],
            arm_base_pos=v[r.arm_base_pos : r.arm_base_pos + 2],
            arm_base_vel=v[r.arm_base_vel : r.arm_base_vel + 2],
            base_pose=self.st[i, [S.x, S.y, S.yaw]],
            joint_pos=v[r.joint_pos : r.joint_pos + m],
            joint_vel=v[r.joint_vel : r.joint_vel + m],
            roll_pitch=(float(self.st[i, S.roll]), float(self.st[i, S.pitch])),
        )

    # --- results ------------------------------------------------------------------------------------------------
    def result(self, i: int) -> StepResult:
        """Row i's results of the last kernel call (a step, or a reset's), by name. The results block of `io`
        holds them in `StepResult`'s order (`io_columns` from `reward` to `tipped_over`, `ee_pos_true` 3 wide):
        one read of the block, as the single env's step runs this every step."""
        c = self.IO
        reward, tracking, effort, err, e0, e1, e2, clipped, term, trunc, n_clipped, hits, tipped = self.io[
            i, c.reward : c.tipped_over + 1
        ].tolist()
        return StepResult(
            reward, tracking, effort, err, np.array((e0, e1, e2)), clipped != 0.0, term != 0.0, trunc != 0.0,
            int(n_clipped), int(hits), tipped != 0.0,
        )  # fmt: skip

    def named(self, array: str) -> np.ndarray:
        """`prm`, `st` or `io` as N records whose fields are its layout's names (`engine.PRM`, `state_columns`,
        `io_columns`): a view, so `named("prm")["actuator_tau"]` is the (N,) column the kernels read as
        `prm[i, PRM.actuator_tau]`, and writing it writes the array."""
        layout = {"prm": E.PRM, "st": self.S, "io": self.IO}[array]
        return E.record_view(getattr(self, array), layout)

    def new_obs(self) -> np.ndarray:
        """A fresh (N, obs) float32 array for a kernel to fill (observations handed out are never reused)."""
        return np.empty((self.num, E.obs_size(self.m)), dtype=np.float32)

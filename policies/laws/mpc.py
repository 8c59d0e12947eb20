"""`mpc`, `mpc-oracle`: receding-horizon whole-body QP with the path's preview, the actuator lag and the speed
limits in its prediction model.

Why: the reactive laws (`qp-oracle` included) see only r_d(t) and r_d_dot(t) and take the command for the
speed: on fast paths they meet the actuator limits late, and under actuator lag they lag behind. This law plans
the next `horizon` x `step` control periods (60 ms by default) against the path ahead, through the lag, so it
starts the motions early and commands through the lag. It may import `mobman_env` (engine, validation),
`policies.base`, `policies.batched`, `policies.kernels.shared`, `policies.laws.qp` (the dampers, the QP backends) and
`policies.kernels.mpc_model` (the prediction model and its kernels, with their docstring).

The law (per control step, at the measured joint angles and heading)
--------------------------------------------------------------------
Decision variable: B blocked commands x = [u_0; ...; u_{B-1}] (B (n + 2) rad/s; `policies.kernels.mpc_model`: the first
block is the move applied now). With the predicted end-effector r_k = r_0 + J D_k (D_k the actuators' angle
changes through the exact lag from the realised speeds w_0, J the whole-body Jacobian of the model at the
measured state, r_0 the measured `ee_pos`):

    minimise    sum_k omega_k ||r_d(t + k h) - r_k||^2 / h^2                      (tracking, k = 1 .. H)
              + effort_weight sum_b len_b (u_b - z)^T W (u_b - z)                  (effort and posture)
              + rate_weight (||u_0 - u_prev||^2 + sum_b ||u_b - u_{b-1}||^2)      (smoothness)
    subject to  -scale <= u_b <= scale,  u_0 within qp's joint-limit dampers

omega_k = 1, and `terminal_weight` at k = H; W = 1 for the arm joints, `wheel_weight` for the wheels; z the
posture pull of `policies.laws.qp` (arm: posture_gain (q_0 - q)); u_prev the previous command. The realised speeds are
convex combinations of w_0 and the commands, so the speed bounds on u bound w too. u_0 is sent.

w_0 is the law's own lag state: the measured `joint_vel` at the episode start, then propagated through the
commands the env applied (`MPCLaw._lag_state`). In kinematic mode it equals `joint_vel` to its float32 rounding
(the same results on every figure below); in physics mode `joint_vel` is PyBullet's joint speed, while the lag
state that shapes the motors' next commands is the engine's. With the measured speeds `mpc-oracle` chattered in
physics under 50 ms lag (Circle, radius 0.3 m in 6 s, dev seeds 3 and 4: max errors 26.4 and 14.2 mm,
cmd_accel_rms 1336 and 1476 rad/s^2); with its own lag state 2.8 and 4.9 mm (16, 19 rad/s^2; `qp-oracle` 7.8 and
8.1 mm). Without lag, in physics, `mpc-oracle` is behind `qp-oracle` on those two (6.2 and 6.9 mm against 1.6 and
2.9 mm): it has no feedback gain beyond re-planning from the measured point, and contact dynamics are not in its
model.

Models: `mpc-oracle` solves with the true robot (`params_provider`) and the true lag (`lag_provider`: the env's
`true_actuator_tau`), both read at every episode start: the known-model reference of protocol v3. `mpc` has the
catalogue robot, which lists no lag, so it identifies the one parameter online from its own commands and the
measured speeds (observations only): per control period (w_{k+1} - u_k) = a (w_k - u_k) for every actuator,
a = exp(-dt/tau), least squares over the episode (speeds normalised by their limits), used once the accumulated
excitation passes 1e-6 (`policies.kernels.mpc_model.lag_fit_rows`), a decay below 1e-3 per period read as no lag (the
float32 speeds' rounding reads as a lag of about 0.5 ms, and fitting it made `mpc` chaotic: see
`eval.output.precision`); it finds 0 without lag and 0.1 s within 1e-8 s after 10 steps.

Preview: the path of `info["task"]` (`policies.kernels.mpc_model`); a row started without it extrapolates the target.

Measured (kinematic, PUMA, development seeds; max tracking error per episode; IQM over episodes)
-------------------------------------------------------------------------------------------------
* The 2.5 s rung of the difficulty ladder (random path, 0.3 m, 5 harmonics, 2.5 s; seeds 0-99): within 6 mm,
  `mpc-oracle` 77/100 (IQM 0.98 mm), `qp-oracle` 61/100 (5.65 mm), `mpc` 74/100 (2.02 mm), `qp` 23/100 (8.22
  mm). 26 paths look infeasible (r_d_dot lies more than 1 cm/s outside what the speed limits give at
  `mpc-oracle`'s configurations); on the other 74 `mpc-oracle` tracks 73 (98.6%), `qp-oracle` 58 (78.4%).
  Without the path (the target extrapolated with constant acceleration) `mpc-oracle` tracks 75/100 (1.44 mm).
* Actuator lag (the four tasks, seeds 0-19 each), max-error IQM: at 100 ms `mpc-oracle` 0.013 mm against
  `qp-oracle`'s 0.977 mm, `mpc` 0.215 mm against `qp`'s 1.324 mm; at 150 ms 0.013 / 1.453 and 0.220 / 1.790 mm;
  without lag 0.006 / 0.046 and 0.141 / 0.704 mm. `mpc` assuming tau = 0 instead of identifying it: 0.257 mm at
  100 ms, 0.344 mm at 150 ms, 0.141 mm without lag: so it identifies.
* Horizon: 6 steps of 10 ms in 3 blocks. On the rung (seeds 0-99): 10 steps in 4 blocks 75/100 (IQM 1.63 mm
  with the measured speeds), 8 in 8 78/100 (1.01 mm), 12 in 4 72/100 (1.75 mm); prediction steps of 20 ms (seeds
  0-29) 22/30 against 24/30 for 10 ms, and a 15-step 0.3 s horizon 8/30: the Jacobian held over the horizon is
  what limits it. Re-linearising along the previous plan (the Jacobian of each prediction step at its predicted
  state, heading included) raised the rung to 25/30 (IQM 1.04 against 1.34 mm) but made the commands chatter
  (cmd_accel_rms median 285 against 48 rad/s^2): deleted. With 10 steps in 4 blocks, effort_weight 1e-5,
  rate_weight 1e-4, terminal_weight 10, posture_gain 0 or 5 and wheel_weight 3 moved the rung by -3 to +2
  episodes of 100; with the default horizon rate_weight 1e-3 lost 4 and raised the 100 ms lag IQM to 0.035 mm.
* Sensor noise (`error_time`; development seeds 0-5, PUMA, UR5 and Panda x Circle, Lemniscate and Random, the
  conditions of `eval.conditions`): removing the measured error at once (`error_time` 0, the default) makes the
  law follow the noise of `ee_pos`: under `noise-heavy` (2 mm, 0.02 m/s, 3 mrad) `mpc-oracle` tracks 0/54 within
  6 mm (IQM 8.52 mm, cmd_accel_rms median 247 rad/s^2), with `error_time` 0.01 s 32/54 (5.91 mm), 0.02 s 54/54
  (4.20 mm, 73 rad/s^2), 0.05 s 54/54 (2.61 mm, 29 rad/s^2); `mpc` alike (0.02 s: 54/54, 4.23 mm);
  `physics-combined` (seeds 0-2, 9 episodes) `mpc-oracle` 0/9 -> 7/9 at 0.02 s, `mpc` 0/9 either way. The price
  is precision where there is no noise: at 0.02 s the max-error IQM at `default` goes from 0.005 to 0.013 mm
  (`mpc`: 0.113 to 0.278 mm), under 100 ms lag from 0.011 to 0.019 mm (`mpc`: 0.320 mm), on the 2.5 s rung drawn
  feasible (6 episodes) from 0.57 to 1.34 mm (`mpc`: 1.50 to 3.48 mm, 0.05 s loses 3 of 6), and on the plain
  rung's seed 7 `mpc-oracle` ends at 7.05 mm instead of within 6. So the default stays 0 (the protocol's
  reference per cell is the better of `mpc-oracle` and `qp-oracle`, which holds the noisy cells); a law that
  estimates the noise from its own innovation and picks `error_time` from it is the next step.
* Cost (interleaved with `qp-oracle` in one process, on a shared machine: ratios only): a single env's
  `predict` takes 1.2 times `qp-oracle`'s, a robot-step of 64 batched rows 1.03 times.

Solver: DAQP on the dense QP (box bounds only: `daqp.solve` directly, as `policies.laws.qp.daqp_solve_qp`), other
backends through `qpsolvers.solve_qp`. If it returns no solution the row falls back to the unconstrained
minimiser clipped to the bounds and `qp_failures` counts it (none seen on the development seeds above).

One law for N robots (`MPCLaw`); the single-env `MPC` is its N = 1 case, so row i of a batch equals the single
policy bit for bit (`tests/test_batched_policies.py`): the QP of each row is assembled by a scalar numba kernel.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env import engine as E
from mobman_env.validation import integer, number
from policies.base import EnvFacts, reject_extra
from policies.batched import BatchedController, LawView
from policies.kernels.mpc_model import (
    block_lengths,
    condensed_qp,
    lag_coefficients,
    lag_fit_rows,
    preview_rows,
    task_coefficients,
)
from policies.kernels.shared import ModelJacobians
from policies.laws.qp import SOLVERS, damper_bounds


@dataclass(frozen=True)
class MPCConfig:
    """Options of the receding-horizon QP. Spec keys: `mpc:horizon=10,step=2,...` (also `mpc-oracle:...`)."""

    horizon: int = 6
    """Prediction steps H of the horizon."""
    step: int = 1
    """Control periods per prediction step (h = step dt: the default horizon is 6 x 10 ms = 60 ms)."""
    blocks: int = 3
    """Input blocks B over the horizon (move blocking: the QP has B (n + 2) variables)."""
    terminal_weight: float = 4.0
    """Weight of the last predicted error relative to the others (1 each)."""
    effort_weight: float = 1e-6
    """Weight of (u - z)^2 per prediction step, (m/s)^2 per (rad/s)^2: tracking errors are weighed as e / h."""
    wheel_weight: float = 1.0
    """Effort weight of the wheels relative to the arm joints' (1 = the same per rad/s)."""
    rate_weight: float = 1e-5
    """Weight of the command changes between blocks and from the previous command, (m/s)^2 per (rad/s)^2."""
    posture_gain: float = 2.0
    """Pull of the n arm joints towards their angles at the episode start, 1/s (0 turns it off; as `qp`)."""
    influence: float = 0.5
    """Influence distance of the joint-limit dampers on the first move, rad (as `qp`)."""
    stop: float = 0.03
    """Stop distance of the dampers, rad (as `qp`)."""
    damper_gain: float = 1.0
    """Damper gain, rad/s (as `qp`)."""
    solver: str = "daqp"
    """QP backend: daqp (default), proxqp, osqp or clarabel (through `qpsolvers`)."""
    error_time: float = 0.0
    """Time constant, s, with which the plan removes the measured tracking error e0 = r_d(t) - r_0: the predicted
    errors are weighed against r_d(t + k h) - e0 exp(-k h / error_time); 0 (the default) removes it at once, which
    follows heavy sensor noise into the commands (the module docstring's measurements)."""

    def __post_init__(self):
        for name, low in (("horizon", 1), ("step", 1), ("blocks", 1)):
            object.__setattr__(self, name, integer(f"MPCConfig.{name}", getattr(self, name), low=low, high=200))
        for name, open_low in (
            ("terminal_weight", False),
            ("effort_weight", True),
            ("wheel_weight", True),
            ("rate_weight", False),
            ("posture_gain", False),
            ("influence", True),
            ("stop", False),
            ("damper_gain", True),
            ("error_time", False),
        ):
            object.__setattr__(self, name, number(f"MPCConfig.{name}", getattr(self, name), low=0.0, open_low=open_low))
        if self.blocks > self.horizon:
            raise ValueError(f"MPCConfig.blocks ({self.blocks}) must be at most MPCConfig.horizon ({self.horizon})")
        if self.stop >= self.influence:
            raise ValueError(
                f"MPCConfig.stop ({self.stop!r} rad) must be smaller than MPCConfig.influence ({self.influence!r} rad)"
            )
        if self.solver not in SOLVERS:
            raise ValueError(f"MPCConfig.solver must be one of {', '.join(SOLVERS)}, got {self.solver!r}")


def daqp_solve_box(P: np.ndarray, f: np.ndarray, lb: np.ndarray, ub: np.ndarray) -> np.ndarray | None:
    """min 1/2 x^T P x + f^T x subject to lb <= x <= ub by DAQP (simple bounds, no other constraint); the
    solution, or None when DAQP finds none."""
    import daqp

    x, _, exitflag, _ = daqp.solve(P, f, np.zeros((0, len(f))), ub, lb, np.zeros(len(f), dtype=np.intc))
    return x if exitflag > 0 else None


class MPCLaw(BatchedController):
    """The receding-horizon QP of this module for N robots (see the module docstring). `params(i)` returns row
    i's `RobotParams` and `lag(i)` its true lag (s; None: the nominal model, which identifies it online), read
    at each of the row's episode starts. `MPC` is its N = 1 case.

    Diagnostics per row: `tau` (N,), the lag the prediction uses (s); `has_path` (N,), whether the row previews
    its path (else it extrapolates the target); `last_plan` (N, B, n + 2), the blocked commands of the last
    solution (rad/s); `qp_failures` (N,), steps this episode on which the solver gave no solution."""

    uses_keys: tuple[str, ...] = (
        "joint_pos",
        "joint_vel",
        "base_yaw",
        "ee_pos",
        "target_pos",
        "target_vel",
        "time",
    )

    def __init__(
        self,
        facts: EnvFacts,
        config: MPCConfig,
        n: int,
        seed: int | None,
        params: Callable[[int], Any],
        lag: Callable[[int], float] | None,
        name: str,
    ):
        super().__init__(facts, n, seed)
        self.name = self.spec = name
        self.config = c = config
        if c.solver == "daqp":
            self._solve: Callable[..., Any] = daqp_solve_box
        else:
            import qpsolvers  # a core dependency, imported here so that importing `policies` stays light

            self._solve = lambda P, f, lb, ub: qpsolvers.solve_qp(P, f, lb=lb, ub=ub, solver=c.solver)
        self._model = ModelJacobians(n, params)
        self._lag = lag
        self._identify = lag is None
        self._m = m = facts.n_actuators
        self._n_arm = m - 2
        H, B = c.horizon, c.blocks
        self._h = c.step * facts.dt
        self._lengths = block_lengths(H, B)
        self._omega = np.ones(H)
        self._omega[-1] = c.terminal_weight
        # the share of the measured error each prediction step still carries (`error_time`; none: removed at once)
        self._decay = np.exp(-self._h * np.arange(1, H + 1) / c.error_time) if c.error_time > 0 else None
        weights = np.r_[np.ones(m - 2), np.full(2, c.wheel_weight)]
        self._reg = c.effort_weight * self._lengths[:, None] * weights[None, :]
        self._lbx, self._ubx = np.tile(-self._scale, B), np.tile(self._scale, B)
        self._P, self._f = np.zeros((B * m, B * m)), np.zeros(B * m)
        self._lower, self._upper = np.zeros((n, m - 2)), np.zeros((n, m - 2))
        self._q0 = np.zeros((n, m - 2))
        self._coef = np.zeros((n, E.PATH_LEN))
        self.has_path = np.zeros(n, dtype=bool)
        self._fresh = np.ones(n, dtype=bool)  # no previous step this episode (no speed or target history)
        self._w_prev, self._tvel_prev = np.zeros((n, m)), np.zeros((n, 3))
        self.tau = np.zeros(n)
        self._sxy, self._sxx = np.zeros(n), np.zeros(n)
        self._c, self._G = np.zeros((n, H)), np.zeros((n, H, B))
        self.last_plan = np.zeros((n, B, m))
        self.qp_failures = np.zeros(n, dtype=int)
        self._tasks: Any = None
        self._w = np.zeros((n, m))  # the lag state (`_lag_state`)

    @property
    def params(self) -> list[Any]:
        """The `RobotParams` each row solves with this episode (None before its first episode start)."""
        return self._model.params

    def reset(self, obs: dict, info: dict | None = None, *, seed: Any = None) -> None:
        """Start every row's episode; `info` (the vector env's reset info) gives each row its path to preview."""
        self._tasks = info
        try:
            super().reset(obs, info, seed=seed)
        finally:
            self._tasks = None

    def _reset_rows(self, rows: np.ndarray, obs: dict) -> None:
        self._model.load(rows.tolist())
        m = self._m
        for i in rows.tolist():
            p = self._model.params[i]
            if p.n_actuators != m:
                raise ValueError(
                    f"MPC was built for {m} actuators (EnvFacts) but its model {p.arm.name} has {p.n_actuators}; "
                    "build the policy from the env it drives (policies.make(spec, env))"
                )
            self._lower[i], self._upper[i] = p.joint_lower, p.joint_upper
            coef = None if self._tasks is None else task_coefficients(self._tasks, i)
            self.has_path[i] = coef is not None
            if coef is not None:
                self._coef[i] = coef
            self.tau[i] = 0.0 if self._lag is None else float(self._lag(i))
            lag_coefficients(self.tau[i], self._h, self._lengths, self._c[i], self._G[i])
        self._q0[rows] = obs["joint_pos"][rows, : m - 2]
        self._fresh[rows] = True
        self._sxy[rows] = self._sxx[rows] = 0.0
        self.qp_failures[rows] = 0

    def _lag_state(self, measured: np.ndarray, applied: np.ndarray) -> np.ndarray:
        """w_0 (N, m), rad/s: the realised speeds as the lag model has them, propagated from the measured speeds at
        the episode start through the commands the env applied (`applied`, the last control period's). In
        kinematic mode this equals `joint_vel` to its float32 rounding; in physics mode `joint_vel` is PyBullet's
        joint speed while the lag state that shapes the motors' next commands is the engine's, this one (see the
        module docstring for what the measured speeds did there)."""
        decay = np.exp(-self.facts.dt / np.where(self.tau > 0.0, self.tau, 1.0))
        decay = np.where(self.tau > 0.0, decay, 0.0)[:, None]
        self._w = np.where(self._fresh[:, None], measured, applied + (self._w - applied) * decay)
        return self._w

    def _update_lag(self, w: np.ndarray, applied: np.ndarray) -> None:
        """The online lag fit (the nominal model) of the rows with a previous step, from the commands the env
        applied (the float32 action times the scale) and the measured speeds `w`."""
        # a row whose speeds or commands are not finite this step adds nothing (a NaN would stop its fit for good)
        ok = np.isfinite(w).all(axis=1) & np.isfinite(self._w_prev).all(axis=1) & np.isfinite(applied).all(axis=1)
        rows = np.flatnonzero(~self._fresh & ok)
        if not len(rows):
            return
        before = self.tau.copy()
        lag_fit_rows(rows, self._w_prev, w, applied, self._scale, self.facts.dt, self._sxy, self._sxx, self.tau)
        for i in np.flatnonzero(self.tau != before).tolist():
            lag_coefficients(self.tau[i], self._h, self._lengths, self._c[i], self._G[i])

    def _act(self, obs: dict) -> np.ndarray:
        c = self.config
        m, na = self._m, self._n_arm
        tvel = obs["target_vel"]
        applied = (self.last_u / self._scale).astype(np.float32).astype(float) * self._scale  # as the env applies it
        if self._identify:
            self._update_lag(obs["joint_vel"], applied)
        w0 = self._lag_state(obs["joint_vel"], applied)
        acc = np.where(self._fresh[:, None], 0.0, (tvel - self._tvel_prev) / self.facts.dt)
        n = len(w0)
        d = np.empty((n, c.horizon, 3))
        preview_rows(self._coef, self.has_path, obs["time"][:, 0], self._h, obs["target_pos"], tvel, acc, d)
        d -= obs["ee_pos"][:, None, :]
        if self._decay is not None:  # remove the measured error at the rate 1 / error_time, not at once
            d -= (obs["target_pos"] - obs["ee_pos"])[:, None, :] * self._decay[None, :, None]
        J = self._model(obs["joint_pos"], obs["base_yaw"], True)
        q = obs["joint_pos"][:, :na]
        z = np.zeros((n, m))
        if c.posture_gain > 0:
            z[:, :na] = c.posture_gain * (self._q0 - q)
        lb, ub = damper_bounds(q, self._lower, self._upper, self._scale, c.influence, c.stop, c.damper_gain)
        u = np.empty((n, m))
        P, f, lbx, ubx = self._P, self._f, self._lbx, self._ubx
        # a row with a non-finite observation gets NaN (that row's problem, as in `policies.laws.qp`: the env refuses it
        # naming the robot), never the solver or LAPACK's least squares, whose error would fail every row
        finite = (
            np.isfinite(J).all(axis=(1, 2))
            & np.isfinite(d).all(axis=(1, 2))
            & np.isfinite(w0).all(axis=1)
            & np.isfinite(z).all(axis=1)
        )
        for i in range(n):
            if not finite[i]:
                u[i] = np.nan
                continue
            condensed_qp(J[i], d[i], w0[i], self._c[i], self._G[i], self._omega, self._h, self._reg, z[i],
                         c.rate_weight, self.last_u[i], P, f)  # fmt: skip
            lbx[:m], ubx[:m] = lb[i], ub[i]
            x = self._solve(P, f, lbx, ubx)
            if x is None or not np.all(np.isfinite(x)):
                self.qp_failures[i] += 1
                x = np.clip(np.linalg.lstsq(P, -f, rcond=None)[0], lbx, ubx)
            self.last_plan[i] = x.reshape(c.blocks, m)
            u[i] = x[:m]
        self._w_prev[:] = obs["joint_vel"]
        self._tvel_prev[:] = tvel
        self._fresh[:] = False
        return u


class MPC(LawView):
    """The receding-horizon QP of this module for one env: the N = 1 case of `MPCLaw`.

    `MPC(facts, config=None, seed=None, *, nominal_params=None, params_provider=None, lag_provider=None)`:
    exactly one model source, `nominal_params` (a `RobotParams` or a callable returning the episode's nominal
    one: `mpc`) or `params_provider` with `lag_provider` (callables returning the true `RobotParams` and the true
    lag, s, called at every episode start: `mpc-oracle`). `reset(obs, info)` reads the path to preview from
    `info["task"]`.
    """

    name = "mpc"
    #: `policies.registry` gives the true model's classes of this flag the env's true lag (`lag_provider`)
    reads_true_lag = True

    def __init__(
        self,
        facts: EnvFacts,
        config: MPCConfig | None = None,
        seed: int | None = None,
        *,
        nominal_params: Any = None,
        params_provider: Callable[[], Any] | None = None,
        lag_provider: Callable[[], float] | None = None,
        **extra: Any,
    ):
        reject_extra(self, extra, "nominal_params, params_provider, lag_provider")
        if (nominal_params is None) == (params_provider is None):
            raise ValueError(
                "MPC needs exactly one model source: nominal_params (a RobotParams, for `mpc`) or params_provider "
                "with lag_provider (callables returning the true RobotParams and lag, for `mpc-oracle`)"
            )
        if params_provider is not None and not (callable(params_provider) and callable(lag_provider)):
            raise ValueError(
                "MPC's params_provider and lag_provider must both be callables returning the env's current true "
                "RobotParams and actuator lag (s)"
            )
        self.config = config or MPCConfig()
        # the providers are read through self at each episode start (a test spies on them)
        if params_provider is not None:
            assert lag_provider is not None  # checked above
            self._provider, self._lag_provider = params_provider, lag_provider
            self.law: MPCLaw = MPCLaw(
                facts, self.config, 1, seed, lambda i: self._provider(), lambda i: self._lag_provider(), "mpc-oracle"
            )
        else:
            self._provider = nominal_params if callable(nominal_params) else (lambda: nominal_params)
            self.law = MPCLaw(facts, self.config, 1, seed, lambda i: self._provider(), None, "mpc")
        super().__init__(facts, seed)

    @classmethod
    def batched(
        cls,
        facts: EnvFacts,
        config: Any,
        n: int,
        seed: int | None,
        *,
        nominal_params: Callable[[int], Any] | None = None,
        params_provider: Callable[[int], Any] | None = None,
        lag_provider: Callable[[int], float] | None = None,
    ) -> MPCLaw:
        """The batched law for n robots (`policies.make(spec, vector_env)`): `nominal_params(i)` (`mpc`) or
        `params_provider(i)` and `lag_provider(i)` (`mpc-oracle`) return row i's model."""
        if (nominal_params is None) == (params_provider is None) or (params_provider is not None) != (
            lag_provider is not None
        ):
            raise ValueError("MPC.batched needs nominal_params, or params_provider with lag_provider")
        if params_provider is not None:
            return MPCLaw(facts, config, n, seed, params_provider, lag_provider, "mpc-oracle")
        return MPCLaw(facts, config, n, seed, nominal_params, None, "mpc")  # type: ignore[arg-type]

    @property
    def knowledge(self) -> str:
        """The knowledge class (`policies.knowledge`): "true" for `mpc-oracle` (the worn robot and the true lag),
        "nominal" for `mpc` (the catalogue's robot; the lag it identifies from its own observations)."""
        return "true" if self.name == "mpc-oracle" else "nominal"

    def reset(self, obs: dict, info: dict | None = None, *, seed: int | None = None) -> None:
        self.law._tasks = info
        try:
            super().reset(obs, info, seed=seed)
        finally:
            self.law._tasks = None

    @property
    def params(self) -> Any:
        """The `RobotParams` solved with this episode."""
        return self.law.params[0]

    @property
    def tau(self) -> float:
        """The lag the prediction uses, s."""
        return float(self.law.tau[0])

    @property
    def qp_failures(self) -> int:
        return int(self.law.qp_failures[0])

"""`qp`, `qp-oracle`: whole-body differential inverse kinematics as a quadratic program, with joint limits.

The reactive mobile-manipulation controllers of Haviland & Corke (NEO, RA-L 2021; "A holistic approach to
reactive mobile manipulation", RA-L 2022) turn resolved-rate control into a small QP per control step, so that
joint position limits, speed limits and a secondary objective are respected *while* the end-effector tracks.
This module is that controller for the position-only task of this benchmark; it may import `mobman_env`
(kinematics, validation), `policies.base` and `qpsolvers`.

The law (per control step, at the measured joint angles q (`joint_pos[:6]`) and heading (`base_yaw`))
-------------------------------------------------------------------------------------------------------------
Decision variable x = [u; s]: the n + 2 actuator speeds u (rad/s: n arm joints, left wheel, right wheel; n from
`EnvFacts`, 6 for the PUMA) and a task
slack s (3, m/s).

    minimise    1/2 sum_i w_i (u_i - z_i)^2  +  1/2 slack_weight ||s||^2
    subject to  J_wb(q, yaw) u + s = v,         v = r_d_dot + gamma (r_d - r_a)        (task, with slack)
                lb_i <= u_i <= ub_i                                                    (speeds and dampers)

* J_wb is the whole-body Jacobian of the model (`mobman_env.kinematics.whole_body_jacobian`: the platform's
  translation included), v the closed-loop task velocity of eq. (10) with the measured `ee_pos`,
  `target_pos` and `target_vel` (m/s). The slack keeps the problem feasible whatever the bounds; with a heavy
  `slack_weight` it stays near zero while the task is feasible (it acts like a damping of 1/slack_weight
  m^2/rad^2 of the pseudo-inverse, so it also bounds the speeds at a singularity).
* w_i: 1 for the arm joints, `wheel_weight` for the wheels ((rad/s)^-2, relative). z: the posture term, a pull
  of the n arm joints back to their angles at the episode start, z_arm = posture_gain (q_0 - q) (rad/s;
  z_wheels = 0). Together they make the solution the speeds closest to the posture pull that track v: the
  arm keeps away from its reach limit and lets the platform drive and turn.
* Bounds: the speed limits (the env's action scale, rad/s) and, for each arm joint within `influence` (rad) of
  a position limit, a velocity damper (NEO's): the speed towards that limit is at most
  damper_gain (rho - stop) / (influence - stop), rho the distance to the limit, so it falls linearly to 0 at
  `stop` rad from it (and turns into a push away inside it). The limits come from the model's `RobotParams`
  (`joint_lower`, `joint_upper`; the env's true robot has the same limits as the catalogue).

Model: `qp` uses the nominal model (`nominal_params`), `qp-oracle` the true robot from a `params_provider`
called at every episode start (`policies.registry.true_params_provider`): `qp-oracle` is the known-model
ceiling of the benchmark; unlike `oracle` it respects the joint limits (joint 1's stop ends many Circle-v0
episodes of the minimum-norm laws).

Solver: the dense dual active-set solver DAQP (`solver`, default "daqp"): measured on this problem (11
variables, 3 equalities, box bounds), median solve times 11 us (daqp), 58 us (proxqp), 410 us (osqp), 530 us
(clarabel), all through `qpsolvers.solve_qp`. The default calls `daqp.solve` with the arrays
`qpsolvers.solve_qp(..., solver="daqp")` builds for it (`daqp_solve_qp`; same solution bit for bit, checked by
`tests/test_baselines.py`), which saves qpsolvers' problem checks, about 14 of the 21 us per step; the other
backends go through `qpsolvers.solve_qp`. If the solver returns no solution (none seen on the development
seeds), the step falls back to the damped pseudo-inverse clipped to the bounds and `qp_failures` counts it.

One law for N robots (`QPLaw`, `policies.make(spec, vector_env)`): the Jacobians of all rows in one batched
pass (`policies.kernels.shared.ModelJacobians`), the bounds, the posture term and v as whole-array operations, then one
QP per row. The single-env `QP` is its N = 1 case (STYLE 14), so row i of a batch equals the single policy bit
for bit (`tests/test_batched_policies.py`).
"""

from __future__ import annotations

from collections.abc import Callable
from ctypes import c_int
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env.validation import number
from policies.base import EnvFacts, reject_extra
from policies.batched import BatchedController, LawView
from policies.kernels.shared import ModelJacobians
from policies.laws.jmpi import DEFAULT_GAMMA

#: QP backends accepted by `QPConfig.solver` (dense ones that `qpsolvers` drives; daqp is the default).
SOLVERS = ("daqp", "proxqp", "osqp", "clarabel")


@dataclass(frozen=True)
class QPConfig:
    """Options of the whole-body QP. Spec keys: `qp:gamma=20,posture_gain=2,...` (also `qp-oracle:...`)."""

    gamma: float = DEFAULT_GAMMA
    """Task-space feedback gain, 1/s: v = r_d_dot + gamma (r_d - r_a) (the benchmark's one gain, 20)."""
    slack_weight: float = 1e6
    """Weight of the task slack ||s||^2, (m/s)^-2 relative to the joint-speed cost: large, so the task is
    tracked exactly whenever the bounds allow it."""
    wheel_weight: float = 1.0
    """Cost weight of the two wheel speeds relative to the arm joints' (1 = the same per rad/s)."""
    posture_gain: float = 2.0
    """Pull of the n arm joints towards their angles at the episode start, 1/s (0 turns it off)."""
    influence: float = 0.5
    """Influence distance of the joint-limit dampers, rad: a damper acts within this distance of a limit."""
    stop: float = 0.03
    """Stop distance of the dampers, rad: the speed towards a limit is 0 at this distance from it."""
    damper_gain: float = 1.0
    """Damper gain xi, rad/s: the largest speed towards a limit allowed at the influence distance."""
    solver: str = "daqp"
    """QP backend through `qpsolvers`: daqp (default, the fastest measured), proxqp, osqp or clarabel."""

    def __post_init__(self):
        for name, open_low in (
            ("gamma", False),
            ("slack_weight", True),
            ("wheel_weight", True),
            ("posture_gain", False),
            ("influence", True),
            ("stop", False),
            ("damper_gain", True),
        ):
            object.__setattr__(self, name, number(f"QPConfig.{name}", getattr(self, name), low=0.0, open_low=open_low))
        if self.stop >= self.influence:
            raise ValueError(
                f"QPConfig.stop ({self.stop!r} rad) must be smaller than QPConfig.influence ({self.influence!r} "
                f"rad): the damper falls from damper_gain at the influence distance to 0 at the stop distance"
            )
        if self.solver not in SOLVERS:
            raise ValueError(f"QPConfig.solver must be one of {', '.join(SOLVERS)}, got {self.solver!r}")


def daqp_solve_qp(
    P: np.ndarray, q: np.ndarray, *, A: np.ndarray, b: np.ndarray, lb: np.ndarray, ub: np.ndarray, solver: str = "daqp"
) -> np.ndarray | None:
    """`qpsolvers.solve_qp(P, q, A=A, b=b, lb=lb, ub=ub, solver="daqp")` for this module's problem (equalities
    and box bounds, no inequalities): the constraint arrays qpsolvers' DAQP interface builds (box rows first,
    then the equalities, sense 5), handed to `daqp.solve` directly. The solution, or None when DAQP finds none."""
    import daqp

    ms, meq = len(lb), len(b)
    upper = np.empty(ms + meq)
    lower = np.full(ms + meq, -1e30)
    upper[:ms], lower[:ms], upper[ms:] = ub, lb, b
    sense = np.zeros(ms + meq, dtype=c_int)
    sense[ms:] = 5
    x, _, exitflag, _ = daqp.solve(P, q, A, upper, lower, sense)
    return x if exitflag > 0 else None


def damper_bounds(
    q_arm: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    scale: np.ndarray,
    influence: float,
    stop: float,
    gain: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(lb, ub) of the actuator speeds, (N, n + 2) each, at the arm angles `q_arm` (N, n) (rad) of robots whose
    joint limits are `lower`, `upper` (N, n) (rad): the speed limits `scale` (n + 2,) (rad/s) tightened by NEO's
    velocity dampers (see the module docstring: within `influence` rad of a limit the speed towards it is at most
    gain (rho - stop) / (influence - stop)). The one implementation of the dampers (`qp`, `mpc`)."""
    m = q_arm.shape[1]
    ramp = gain / (influence - stop)  # (rad/s) per rad of distance beyond `stop`
    lb = np.broadcast_to(-scale, (len(q_arm), m + 2)).copy()
    ub = np.broadcast_to(scale, (len(q_arm), m + 2)).copy()
    d_up = upper - q_arm
    d_lo = q_arm - lower
    near_up = d_up < influence
    near_lo = d_lo < influence
    if near_up.any():
        ub[:, :m] = np.where(near_up, np.minimum(ub[:, :m], ramp * (d_up - stop)), ub[:, :m])
    if near_lo.any():
        lb[:, :m] = np.where(near_lo, np.maximum(lb[:, :m], -ramp * (d_lo - stop)), lb[:, :m])
    # inside the stop distance a damper pushes away; keep every box non-empty and within the speed limits
    return np.minimum(lb, scale), np.maximum(ub, -scale)


class QPLaw(BatchedController):
    """The whole-body QP of this module for N robots (see the module docstring); `params(i)` returns row i's
    `RobotParams` (nominal or true), read at each of the row's episode starts. `QP` is its N = 1 case.

    Diagnostics per row: `last_slack` (N, 3), s of the last step (m/s); `qp_failures` (N,), steps this episode on
    which the solver gave no solution and the fallback acted."""

    uses_keys: tuple[str, ...] = ("joint_pos", "base_yaw", "ee_pos", "target_pos", "target_vel")

    def __init__(
        self, facts: EnvFacts, config: QPConfig, n: int, seed: int | None, params: Callable[[int], Any], name: str
    ):
        super().__init__(facts, n, seed)
        self.name = self.spec = name
        self.config = c = config
        if c.solver == "daqp":
            self._solve_qp: Callable[..., Any] = daqp_solve_qp
        else:
            import qpsolvers  # a core dependency; imported here so that importing `policies` stays light

            self._solve_qp = qpsolvers.solve_qp
        self._model = ModelJacobians(n, params)
        self._n_arm = m = facts.n_arm
        na = m + 2
        self._P = np.diag(np.r_[np.ones(m), np.full(2, c.wheel_weight), np.full(3, c.slack_weight)])
        self._w = np.diag(self._P)[:na].copy()
        self._A = np.zeros((3, na + 3))
        self._A[:, na:] = np.eye(3)
        self._lb = np.r_[-self._scale, np.full(3, -np.inf)]
        self._ub = np.r_[self._scale, np.full(3, np.inf)]
        self._lower = np.zeros((n, m))
        self._upper = np.zeros((n, m))
        self._q0 = np.zeros((n, m))
        self.last_slack = np.zeros((n, 3))
        self.qp_failures = np.zeros(n, dtype=int)

    @property
    def params(self) -> list[Any]:
        """The `RobotParams` each row solves with this episode (None before its first episode start)."""
        return self._model.params

    def _reset_rows(self, rows: np.ndarray, obs: dict) -> None:
        self._model.load(rows.tolist())
        m = self._n_arm
        for i in rows.tolist():
            p = self._model.params[i]
            if p.n_actuators != m + 2:
                raise ValueError(
                    f"QP was built for {m + 2} actuators (EnvFacts) but its model {p.arm.name} has "
                    f"{p.n_actuators}; build the policy from the env it drives (policies.make(spec, env))"
                )
            self._lower[i], self._upper[i] = p.joint_lower, p.joint_upper
        self._q0[rows] = obs["joint_pos"][rows, :m]
        self.last_slack[rows] = 0.0
        self.qp_failures[rows] = 0

    def bounds(self, q_arm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lb, ub) of u, (N, n + 2) each, at the arm angles `q_arm` (N, n) (rad): the speed limits tightened by
        the joint-limit dampers (`damper_bounds`)."""
        c = self.config
        return damper_bounds(q_arm, self._lower, self._upper, self._scale, c.influence, c.stop, c.damper_gain)

    def _act(self, obs: dict) -> np.ndarray:
        c = self.config
        m = self._n_arm
        na = m + 2
        q = obs["joint_pos"][:, :m]
        J = self._model(obs["joint_pos"], obs["base_yaw"], True)
        v = obs["target_vel"] + c.gamma * (obs["target_pos"] - obs["ee_pos"])
        z = np.zeros((len(q), na))
        if c.posture_gain > 0:
            z[:, :m] = c.posture_gain * (self._q0 - q)
        lb, ub = self.bounds(q)
        f = np.zeros((len(q), na + 3))
        f[:, :na] = -self._w * z
        u = np.empty((len(q), na))
        # a row with a non-finite observation gets NaN (that row's problem: the env refuses it naming the robot),
        # never the solver or LAPACK's least squares, whose error on NaN would fail every row of the batch
        finite = np.isfinite(J).all(axis=(1, 2)) & np.isfinite(v).all(axis=1) & np.isfinite(z).all(axis=1)
        A, lbx, ubx = self._A, self._lb, self._ub
        for i in range(len(q)):
            if not finite[i]:
                u[i] = self.last_slack[i] = np.nan
                continue
            A[:, :na] = J[i]
            lbx[:na], ubx[:na] = lb[i], ub[i]
            x = self._solve_qp(self._P, f[i], A=A, b=v[i], lb=lbx, ub=ubx, solver=c.solver)
            if x is None or not np.all(np.isfinite(x)):
                self.qp_failures[i] += 1
                Ji, vi, zi = J[i], v[i], z[i]
                ui = np.clip(zi + np.linalg.lstsq(Ji, vi - Ji @ zi, rcond=None)[0], lb[i], ub[i])
                self.last_slack[i] = vi - Ji @ ui
                u[i] = ui
                continue
            self.last_slack[i] = x[na:]
            u[i] = x[:na]
        return u


class QP(LawView):
    """Whole-body differential IK as a QP with joint-limit dampers; see the module docstring. The N = 1 case of
    `QPLaw`.

    `QP(facts, config=None, seed=None, *, nominal_params=None, params_provider=None)`: exactly one of the
    two model sources: `nominal_params` (a `RobotParams`, or a callable returning the episode's nominal one: the
    `qp` controller) or `params_provider` (a callable
    returning the current true `RobotParams`, called at every episode start: `qp-oracle`).

    Diagnostics: `last_slack` (s of the last step, m/s), `qp_failures` (steps this episode on which the solver
    gave no solution and the fallback acted).
    """

    name = "qp"

    def __init__(
        self,
        facts: EnvFacts,
        config: QPConfig | None = None,
        seed: int | None = None,
        *,
        nominal_params: Any = None,
        params_provider: Callable[[], Any] | None = None,
        **extra: Any,
    ):
        reject_extra(self, extra, "nominal_params, params_provider")
        if (nominal_params is None) == (params_provider is None):
            raise ValueError(
                "QP needs exactly one model source: nominal_params (a RobotParams, for `qp`) or params_provider "
                "(a callable returning the true RobotParams, for `qp-oracle`)"
            )
        if params_provider is not None and not callable(params_provider):
            raise ValueError("QP's params_provider must be a callable returning the env's current true RobotParams")
        if params_provider is not None:
            name, provider = "qp-oracle", params_provider
        elif callable(nominal_params):  # the nominal robot of each episode (a random arm per reset)
            name, provider = "qp", nominal_params
        else:
            name, provider = "qp", lambda: nominal_params
        self.config = config or QPConfig()
        self._provider = provider  # read through self at each episode start (a test spies on it)
        self.law: QPLaw = QPLaw(facts, self.config, 1, seed, lambda i: self._provider(), name)
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
    ) -> QPLaw:
        """The batched law for n robots (`policies.make(spec, vector_env)`): `nominal_params(i)` (`qp`) or
        `params_provider(i)` (`qp-oracle`) returns row i's model."""
        if (nominal_params is None) == (params_provider is None):
            raise ValueError("QP.batched needs exactly one model source: nominal_params or params_provider")
        if params_provider is not None:
            return QPLaw(facts, config, n, seed, params_provider, "qp-oracle")
        return QPLaw(facts, config, n, seed, nominal_params, "qp")  # type: ignore[arg-type]

    @property
    def knowledge(self) -> str:
        """The knowledge class (`policies.knowledge`): "true" for `qp-oracle` (the worn robot's parameters),
        "nominal" for `qp` (the catalogue's)."""
        return "true" if self.name == "qp-oracle" else "nominal"

    @property
    def params(self) -> Any:
        """The `RobotParams` solved with this episode."""
        return self.law.params[0]

    @property
    def last_slack(self) -> np.ndarray:
        return self.law.last_slack[0]

    @property
    def qp_failures(self) -> int:
        return int(self.law.qp_failures[0])

    @property
    def _solve_qp(self) -> Callable[..., Any]:
        return self.law._solve_qp

    @_solve_qp.setter
    def _solve_qp(self, solve: Callable[..., Any]) -> None:
        self.law._solve_qp = solve

    def bounds(self, q_arm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lb, ub) of u at the arm angles `q_arm` (rad): the speed limits tightened by the joint-limit dampers."""
        lb, ub = self.law.bounds(np.asarray(q_arm, float)[None])
        return lb[0], ub[0]

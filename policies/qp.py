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

Solver: `qpsolvers` with the dense dual active-set solver DAQP (`solver`, default "daqp"): measured on this
problem (11 variables, 3 equalities, box bounds), median solve times 11 us (daqp), 58 us (proxqp), 410 us
(osqp), 530 us (clarabel), all through `qpsolvers.solve_qp`. If the solver returns no solution (none seen on
the development seeds), the step falls back to the damped pseudo-inverse clipped to the bounds and
`qp_failures` counts it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env import kinematics as K
from mobman_env.validation import number
from policies.base import ControllerPolicy, EnvFacts, reject_extra
from policies.jmpi import DEFAULT_GAMMA

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


class QP(ControllerPolicy):
    """Whole-body differential IK as a QP with joint-limit dampers; see the module docstring.

    `QP(facts, config=None, seed=None, *, nominal_params=None, params_provider=None)`: exactly one of the
    two model sources: `nominal_params` (a `RobotParams`, or a callable returning the episode's nominal one: the
    `qp` controller) or `params_provider` (a callable
    returning the current true `RobotParams`, called at every episode start: `qp-oracle`).

    Diagnostics: `last_slack` (s of the last step, m/s), `qp_failures` (steps this episode on which the solver
    gave no solution and the fallback acted).
    """

    name = "qp"
    uses_keys = ("joint_pos", "base_yaw", "ee_pos", "target_pos", "target_vel")

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
        super().__init__(facts, seed)
        import qpsolvers  # a core dependency; imported here so that importing `policies` stays light

        self._solve_qp = qpsolvers.solve_qp
        self.config = c = config or QPConfig()
        if params_provider is not None:
            self.name = "qp-oracle"
            self._provider: Callable[[], Any] = params_provider
        elif callable(nominal_params):  # the nominal robot of each episode (a random arm per reset)
            self._provider = nominal_params
        else:
            self._provider = lambda: nominal_params
        self._n_arm = facts.n_arm
        n = self._n_arm + 2
        self._P = np.diag(np.r_[np.ones(self._n_arm), np.full(2, c.wheel_weight), np.full(3, c.slack_weight)])
        self._w = np.diag(self._P)[:n].copy()
        self._A = np.zeros((3, n + 3))
        self._A[:, n:] = np.eye(3)
        self._lb = np.r_[-self._scale, np.full(3, -np.inf)]
        self._ub = np.r_[self._scale, np.full(3, np.inf)]
        self._ramp = c.damper_gain / (c.influence - c.stop)  # (rad/s) per rad of distance beyond `stop`
        self.params: Any = None
        self.last_slack = np.zeros(3)
        self.qp_failures = 0

    def _reset(self, obs: dict) -> None:
        self.params = self._provider()
        self._lower = np.asarray(self.params.joint_lower, float)
        self._upper = np.asarray(self.params.joint_upper, float)
        if self.params.n_actuators != self._n_arm + 2:
            raise ValueError(
                f"QP was built for {self._n_arm + 2} actuators (EnvFacts) but its model {self.params.arm.name} has "
                f"{self.params.n_actuators}; build the policy from the env it drives (policies.make(spec, env))"
            )
        self._q0 = obs["joint_pos"][: self._n_arm].copy()
        self.last_slack = np.zeros(3)
        self.qp_failures = 0

    def bounds(self, q_arm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lb, ub) of u at the arm angles `q_arm` (rad): the speed limits tightened by the joint-limit dampers."""
        c = self.config
        m = self._n_arm
        n = m + 2
        lb, ub = -self._scale.copy(), self._scale.copy()
        d_up = self._upper - q_arm
        d_lo = q_arm - self._lower
        near_up = d_up < c.influence
        near_lo = d_lo < c.influence
        if near_up.any():
            ub[:m][near_up] = np.minimum(ub[:m][near_up], self._ramp * (d_up[near_up] - c.stop))
        if near_lo.any():
            lb[:m][near_lo] = np.maximum(lb[:m][near_lo], -self._ramp * (d_lo[near_lo] - c.stop))
        # inside the stop distance a damper pushes away; keep every box non-empty and within the speed limits
        ub = np.maximum(ub, -self._scale[:n])
        lb = np.minimum(lb, self._scale[:n])
        return lb, ub

    def _act(self, obs: dict) -> np.ndarray:
        c = self.config
        m = self._n_arm
        n = m + 2
        q = obs["joint_pos"][:m]
        J = K.whole_body_jacobian(self.params, q, float(obs["base_yaw"][0]))
        v = obs["target_vel"] + c.gamma * (obs["target_pos"] - obs["ee_pos"])
        z = np.zeros(n)
        if c.posture_gain > 0:
            z[:m] = c.posture_gain * (self._q0 - q)
        lb, ub = self.bounds(q)
        self._A[:, :n] = J
        self._lb[:n], self._ub[:n] = lb, ub
        f = np.zeros(n + 3)
        f[:n] = -self._w * z
        x = self._solve_qp(self._P, f, A=self._A, b=v, lb=self._lb, ub=self._ub, solver=c.solver)
        if x is None or not np.all(np.isfinite(x)):
            self.qp_failures += 1
            u = z + np.linalg.lstsq(J, v - J @ z, rcond=None)[0]
            self.last_slack = v - J @ np.clip(u, lb, ub)
            return np.clip(u, lb, ub)
        self.last_slack = x[n:]
        return x[:n]

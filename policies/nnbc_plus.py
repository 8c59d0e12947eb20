"""`nnbc-plus`: a model-free controller that keeps NNBC's promise (no kinematic model, only measurements) and
tracks every task: the Jacobian is a moving state estimated by a Kalman filter, not a rank-one ZNN update.

Why the paper's NNBC fails
--------------------------
u = J_hat^+ v lies in the row space of J_hat, and eq. (15) adds only multiples of u^T to J_hat, so the row
space fixed by J_hat(0) never changes: only the direction of the current u is ever re-learnt, the others go
stale as the arm moves, and J_hat's smallest singular value collapses while the true one does not.

What this controller does (per control step, numpy on 3x8 and 16x16 matrices)
-------------------------------------------------------------------------------
1. **Measure** one linear equation per task axis: y = J(t_k) x, with x the measured actuator speeds
   (`joint_vel`, 8) and y the measured end-effector velocity (`ee_vel`, 3; minus `[arm_base_vel; 0]` in the
   paper's formulation). Nothing is differentiated, so position noise never reaches the estimator. With
   `measurement="position"` they are finite differences of `joint_pos` and `ee_pos` over the last step
   instead (y = (r_a(t_k) - r_a(t_k-1))/dt against x = (q(t_k) - q(t_k-1))/dt, which holds at the interval's
   middle), for sensor sets without velocities; that variant needs clean positions (1 mm of noise on ee_pos
   is 0.14 m/s on y).
2. **Estimate** J and its time rate J_dot jointly: each of the 3 rows of [J | J_dot] is the state of a linear
   Kalman filter with a constant-velocity model (J(t + dt) = J(t) + dt J_dot(t)) driven by random-walk process
   noise (`q_jacobian`, `q_rate`); the three rows see the same regressor, so they share one 16x16 covariance
   and one gain. Every direction of J follows the arm, not only the current u's. Exponential `forgetting` is
   available instead of (or with) the process noise; it was measured worse in physics mode (module README).
   A robust update (`innov_clip`) shortens single-step outliers of the innovation.
3. **Excite** the directions the task does not use: a random-sign dither (`dither`, rad/s) projected into the
   null space of J_hat, so it moves the actuators but (when J_hat is right) not the end-effector. Without it the
   unexcited directions of J go stale and the estimate fails (measured). `task_dither` excites J's row space
   too, with a zero-mean two-step task-space excitation (+d on one step, -d on the next, so the end-effector
   comes back): at 2 mm/s it costs no measurable tracking error and keeps the row-space estimate within a few
   percent of the true J (without it the path's own motion leaves 20-50% errors there, which the feedback
   hides but which leave less margin).
4. **Control** with the estimate extrapolated half a step (the command is held over [t_k, t_k+1]):
   u = z + J_c^+ (v - J_c z), v = r_d_dot(t_k + dt/2) + gamma (r_d - r_hat_a), J_c = J_hat + dt/2 J_dot_hat,
   J_c^+ a damped (`damping`) pseudo-inverse, z the null-space motion: dither plus a pull of the 6 arm joints
   back to their angles at the episode start (`posture_gain`). The pull keeps the arm away from its reach
   limit, its joint limits and the singularities around them and lets the platform drive (Line-v0 is 3 m
   long): without it joint 1 runs into its limit on some circles. r_hat_a is the measured ee_pos after a
   complementary filter (`pos_filter`) that advances it by the measured motion and pulls it towards the
   measurement, so position noise is attenuated in the feedback.
5. **J_hat(0)** comes from a short probe at the start: each actuator in turn at +probe_speed for one step,
   then -probe_speed (back to where it was), 16 steps = 0.16 s at 100 Hz, counted in the episode like every
   other step; J_hat(0) is the least-squares fit of the measured (x, y) pairs. `j0_noise` perturbs it by a
   random matrix of that fraction of its Frobenius norm, drawn from the controller's own RNG (robustness test).

The controller reads only `EnvFacts` (dt, action scale) and observations: no `RobotParams`, no kinematics.

One scaffolding, several estimators
-----------------------------------
Steps 1, 3, 4 and 5 (measurement, excitation, control law, probe) are `EstimatingController`; step 2 is an
estimator object behind the interface of `policies.estimators` (`reset`, `init(J0)`, `update(x, y)`, `J`,
`Jdot`). `nnbc-plus` is the scaffolding with the Kalman filter (`KalmanEstimator`); `broyden` and `rls`
(`policies.broyden_rls`) are the same scaffolding with Broyden's secant update and recursive least squares, so
comparisons between them isolate the estimator. The shared options are the fields of `ModelFreeConfig`;
`NNBCPlusConfig` adds the Kalman filter's.

The estimate is exposed as `jacobian_estimate` (3 x 8, m/rad: joint_vel in rad/s to task velocity in m/s):
the whole-body Jacobian d r_a / d u (formulation "whole_body") or the paper's J of eq. (6), the map to
r_a_dot - [p_c_dot; 0] ("paper"); `jacobian_kind` says which. None during the probe.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from mobman_env.validation import number
from policies.base import ControllerPolicy, EnvFacts
from policies.estimators import JacobianEstimator, KalmanEstimator

FORMULATIONS = ("whole_body", "paper")
MEASUREMENTS = ("velocity", "position")


N_ACT = 8
N_PROBE = 2 * N_ACT  # probe steps: actuator i at +probe_speed on step 2i, at -probe_speed on step 2i + 1
_SIGN_BLOCK = 256  # random dither signs are drawn this many steps at a time (one RNG call)


@dataclass(frozen=True)
class ModelFreeConfig:
    """Options of the shared scaffolding (probe, excitation, control law) of `nnbc-plus`, `broyden` and `rls`;
    defaults tuned on development seeds 0-999 only (see the module docstring)."""

    gamma: float = 20.0
    """Task-space feedback gain, 1/s: v = r_d_dot + gamma (r_d - r_a) (the paper's gamma)."""
    formulation: str = "whole_body"
    """"whole_body": J_hat maps u to the whole r_a_dot (the platform's translation is learnt, so it can drive);
    "paper": J_hat maps u to r_a_dot - [p_c_dot; 0] and the measured p_c_dot is subtracted in the control law, as
    in the paper's eq. (11)."""
    measurement: str = "velocity"
    """"velocity": learn from the measured ee_vel (and arm_base_vel) against joint_vel at t_k; "position": from
    finite differences of ee_pos (arm_base_pos) against joint_pos over the last step (for sensor sets without
    velocities)."""
    damping: float = 3e-4
    """Damping of the pseudo-inverse, m^2/rad^2: added to J_c W J_c^T before inversion (bounds the speeds near a
    singularity of J_hat; it costs at most damping / sigma_min^2 of the commanded task velocity)."""
    dither: float = 0.05
    """Amplitude of the random-sign excitation, rad/s per actuator, projected into J_hat's null space by the
    control law (it moves the actuators, not the end-effector); new signs every step (0 turns it off)."""
    task_dither: float = 0.002
    """Amplitude of a zero-mean task-space excitation, m/s: a random direction (each component +-task_dither)
    added to v on one step and subtracted on the next, so the end-effector comes back (displacement <=
    task_dither * dt) while the directions of J's row space that the path does not use are still excited."""
    posture_gain: float = 2.0
    """Null-space pull of the 6 arm joints back to their angles at the episode start, 1/s (0 turns it off)."""
    weighting: str = "none"
    """Actuator weights W of the pseudo-inverse u = W J^T (J W J^T + damping I)^-1 v: "none" (W = I) or
    "scale" (W = diag(action_scale^2) / max: fast actuators, i.e. the wheels, take more of the motion; measured
    much worse: the platform's slow-to-steer motion then does most of the tracking)."""
    probe_speed: float = 0.05
    """Probe amplitude, rad/s (one step at + then one at - per actuator)."""
    j0_noise: float = 0.0
    """Perturb the probed J_hat(0) by a random Gaussian matrix scaled to j0_noise * ||J_hat(0)||_F (robustness
    test); drawn from the controller's RNG."""
    pos_filter: float = 0.1
    """Weight of the measured position in the fed-back end-effector position, 0 < pos_filter <= 1: each step
    the estimate is advanced by the measured motion (dt * ee_vel, or J_hat dq with `measurement="position"`) and
    pulled by pos_filter towards the measured ee_pos (a complementary filter; 1 = raw measurement). Below 1 it
    filters sensor noise (`obs_noise`) out of the feedback."""
    lookahead: bool = True
    """Control with J_hat and r_d_dot extrapolated half a step (the command is held for the whole step)."""

    def __post_init__(self):
        if self.formulation not in FORMULATIONS:
            raise ValueError(f"formulation must be one of {FORMULATIONS}, got {self.formulation!r}")
        if self.measurement not in MEASUREMENTS:
            raise ValueError(f"measurement must be one of {MEASUREMENTS}, got {self.measurement!r}")
        if self.weighting not in ("none", "scale"):
            raise ValueError(f"weighting must be 'none' or 'scale', got {self.weighting!r}")
        name = type(self).__name__
        for f in fields(self):
            if f.type in ("float", float):  # spec strings may give ints ("gamma=20"): stored as float
                object.__setattr__(self, f.name, number(f"{name}.{f.name}", getattr(self, f.name), low=0.0))
        number(f"{name}.pos_filter", self.pos_filter, low=0.0, open_low=True, high=1.0)


@dataclass(frozen=True)
class NNBCPlusConfig(ModelFreeConfig):
    """Gains of `NNBCPlus`: the scaffolding's (`ModelFreeConfig`) and the Kalman filter's; defaults tuned on
    development seeds 0-999 only (see the module docstring)."""

    forgetting: float = 1.0
    """Exponential forgetting of the Kalman filter per control step (0 < forgetting <= 1): the covariance is
    divided by it at every prediction, so old data fade with a time constant of dt / (1 - forgetting); 1 = off
    (the default: the process noise below keeps the estimate fresh instead). 0.92 (without process noise)
    measured as good with the default excitation; without the task-space dither it lost a physics episode
    (development seed 93, Random-v0) that the process-noise model kept."""
    q_jacobian: float = 1e-6
    """Process noise: variance added to each J_hat entry per step, (m/rad)^2 (J_hat may drift about 1 mm/rad per
    step beyond what its rate predicts)."""
    q_rate: float = 2e-3
    """Process noise: variance added to each J_dot_hat entry per step, (m/rad/s)^2 (the rate may change by about
    0.045 m/rad/s per step, i.e. J_ddot up to a few m/rad/s^2)."""
    meas_std: float = 1e-3
    """Standard deviation assumed for one measured end-effector velocity component, m/s (the Kalman filter's R).
    Set it to the velocity sensor's noise: with `obs_noise_vel` = 0.01 m/s, 1e-3 fails in physics mode and 0.01
    tracks (measured); without velocity noise 0.01 makes J_hat lag when J changes fast (a physics Lemniscate-v0
    episode lost, development seed 134) and leaves 10-20% row-space errors instead of 1-5%."""
    innov_clip: float = 4.0
    """Robust update: an innovation (measured minus predicted task velocity) longer than innov_clip times the
    running RMS of the recent innovations is shortened to that length before it updates J_hat (0 turns it off).
    Single-step violations of y = J x (a platform jolt in physics mode: seen as 20-30 mm/s one-step residuals)
    are damped, while a truly changed J (the RMS grows quickly) is still learnt. A safeguard: no measured effect
    on the development seeds."""
    innov_rate: float = 0.05
    """Per-step weight of the newest (clipped) innovation in the running mean square that `innov_clip` uses."""
    p0_jacobian: float = 1.0
    """Initial covariance of each J_hat entry, (m/rad)^2: how far the probed J_hat(0) is trusted."""
    p0_rate: float = 1.0
    """Initial covariance of each J_dot_hat entry, (m/rad/s)^2."""
    p_max: float = 1.0
    """Upper bound on the covariance trace (divided by the 16 states), applied when forgetting < 1: stops the
    forgetting from winding it up when the excitation is poor (the process noise alone keeps P bounded)."""

    def __post_init__(self):
        number("NNBCPlusConfig.forgetting", self.forgetting, low=0.0, open_low=True, high=1.0)
        super().__post_init__()


def _solve3(A: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve the 3x3 system A x = rhs by cofactors in plain floats (several times faster than np.linalg.solve
    at this size; A = J W J^T + damping I is symmetric positive definite)."""
    (a, b, c), (d, e, f), (g, h, i) = A.tolist()
    p, q, r = rhs.tolist()
    c00, c01, c02 = e * i - f * h, c * h - b * i, b * f - c * e
    c10, c11, c12 = f * g - d * i, a * i - c * g, c * d - a * f
    c20, c21, c22 = d * h - e * g, b * g - a * h, a * e - b * d
    inv_det = 1.0 / (a * c00 + b * c10 + c * c20)
    return np.array(
        [
            (c00 * p + c01 * q + c02 * r) * inv_det,
            (c10 * p + c11 * q + c12 * r) * inv_det,
            (c20 * p + c21 * q + c22 * r) * inv_det,
        ]
    )


class EstimatingController(ControllerPolicy):
    """The model-free scaffolding (probe, measurement, excitation, control law) around a Jacobian estimator.

    Subclasses set `config_cls` and implement `_make_estimator()`; everything else is shared. After each step:
    `J_hat` and `Jdot_hat` (3 x 8) are the estimator's current J and J_dot, `estimator` the estimator object,
    `last_u` the issued command (rad/s), `jacobian_estimate` a copy of J_hat (None during the probe).
    """

    name = "estimating-controller"
    config_cls: type[ModelFreeConfig] = ModelFreeConfig

    def __init__(self, facts: EnvFacts, config: ModelFreeConfig | None = None, seed: int | None = None, **extra: Any):
        cls = type(self).__name__
        if extra:
            raise TypeError(
                f"{cls} takes no extra arguments (it is model-free: EnvFacts and observations only), got "
                f"{sorted(extra)}"
            )
        super().__init__(facts, seed=seed)
        # the actuator count from the env's facts (n arm joints + 2 wheels), not the module's N_ACT (the PUMA's)
        self._n_act = n_act = facts.n_actuators
        self._n_probe = 2 * n_act
        if config is None:
            config = self.config_cls()
        if not isinstance(config, self.config_cls):
            raise TypeError(f"config must be a {self.config_cls.__name__}, got {type(config).__name__}")
        self.config = c = config
        self._dt = facts.dt
        self._w = self._scale**2 / np.max(self._scale**2) if c.weighting == "scale" else np.ones(n_act)
        self._damp = c.damping * np.eye(3)
        self._whole = c.formulation == "whole_body"
        self._use_vel = c.measurement == "velocity"
        self.jacobian_kind = "whole_body" if self._whole else "paper"
        self.estimator: JacobianEstimator = self._make_estimator()
        self._k = 0

    def _make_estimator(self) -> JacobianEstimator:
        raise NotImplementedError

    @property
    def J_hat(self) -> np.ndarray:
        return self.estimator.J

    @property
    def Jdot_hat(self) -> np.ndarray:
        return self.estimator.Jdot

    @property
    def jacobian_estimate(self) -> np.ndarray | None:
        """The estimated Jacobian (3 x 8, m/rad: actuator speeds in rad/s to task velocity in m/s) at the time
        of the last observation: the whole-body Jacobian, or the paper's J of eq. (6) with
        `formulation="paper"` (`jacobian_kind`). None before the probe has finished."""
        return self.estimator.J.copy() if self._initialised and self._k > self._n_probe else None

    # --- episode start ---------------------------------------------------------------------------------
    def _reset(self, obs: dict) -> None:
        self._k = 0
        q = obs["joint_pos"]
        self._q0 = q[: self._n_act - 2].copy()
        self._probe_x: list[np.ndarray] = []
        self._probe_y: list[np.ndarray] = []
        self._prev_q = q.copy()
        self._prev_s = self._task_pos(obs)
        self._s_f = self._prev_s.copy()
        self._prev_vd = obs["target_vel"].copy()
        self._td: np.ndarray = np.zeros(3)
        self._signs: np.ndarray = np.empty((0, self._n_act))
        self.estimator.reset()

    def _task_pos(self, obs: dict) -> np.ndarray:
        """The position J_hat's output integrates to: r_a (whole body) or r_a - [p_c; 0] (paper)."""
        r = obs["ee_pos"]
        if self._whole:
            return r.copy()
        pc = obs["arm_base_pos"]
        return np.array([r[0] - pc[0], r[1] - pc[1], r[2]])

    def _measure(self, obs: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, ds): actuator speeds (8) and task velocity (3) with y = J x (see `measurement`), and the task
        motion over the last step for the position filter."""
        q = obs["joint_pos"]
        s = self._task_pos(obs)
        if self._use_vel:
            x = obs["joint_vel"]
            y = obs["ee_vel"]
            if not self._whole:
                v = obs["arm_base_vel"]
                y = np.array([y[0] - v[0], y[1] - v[1], y[2]])
            ds = self._dt * y
        else:
            dq = q - self._prev_q
            x = dq / self._dt
            y = (s - self._prev_s) / self._dt
            ds = self.estimator.J @ dq
        self._prev_q = q.copy()
        self._prev_s = s
        a = self.config.pos_filter
        self._s_f += ds
        self._s_f += a * (s - self._s_f)
        return x, y, ds

    def _finish_probe(self) -> None:
        """J_hat(0): least squares over the probe's (x, y) pairs; J_dot_hat(0) = 0."""
        X = np.array(self._probe_x).T  # (8, n)
        Y = np.array(self._probe_y).T  # (3, n)
        A = X @ X.T
        tr = np.trace(A)
        if tr > 0:
            J0 = np.linalg.solve(A + 1e-9 * tr / self._n_act * np.eye(self._n_act), X @ Y.T).T
        else:  # no actuator moved during the probe (e.g. the same observation fed again and again): no information
            J0 = np.zeros((3, self._n_act))
        if self.config.j0_noise > 0:
            noise = self.rng.standard_normal(J0.shape)
            J0 = J0 + self.config.j0_noise * np.linalg.norm(J0) / np.linalg.norm(noise) * noise
        self.estimator.init(J0)

    # --- one step --------------------------------------------------------------------------------------
    def _act(self, obs: dict) -> np.ndarray:
        k = self._k
        self._k = k + 1
        c = self.config
        x, y, _ = self._measure(obs)
        if k <= self._n_probe:
            if k > 0:
                self._probe_x.append(np.array(x, dtype=float))
                self._probe_y.append(np.array(y, dtype=float))
            if k < self._n_probe:
                self._prev_vd = obs["target_vel"].copy()
                u = np.zeros(self._n_act)
                u[k // 2] = c.probe_speed if k % 2 == 0 else -c.probe_speed
                return u
            self._finish_probe()
        else:
            self.estimator.update(x, y)
        # --- control: u = z + J_c^+ (v - J_c z)
        J, Jdot = self.estimator.J, self.estimator.Jdot
        vd = obs["target_vel"]
        if c.lookahead:
            Jc = J + (0.5 * self._dt) * Jdot
            v = 1.5 * vd - 0.5 * self._prev_vd  # r_d_dot half a step ahead
        else:
            Jc = J
            v = vd.copy()
        self._prev_vd = vd.copy()
        s_d = obs["target_pos"]
        if not self._whole:
            pc, pv = obs["arm_base_pos"], obs["arm_base_vel"]
            s_d = np.array([s_d[0] - pc[0], s_d[1] - pc[1], s_d[2]])
            v[0] -= pv[0]
            v[1] -= pv[1]
        v += c.gamma * (s_d - self._s_f)
        if c.task_dither > 0:
            if k % 2 == 0:
                self._td = c.task_dither * (2.0 * self.rng.integers(0, 2, 3) - 1.0)
                v += self._td
            else:
                v -= self._td
        z = np.zeros(self._n_act)
        if c.dither > 0:
            if not len(self._signs):
                self._signs = 2.0 * self.rng.integers(0, 2, (_SIGN_BLOCK, self._n_act)) - 1.0
            z += c.dither * self._signs[0]
            self._signs = self._signs[1:]
        if c.posture_gain > 0:
            z[: self._n_act - 2] -= c.posture_gain * (obs["joint_pos"][: self._n_act - 2] - self._q0)
        JW = Jc * self._w
        lam = _solve3(JW @ Jc.T + self._damp, v - Jc @ z)
        return z + JW.T @ lam


class NNBCPlus(EstimatingController):
    """Model-free Jacobian control with a Kalman-filtered (J, J_dot) estimate; see the module docstring.

    After each step: `J_hat` (3x8) and `Jdot_hat` (3x8) are the current estimates, `P` the shared 16x16
    covariance (in the units of one row of [J | J_dot]), `last_u` the issued command (rad/s).
    """

    name = "nnbc-plus"
    config_cls = NNBCPlusConfig
    Config = NNBCPlusConfig

    def _make_estimator(self) -> KalmanEstimator:
        c = self.config
        assert isinstance(c, NNBCPlusConfig)
        return KalmanEstimator(
            self._n_act,
            self._dt,
            q_jacobian=c.q_jacobian,
            q_rate=c.q_rate,
            meas_std=c.meas_std,
            innov_clip=c.innov_clip,
            innov_rate=c.innov_rate,
            p0_jacobian=c.p0_jacobian,
            p0_rate=c.p0_rate,
            forgetting=c.forgetting,
            p_max=c.p_max,
            midpoint=not self._use_vel,
            sym_phase=self._n_probe + 1,
        )

    @property
    def P(self) -> np.ndarray:
        """The Kalman filter's shared 16 x 16 covariance."""
        return self.estimator.P  # type: ignore[attr-defined]

    @property
    def X(self) -> np.ndarray:
        """[J_hat | J_dot_hat] (3 x 16), the Kalman filter's state."""
        return self.estimator.X  # type: ignore[attr-defined]

"""`calib-qp`: the whole-body QP of `qp` on a robot model calibrated online from the catalogue: the adaptive baseline.

The law is `qp`'s (`policies.laws.qp.QPLaw`, unchanged: the same QP, bounds, dampers and posture term); what changes is
the model whose whole-body Jacobian it solves with. `CalibQPLaw` subclasses `QPLaw`, and before each of its steps
writes the current estimate of the robot's lengths into the packed model rows of the law's
`policies.kernels.shared.ModelJacobians` (`ModelJacobians.arm`, `.prm`: a calibrated model is the same chain with other
numbers in its row). The rows start from the catalogue (`nominal_params`, read at every episode start: for the
random arm family, the episode's drawn design) and are calibrated from the measured end-effector and mount
positions and velocities, the heading and the joint readings. May import numpy, numba, `mobman_env` (engine,
params, validation, numba_cache) and `policies.base`, `.batched`, `.qp`.

Knowledge class `nominal` (DESIGN, release 0.4; labelled `structure` in 0.3): the estimator reads the catalogue,
the object class `nominal` reads (`policies.views`): the kind of chain (its joint axes, twists and offsets, which DH
lengths are non-zero), that the platform is a unicycle carrying the arm at a sensed mount, the shoulder height,
and the catalogue's values as the prior of its lengths (`prior_rel_std` relative uncertainty, which the data
overrule within the episode). It learns every worn length; its class is what it is built from, not what it keeps.

What is estimated, per robot (row)
----------------------------------
* The arm: theta = the nominal arm's `length_slots` (every non-zero DH a, every non-zero d, the tool; the PUMA's
  a2, a3, d3, d4, tool; 8 for the Panda). With the joint angles q fixed, the arm point f(q; theta) in frame 0 is
  LINEAR in theta (the frames' rotations do not depend on the lengths; each length moves the origin along one
  axis), so f = Phi(q) theta, where column j of Phi is the arm point of this arm with length j = 1 and every other
  length 0. Phi comes from the engine's own chain (`mobman_env.engine.arm_points`) on "unit rows" packed at the
  episode start, one batched call per step for every column of every row. The measurement is
  f_meas = R(-yaw) (ee_pos - [arm_base_pos; h]), with h the shoulder height (not worn). Lengths along one axis
  (the Panda's d7 and tool, both along z7) are seen only as their sum: the filter splits it as the prior says,
  which changes nothing in the kinematics. Directions the path does not excite keep their prior (a straight
  line hardly turns the platform, so r / (2 b) learns little there).
* The platform, as the three numbers its Jacobian columns depend on: alpha = r / 2, beta = r / (2 b) and
  gamma = d beta (the wheel columns of the whole-body Jacobian involve r, b and d only through them). In the
  platform frame the measured mount velocity `arm_base_vel` is [v; d yaw_rate] = [alpha (w_l + w_r);
  gamma (w_r - w_l)]: two scalar updates. The wheel speeds are the wheel angles' changes over the last step
  (`joint_pos`, encoders) divided by dt, not `joint_vel`: noise on a regressor biases a least-squares estimate
  towards zero, and the platform's wheel speeds are small in these tasks, so with `obs_noise_joint_vel` 0.05
  rad/s the `joint_vel` regressors shrank r and the median max error at 20% wear went from 0.057 to 1.0 mm
  (worst 2.9 mm; `qp-oracle` 0.042 mm); with the angles' changes noise on `joint_vel` changes nothing, and an
  actuator lag (`actuator_tau` 0.02 s: the change is the mean speed over the step, the mount velocity the last)
  tracks as `qp-oracle` does (0.20 / 0.52 mm against 0.21 / 0.53 mm). The lateral one uses the yaw rate the
  wheels predict, so it estimates gamma, the product the Jacobian needs, directly; a yaw rate measured by
  differencing `base_yaw` carries sqrt(2) obs_noise_yaw / dt of noise (0.14 rad/s at 1 mrad, against yaw rates
  of 0.1-0.5 rad/s): fitted on recorded episodes, d was 0.1% off the wheel-predicted way and 31% (median) the
  measured way at 1 mrad, equal without heading noise (`docs/results/calib-qp/dev.md`). beta comes from the
  heading: a two-state Kalman filter on (heading psi, beta) with psi_k = psi_k-1 + beta (W_k - W_k-1), W = the
  right less the left wheel angle (`joint_pos`), the measured `base_yaw` = psi + noise. It uses the heading's
  level, not its differences: with `obs_noise_yaw` 5 mrad (and 3 mm, 0.03 m/s, 0.05 rad/s on the other sensors),
  a regression of the per-step heading changes (noise twice the heading's, correlated from step to step) left
  beta 88% wrong after 4 s of a Circle-v0 episode (development seed 0, 20% wear; `prior_rel_std` 0.2 then), the
  filter 1.4%. The estimate is written into the row as (r, b, d) = (2 alpha, alpha / beta, gamma / beta), only
  while alpha and beta are positive (a guard; never seen to act).

The estimator
-------------
A Kalman filter on parameters that follow a random walk (recursive least squares with additive process noise):
prior mean the catalogue's value L0, prior variance (`prior_rel_std` L0)^2 (beta a ratio of two lengths and gamma
of three: 2 and 3 times that relative variance); measurement noise variances from `pos_std` (2 pos_std^2 on the
horizontal components of f_meas, the end-effector's and the mount's noise; pos_std^2 on the vertical one),
`vel_std` and `yaw_std`; process noise (`drift` L0)^2 dt per control step. The three components of f_meas are
taken as three scalar updates in a row (equal to the joint update for independent noise), so no matrix is
inverted. No variance is allowed above its prior (the covariance is scaled back where it would be: a
parameter never seen long enough is no less certain than the catalogue).

Why process noise and not a forgetting factor (measured on development seeds 0-9, the four PUMA tasks, kinematic
mode, with `prior_rel_std` 0.2 at the time): under `wear_rate` 0.005 1/s a forgetting factor (0.999, or none)
let the arm estimate wander 100-250 mm along the directions the path hardly excites (a few mm of drift between
early and late measurements, divided by a small change of Phi), median max error 0.69-0.73 mm, on Lemniscate-v0
worse than `qp` (1.4 against 0.95 mm); forgetting scales the covariance, so the least excited directions grow
most and absorb the drift. Additive process noise grows every direction alike: with `drift` = 0.005 the median
max error was 0.26 mm (`qp-oracle`, which reads the robot of t = 0, 0.62 mm), while a forgetting factor of
0.999 gained 0.008 mm at 20% wear without drift. The forgetting factor was deleted (`docs/results/calib-qp/dev.md`
keeps these figures, and those of every option's choice).

Cost and the batch
------------------
The updates are one per-row scalar kernel (`calibrate_rows`, `@njit(cache=True)`, no matrix product: the sums
are written out), looped over the rows, so row i of a batch equals the single policy (`CalibQP`, the N = 1 view)
bit for bit. The calibration (`calibrate`: the unit rows' chain and the kernel) costs about 5.5 us per single
`predict` and 1.5 us per row at N = 64, against 28-72 us per row for the rest of `qp`'s step (the QP, solved row
by row; thread CPU time, medians, on a shared 2-core x86-64 machine), so it runs every step: updating every k
steps would save at most a tenth of the step.

Diagnostics per row: `theta` (N, 2n + 1): the arm lengths in `length_slots` order (the first `n_lengths[i]`
entries), `platform` (N, 3): alpha, beta, gamma; `estimated_params(i)`: the estimate as a `RobotParams`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env import engine as E
from mobman_env.numba_cache import njit
from mobman_env.params import slot_name
from mobman_env.validation import number
from policies.base import EnvFacts, reject_extra
from policies.batched import LawView
from policies.laws.qp import QPConfig, QPLaw

#: The platform numbers `CalibQPLaw.platform` holds, in order: alpha = r / 2 (m), beta = r / (2 b), gamma = d beta (m).
PLATFORM = ("alpha", "beta", "gamma")


@dataclass(frozen=True)
class CalibQPConfig(QPConfig):
    """Options of `calib-qp`: those of `qp` (`policies.laws.qp.QPConfig`: gain, weights, dampers, solver) and of the
    online calibration. Spec keys: `calib-qp:drift=0.01,pos_std=0.003,...`. Set the three noise stds to your
    sensors' (the env's `obs_noise`, `obs_noise_vel`, `obs_noise_yaw`)."""

    prior_rel_std: float = 0.4
    """Relative std of the prior on each length around the catalogue's value (1), and the ceiling of every
    variance: wide enough to cover the worn robots (`model_error` < 1/3). Measured (`docs/results/calib-qp/dev.md`,
    median / worst max error, mm): at 20% wear 0.159 / 0.55 with 0.05, 0.069 / 0.22 with 0.2, 0.057 / 0.155 with
    0.4, 0.049 / 0.104 with 1.0 (30% wear: 0.249 / 0.82, 0.095 / 0.36, 0.067 / 0.25, 0.060 / 0.22); wider
    priors gain less than 0.01 mm beyond 0.4 while the drift condition loses a little (0.264 with 0.4, 0.274
    with 1.0) and a prior of 100% no longer keeps a length off zero; equal with sensor noise."""
    pos_std: float = 1e-3
    """Std of the position sensors (`ee_pos`, `arm_base_pos`), m: the arm's measurement noise. Measured at 20%
    wear with 1 mm and 0.01 m/s noise: 1e-4 trusts the noise (median / worst 2.34 / 5.80 mm), 1e-3 and 1e-2
    track as `qp-oracle` (1.43 / 1.69 mm; `qp-oracle` 1.42 / 1.66); without noise 1e-2 learns slower (0.067 /
    0.32 mm against 0.057 / 0.155 mm with 1e-3)."""
    vel_std: float = 1e-2
    """Std of the mount velocity sensor (`arm_base_vel`), m/s: the measurement noise of r / 2 and d r / (2 b).
    Measured at 20% wear: 0.1 learns slower (median / worst 0.123 / 0.38 mm against 0.057 / 0.155 mm); 1e-3
    tracks within 0.003 mm of 1e-2 with and without the 0.01 m/s noise, and under drift."""
    yaw_std: float = 5e-3
    """Std of the heading sensor (`base_yaw`), rad: the measurement noise of r / (2 b)'s filter. Measured at 20%
    wear with `obs_noise_yaw` 5 mrad (a poor sensor): median / worst max error 0.37 / 1.13 mm with 1e-4, 0.102 /
    0.51 with 1e-3, 0.081 / 0.186 with 5e-3, 0.080 / 0.188 with 2e-2 (`qp-oracle` 0.067 / 0.159); without
    heading noise every value tracks alike (0.057 / 0.155), so the default assumes the poor sensor."""
    drift: float = 0.005
    """Random-walk intensity of every length relative to its catalogue value, 1/sqrt(s): the process noise that
    lets the estimate follow a robot that changes during the episode (`wear_rate`). Measured under `wear_rate`
    0.005 1/s (5% wear), median / worst max error: 0.77 / 2.76 mm with 0 (old data trusted forever; `qp` 0.83 /
    1.74, `qp-oracle` 0.62 / 0.88), 0.31 / 0.42 with 0.001, 0.26 / 0.33 with 0.005, 0.25 / 0.30 with 0.02; at
    20% wear without drift 0.051 / 0.12, 0.051 / 0.13, 0.057 / 0.155 and 0.082 / 0.30 mm."""

    def __post_init__(self) -> None:
        super().__post_init__()
        for name in ("prior_rel_std", "pos_std", "vel_std", "yaw_std"):
            object.__setattr__(
                self,
                name,
                number(
                    f"CalibQPConfig.{name}",
                    getattr(self, name),
                    low=0.0,
                    open_low=True,
                    hint="a standard deviation; a zero one would make the filter trust a prior or a sensor exactly",
                ),
            )
        drift = number("CalibQPConfig.drift", self.drift, low=0.0, hint="1/sqrt(s); 0 turns the process noise off")
        object.__setattr__(self, "drift", drift)


@njit(cache=True)
def _update_scalar(x, y, r, qf, est, var, cap, i, k):
    """One step of the scalar filter of est[i, k] (variance var[i, k], prior variance cap[i, k]) on the measurement
    y = x est + noise of variance r, after the process noise qf cap[i, k]; the variance stays <= cap[i, k]."""
    p = var[i, k] + qf * cap[i, k]
    den = x * x * p + r
    g = p * x / den
    est[i, k] += g * (y - x * est[i, k])
    var[i, k] = min(p - g * x * p, cap[i, k])


@njit(cache=True, inline="always")
def _finite_row(ee, pc, pc_vel, yaw, jp, i):
    """Whether row i's measurements (end-effector, mount position and velocity, heading, joints) are all finite."""
    ok = math.isfinite(yaw[i])
    for a in range(3):
        ok = ok and math.isfinite(ee[i, a])
    for a in range(2):
        ok = ok and math.isfinite(pc[i, a]) and math.isfinite(pc_vel[i, a])
    for a in range(jp.shape[1]):
        ok = ok and math.isfinite(jp[i, a])
    return ok


@njit(cache=True)
def calibrate_rows(
    points, start, count, code, ee, pc, pc_vel, yaw, jp, dt, theta, P, cap, plat, pvar, pcap, head,
    r_pos, r_vel, r_yaw, qf, arm, prm,
):  # fmt: skip
    """One calibration step of every row (see the module docstring), the estimates written into the model rows
    `arm`, `prm` (N rows, `mobman_env.engine`'s layout).

    points (K, 3): the unit rows' arm points (column j of row i's Phi is points[start[i] + j], j < count[i]);
    code (K,): which length each unit row is (k < n: a_k; n + k: d_k; 2n: the tool); ee (N, 3), pc (N, 2),
    pc_vel (N, 2), yaw (N,), jp (N, n + 2): the observation; dt: the control period (s); theta (N, kmax),
    P (N, kmax, kmax), cap (N, kmax): the arm's estimate, covariance and prior variances; plat, pvar, pcap (N, 3):
    alpha, beta, gamma, their variances and prior variances; head (N, 6): beta's filter (heading, its variance,
    its covariance with beta), the last left and right wheel angles, and 1 after a skipped step (else 0);
    r_pos, r_vel, r_yaw: the noise variances; qf: process noise per step as a fraction of the prior variance.

    A row whose measurements are not all finite (a NaN or inf reading) is skipped: a measurement that is not a
    number carries no information, so its estimates stay as they are (a NaN once made the whole row NaN for the
    rest of the episode, and the model's Jacobian with it). The row keeps its last wheel angles; on its next
    finite step the heading filter uses their whole change (exact over any number of steps) while alpha and
    gamma wait a step (the angles' change no longer measures one step's wheel speeds)."""
    nrow = ee.shape[0]
    n = arm.shape[2] - 2
    g = np.empty(theta.shape[1])
    for i in range(nrow):
        if not _finite_row(ee, pc, pc_vel, yaw, jp, i):
            head[i, 5] = 1.0
            continue
        c, s = math.cos(yaw[i]), math.sin(yaw[i])
        _arm_update(i, c, s, n, points, start, count, code, ee, pc, theta, P, cap, r_pos, qf, arm, prm, g)
        _platform_update(i, c, s, n, pc_vel, yaw, jp, dt, plat, pvar, pcap, head, r_vel, r_yaw, qf)
        al, be, ga = plat[i, 0], plat[i, 1], plat[i, 2]
        if al > 0.0 and be > 0.0:  # else the row keeps its last platform (never seen: a guard against r, b <= 0)
            prm[i, E.P_R] = 2.0 * al
            prm[i, E.P_B] = al / be
            prm[i, E.P_MNT] = ga / be


@njit(cache=True, inline="always")
def _arm_update(i, c, s, n, points, start, count, code, ee, pc, theta, P, cap, r_pos, qf, arm, prm, g):
    """Row i's arm lengths: one Kalman update per axis of the end-effector's offset from the mount in the
    platform's frame (heading cos c, sin s), the ceiling (no length less certain than its prior), and the
    estimates written into the model row. g: scratch of length kmax."""
    dx, dy, dz = ee[i, 0] - pc[i, 0], ee[i, 1] - pc[i, 1], ee[i, 2] - prm[i, E.P_H]
    kk = count[i]
    o = start[i]
    for j in range(kk):
        P[i, j, j] += qf * cap[i, j]
    for a in range(3):
        if a == 0:
            y = c * dx + s * dy
        elif a == 1:
            y = c * dy - s * dx
        else:
            y = dz
        e = y
        for j in range(kk):
            e -= points[o + j, a] * theta[i, j]
        den = r_pos if a == 2 else 2.0 * r_pos  # x, y: the end-effector's and the mount's noise
        for j in range(kk):
            acc = 0.0
            for k in range(kk):
                acc += P[i, j, k] * points[o + k, a]
            g[j] = acc
            den += points[o + j, a] * acc
        for j in range(kk):
            theta[i, j] += g[j] * (e / den)
        for j in range(kk):
            gj = g[j] / den
            for k in range(j, kk):
                v = P[i, j, k] - gj * g[k]
                P[i, j, k] = v
                P[i, k, j] = v
    # the ceiling: no length less certain than its prior
    for j in range(kk):
        if P[i, j, j] > cap[i, j]:
            g[j] = math.sqrt(cap[i, j] / P[i, j, j])
        else:
            g[j] = 1.0
    for j in range(kk):
        for k in range(kk):
            P[i, j, k] *= g[j] * g[k]
    for j in range(kk):
        cd = code[o + j]
        if cd < n:
            arm[i, E.A_A, cd] = theta[i, j]
        elif cd < 2 * n:
            arm[i, E.A_D, cd - n] = theta[i, j]
        else:
            prm[i, E.P_TOOL] = theta[i, j]


@njit(cache=True, inline="always")
def _platform_update(i, c, s, n, pc_vel, yaw, jp, dt, plat, pvar, pcap, head, r_vel, r_yaw, qf):
    """Row i's platform: alpha and gamma from the mount's velocity against the wheels' speeds (from their
    angles), beta from the heading (a Kalman filter on heading and beta)."""
    vf = c * pc_vel[i, 0] + s * pc_vel[i, 1]
    vl = c * pc_vel[i, 1] - s * pc_vel[i, 0]
    # the wheels' speeds over the last step from their angles (encoders: no noise in the env)
    dl, dr = jp[i, n] - head[i, 3], jp[i, n + 1] - head[i, 4]
    head[i, 3], head[i, 4] = jp[i, n], jp[i, n + 1]
    wl, wr = dl / dt, dr / dt
    if head[i, 5] == 0.0:
        _update_scalar(wl + wr, vf, r_vel, qf, plat, pvar, pcap, i, 0)
        _update_scalar(wr - wl, vl, r_vel, qf, plat, pvar, pcap, i, 2)
    head[i, 5] = 0.0
    # beta from the heading: a Kalman filter on (heading psi, beta), psi_k = psi_k-1 + beta dW (dW: the
    # change of the wheels' angle difference), the measured heading = psi + noise
    dw = dr - dl
    be = plat[i, 1]
    psi = head[i, 0] + be * dw
    p11 = pvar[i, 1]
    p00 = head[i, 1] + dw * (2.0 * head[i, 2] + dw * p11)
    p01 = head[i, 2] + dw * p11
    p11 = p11 + qf * pcap[i, 1]
    den = p00 + r_yaw
    k0, k1 = p00 / den, p01 / den
    nu = yaw[i] - psi
    head[i, 0] = psi + k0 * nu
    plat[i, 1] = be + k1 * nu
    p11 = p11 - k1 * p01
    p01 = p01 * (1.0 - k0)
    head[i, 1] = p00 * (1.0 - k0)
    if p11 > pcap[i, 1]:
        p01 *= math.sqrt(pcap[i, 1] / p11)
        p11 = pcap[i, 1]
    head[i, 2] = p01
    pvar[i, 1] = p11


def unit_rows(params: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The regression's columns for a robot (`RobotParams`): (codes, values, unit_arm, unit_prm).

    One entry per length of the arm's `length_slots` (every non-zero DH a and d, the tool): `codes` (k,) says which
    (j < n: a_j; n + j: d_j; 2n: the tool), `values` (k,) its catalogue value (m); `unit_arm` (k, 8, n + 2) and
    `unit_prm` (k, `P_LEN`) are this robot packed as `mobman_env.engine` rows with that length 1 and every other
    length 0, so the engine's `arm_points` on them gives the columns of Phi(q), and the arm point of any robot with
    this structure is Phi(q) theta (theta: its lengths in this order)."""
    n = params.n_joints
    arm, prm = E.packed([params])
    slots = params.arm.length_slots
    k = len(slots)
    codes = np.empty(k, dtype=np.intp)
    values = np.empty(k)
    unit_arm = np.repeat(arm, k, axis=0)
    unit_prm = np.repeat(prm, k, axis=0)
    unit_arm[:, E.A_A] = 0.0
    unit_arm[:, E.A_D] = 0.0
    unit_prm[:, E.P_TOOL] = 0.0
    for j, (kind, idx) in enumerate(slots):
        if kind == "a":
            codes[j], values[j] = idx, params.arm.a[idx]
            unit_arm[j, E.A_A, idx] = 1.0
        elif kind == "d":
            codes[j], values[j] = n + idx, params.arm.d[idx]
            unit_arm[j, E.A_D, idx] = 1.0
        else:
            codes[j], values[j] = 2 * n, params.arm.tool
            unit_prm[j, E.P_TOOL] = 1.0
    return codes, values, unit_arm, unit_prm


class CalibQPLaw(QPLaw):
    """`qp`'s law (`QPLaw`) for N robots on models calibrated online (see the module docstring); `params(i)` returns
    row i's nominal `RobotParams` (the prior), read at each of the row's episode starts. `CalibQP` is its N = 1
    case.

    State per row: `theta` (N, 2n + 1), the arm lengths in the nominal arm's `length_slots` order (the first
    `n_lengths[i]` entries; m), `platform` (N, 3), alpha, beta, gamma (`PLATFORM`), and their covariances."""

    config: CalibQPConfig
    uses_keys: tuple[str, ...] = (*QPLaw.uses_keys, "arm_base_pos", "arm_base_vel")
    knowledge = "nominal"

    def __init__(self, facts: EnvFacts, config: CalibQPConfig, n: int, seed: int | None, params: Callable[[int], Any]):
        if not isinstance(config, CalibQPConfig):
            raise TypeError(
                f"calib-qp needs a CalibQPConfig, got {type(config).__name__} (QPConfig's fields are in it)"
            )
        super().__init__(facts, config, n, seed, params, "calib-qp")
        kmax = 2 * facts.n_arm + 1  # every a, every d and the tool: the most lengths an arm of n joints can have
        self.theta = np.zeros((n, kmax))
        self.P = np.zeros((n, kmax, kmax))
        self._cap = np.zeros((n, kmax))
        self.platform = np.zeros((n, 3))
        self._pvar = np.zeros((n, 3))
        self._pcap = np.zeros((n, 3))
        self._head = np.zeros((n, 6))
        self.n_lengths = np.zeros(n, dtype=np.intp)
        # per row: the codes of its lengths and its unit rows (arm, prm); joined into one batch once all rows started
        self._units: list[tuple[np.ndarray, np.ndarray, np.ndarray] | None] = [None] * n
        self._start_of = np.zeros(n, dtype=np.intp)
        self._owner = np.zeros(0, dtype=np.intp)

    def _reset_rows(self, rows: np.ndarray, obs: dict) -> None:
        super()._reset_rows(rows, obs)
        c = self.config
        m = self._n_arm
        arm, prm = self._model.arm, self._model.prm
        rel2 = c.prior_rel_std**2
        for i in rows.tolist():
            p = self._model.params[i]
            E.pack_robot(arm, prm, i, p)  # the catalogue's numbers: the prior mean (a last episode's estimate goes)
            codes, values, unit_arm, unit_prm = unit_rows(p)
            k = len(codes)
            self.theta[i] = self._cap[i] = 0.0
            self.P[i] = 0.0
            self.theta[i, :k] = values
            self._cap[i, :k] = rel2 * values * values
            self.P[i, np.arange(k), np.arange(k)] = self._cap[i, :k]
            self.n_lengths[i] = k
            self._units[i] = (codes, unit_arm, unit_prm)
            r, b, d = p.wheel_radius, p.half_track, p.mount_offset
            alpha, beta = 0.5 * r, 0.5 * r / b
            self.platform[i] = alpha, beta, d * beta
            # beta is a ratio of two worn lengths, gamma a product of three: their relative variances add
            self._pvar[i] = self._pcap[i] = rel2 * np.array([alpha**2, 2.0 * beta**2, 3.0 * (d * beta) ** 2])
            jl, jr = obs["joint_pos"][i, m], obs["joint_pos"][i, m + 1]
            self._head[i] = obs["base_yaw"][i, 0], c.yaw_std**2, 0.0, jl, jr, 0.0
        if all(u is not None for u in self._units):  # (re)build the batch of unit rows
            units = [u for u in self._units if u is not None]
            self._start_of = np.r_[0, np.cumsum(self.n_lengths)[:-1]].astype(np.intp)
            self._owner = np.repeat(np.arange(self.num_envs), self.n_lengths)
            self._code = np.concatenate([u[0] for u in units])
            self._unit_arm = np.concatenate([u[1] for u in units])
            self._unit_prm = np.concatenate([u[2] for u in units])
            self._points = np.empty((len(self._code), 3))
            self._unit_jac = np.empty((len(self._code), 3, m))

    def _act(self, obs: dict) -> np.ndarray:
        self.calibrate(obs)
        return super()._act(obs)

    def calibrate(self, obs: dict) -> None:
        """One calibration step of every row from its observation (`uses_keys`, (N, k) float64), written into the
        model rows: what `_act` does before the QP."""
        c = self.config
        E.arm_points(self._unit_arm, self._unit_prm, obs["joint_pos"][self._owner], self._points, self._unit_jac)
        calibrate_rows(
            self._points,
            self._start_of,
            self.n_lengths,
            self._code,
            obs["ee_pos"],
            obs["arm_base_pos"],
            obs["arm_base_vel"],
            obs["base_yaw"][:, 0],
            obs["joint_pos"],
            self.facts.dt,
            self.theta,
            self.P,
            self._cap,
            self.platform,
            self._pvar,
            self._pcap,
            self._head,
            c.pos_std**2,
            c.vel_std**2,
            c.yaw_std**2,
            (c.drift / c.prior_rel_std) ** 2 * self.facts.dt,
            self._model.arm,
            self._model.prm,
        )

    def lengths(self, i: int) -> dict[str, float]:
        """Row i's current estimate by name: the arm's lengths by slot name (a2, d4, tool; m) and the platform's
        wheel_radius, half_track and mount_offset (m), as written into its model row."""
        p = self._model.params[i]
        out = {slot_name(s): float(self.theta[i, j]) for j, s in enumerate(p.arm.length_slots)}
        prm = self._model.prm[i]
        out.update(wheel_radius=float(prm[E.P_R]), half_track=float(prm[E.P_B]), mount_offset=float(prm[E.P_MNT]))
        return out

    def estimated_params(self, i: int) -> Any:
        """Row i's current estimate as a `RobotParams`: the nominal robot with the estimated lengths (the model the
        QP solves with, up to the rounding of the factors)."""
        p = self._model.params[i]
        est = self.lengths(i)
        slots = p.arm.length_slots
        nominal = [p.tool if s[0] == "tool" else getattr(p.arm, s[0])[s[1]] for s in slots]
        factors = [est[slot_name(s)] / v for s, v in zip(slots, nominal)]
        mount = est["mount_offset"] / p.mount_offset if p.mount_offset != 0.0 else 1.0
        return dataclasses.replace(
            p,
            arm=p.arm.scaled_lengths(factors, mount_factor=mount),
            wheel_radius=est["wheel_radius"],
            half_track=est["half_track"],
        )


class CalibQP(LawView):
    """The whole-body QP of `qp` on a model calibrated online; see the module docstring. The N = 1 case of
    `CalibQPLaw`.

    `CalibQP(facts, config=None, seed=None, *, nominal_params)`: `nominal_params` is the prior, a `RobotParams` or a
    callable returning the episode's nominal robot (read at every episode start). Diagnostics: `theta`,
    `platform`, `lengths()`, `estimated_params()`, `last_slack`, `qp_failures`.
    """

    name = "calib-qp"
    knowledge = "nominal"

    def __init__(
        self,
        facts: EnvFacts,
        config: CalibQPConfig | None = None,
        seed: int | None = None,
        *,
        nominal_params: Any = None,
        **extra: Any,
    ):
        reject_extra(self, extra, "nominal_params")
        if nominal_params is None:
            raise ValueError(
                "CalibQP needs nominal_params, the prior it calibrates from: a RobotParams or a callable returning "
                "the episode's nominal one (policies.make('calib-qp', env) passes the env's)"
            )
        self.config = config or CalibQPConfig()
        self._provider = nominal_params if callable(nominal_params) else (lambda: nominal_params)
        self.law: CalibQPLaw = CalibQPLaw(facts, self.config, 1, seed, lambda i: self._provider())
        super().__init__(facts, seed)

    @classmethod
    def batched(
        cls, facts: EnvFacts, config: Any, n: int, seed: int | None, *, nominal_params: Callable[[int], Any]
    ) -> CalibQPLaw:
        """The batched law for n robots (`policies.make(spec, vector_env)`): `nominal_params(i)` returns row i's
        nominal robot."""
        return CalibQPLaw(facts, config, n, seed, nominal_params)

    @property
    def theta(self) -> np.ndarray:
        """The arm's estimated lengths in the nominal arm's `length_slots` order, m."""
        return self.law.theta[0, : self.law.n_lengths[0]]

    @property
    def platform(self) -> np.ndarray:
        """alpha = r / 2 (m), beta = r / (2 b), gamma = d beta (m) as estimated."""
        return self.law.platform[0]

    def lengths(self) -> dict[str, float]:
        """The estimate by name (`CalibQPLaw.lengths`)."""
        return self.law.lengths(0)

    def estimated_params(self) -> Any:
        """The estimate as a `RobotParams` (`CalibQPLaw.estimated_params`)."""
        return self.law.estimated_params(0)

    @property
    def params(self) -> Any:
        """The nominal `RobotParams` of this episode (the prior)."""
        return self.law.params[0]

    @property
    def last_slack(self) -> np.ndarray:
        return self.law.last_slack[0]

    @property
    def qp_failures(self) -> int:
        return int(self.law.qp_failures[0])

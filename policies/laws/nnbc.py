"""NNBC: the paper's model-free controller (eqs. (7)-(15)), implemented exactly as published.

The controller never sees a kinematic parameter. It keeps an estimate J_hat (3 x 8) of the Jacobian and

* issues, at every control step, eq. (11):

      u = J_hat^+ (r_d_dot - [p_c_dot; 0] + gamma (r_d - r_a))                          (11)

* and updates J_hat with the zeroing-neural-network law eq. (15), which drives the residual of eq. (12),
  eps = r_a_dot - [p_c_dot; 0] - J_hat u, to zero like eps_dot = -mu eps:

      J_hat_dot = (r_a_ddot - [p_c_ddot; 0] - J_hat u_dot + mu (r_a_dot - [p_c_dot; 0] - J_hat u)) u^+   (15)

Everything below is a decision the paper leaves open; each one is written down where it is made.

Measured signals
----------------
Write y = r_a_dot - [p_c_dot; 0] (the part of the end-effector velocity the paper's J explains; `nnbc-full`
uses y = r_a_dot, see below). All of it is read from the observation: `ee_vel` (r_a_dot), `arm_base_vel`
(p_c_dot), `ee_pos` (r_a), `target_pos`/`target_vel` (r_d, r_d_dot). The observation at step k is taken at
t_k, *after* the command u_{k-1} was held over [t_{k-1}, t_k]: y_k is the response to u_{k-1}. So eq. (12)
pairs y_k with u_{k-1}, the command this controller issued one step earlier (`self.last_u`: after its own
clipping to the speed limits, not the measured joint speeds).

Discretisation of eq. (15) (explicit Euler, backward differences)
-----------------------------------------------------------------
With y_dot ~ (y_k - y_{k-1}) / dt and u_dot ~ (u_{k-1} - u_{k-2}) / dt, one Euler step of (15) is

      J_k = J_{k-1} + [ (y_k - y_{k-1}) - J_{k-1} (u_{k-1} - u_{k-2}) + mu dt eps_{k-1} ] u_{k-1}^+
      eps_k = y_k - J_k u_{k-1}                                            (a-posteriori residual)

Multiplying by u_{k-1} (with u^+ u = 1) gives eps_k = (1 - mu dt) eps_{k-1}: the exact discrete image of
eps_dot = -mu eps. The derivative terms are what makes this so: without them (J_k = J_{k-1} + mu dt eps u^+)
the estimate chases a moving target and keeps a lag bias of order |y_dot| / mu that does not shrink with dt.
A consequence worth knowing: with the derivative terms, a residual that starts at zero (the robot at rest,
y_0 = 0, u_{-1} = 0) stays zero up to the u^+ regularisation, whatever mu is: J_hat then reproduces every
measured response along the command that caused it exactly, and mu only shapes how an initial or injected
residual decays.
The code evaluates the bracket in the algebraically identical form a_k - (1 - mu dt) eps_{k-1}, with the a-priori
residual a_k = y_k - J_{k-1} u_{k-1} (one matrix-vector product per step; `NNBCLaw._znn_update`).

The pseudo-inverse of a vector is regularised, u^+ = u^T / (u^T u + eps_u) with eps_u = 1e-6 (rad/s)^2 by
default: for |u| >> 1 mrad/s it is the exact u^T / |u|^2, and as u -> 0 the update fades to zero instead of
dividing by zero. At the first control step r_d_dot(0) = 0 and e(0) = 0, so u = 0 and J_hat is left alone.

Row space (a structural property of the paper's method)
-------------------------------------------------------
u = J_hat^+ v lies in the row space of J_hat, and (15) adds only multiples of u^T, so the row space of J_hat
never changes after J_hat(0) (as long as no clipping alters u): the eight actuators only ever move inside one
3-D subspace fixed at the start. `tests/test_policies.py` checks this numerically. It is why the method fails on
long paths: the update refreshes J_hat only along the current u, and the other directions go stale as the arm
moves. Measured on Circle-v0 (kinematic, 20 seeds, medians): the largest principal angle between J_hat's row
space and the true Jacobian's grows from 1 deg at 1 s to 37 deg at 5 s and 78 deg at 7 s; J_hat's smallest
singular value falls from 0.20 to 0.10 at 5 s and 0.05 at 7 s while the true one is 0.23 at 5 s; the error
passes 6 mm at about 5.3 s. This module keeps the paper's method exactly; an improved controller lives beside
it (`nnbc-plus`).

p_c_dot in eq. (11) closes a loop through the yaw
-------------------------------------------------
The paper subtracts the measured arm-base velocity p_c_dot, not a prediction of it. p_c_dot(t_k) is the result
of the previous command's wheel speeds: the platform's forward speed plus d * phi_dot sideways (d: the arm
mount's offset ahead of the axle). J_hat (the paper's J) models only how the yaw swings the arm about P_c; the
motion of P_c itself appears one step later in the measurement, and the next command compensates it - partly
again with the wheels, whose yaw moves P_c again. This is a discrete feedback loop through the platform's yaw
with a one-step delay: delta_{k+1} = -J_pc J_hat^+ [delta_k; 0], where delta is the measured p_c_dot and J_pc
(2 x 8) maps the wheel speeds to it. Its gain, the spectral radius of J_pc J^+ [I; 0], is small for this robot:
with the true Jacobian along Circle-v0 it is 0.03 (median) and at most 0.1, so the loop settles within a step
or two and adds a small transient whenever the yaw rate changes. With a poor J_hat the gain is whatever J_hat^+
makes it; it is part of the closed loop the paper's method runs.

J_hat(0)
--------
* `probe` (default, model-free): during the first 2 x 8 control steps each actuator in turn gets a doublet,
  +a_i for one step then -a_i for one step (a_i = `probe_amp` x its speed limit; the doublet brings the robot
  back where it was in kinematic mode). Column i is (y_+ - y_-) / (2 a_i) from the two measured responses.
  These steps are part of the episode: the target keeps moving (slowly: every path starts at rest) and the
  metrics count them. The ZNN law starts at step 16.
* `nominal`: the paper's Jacobian of the *nominal* model at the first observation (`nominal_params` must be
  given: this is model knowledge, so `nnbc:j0=nominal` is not model-free).
* a given 3 x 8 matrix (`J0=` in the Python API).

Damped pseudo-inverse of J_hat
------------------------------
J_hat^+ = J_hat^T (J_hat J_hat^T + lambda^2 I)^{-1} with the damping of Nakamura & Hanafusa / Chiaverini:
lambda^2 = 0 while the smallest singular value sigma_min >= `sigma_threshold`, and
lambda^2 = damping^2 (1 - (sigma_min / sigma_threshold)^2) below it. Both default to 0.02 m/rad, far below the
true Jacobian's smallest singular value on the benchmark's paths (about 0.2): damping only bounds the speeds
when J_hat itself has become nearly singular; it never acts while J_hat is well conditioned, and it keeps u in
the row space of J_hat.

`nnbc-full`
-----------
J_hat maps u to the whole r_a_dot (y = r_a_dot, no p_c_dot subtraction in (11), (12), (15)), so the wheel
columns include the platform's translation and the platform can drive (needed for the 3 m line).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from mobman_env.numba_cache import njit
from policies.base import EnvFacts, current_model, reject_extra
from policies.batched import BatchedController, LawView
from policies.kernels.shared import ModelJacobians, damped_pinv_apply_rows
from policies.kernels.shared import damped_pinv as damped_pinv  # re-exported: the module docstring's pseudo-inverse
from policies.kernels.shared import damped_pinv_apply as damped_pinv_apply
from policies.kernels.shared import sigma_min_3 as sigma_min_3

#: Observation keys NNBC reads.
NNBC_OBS_KEYS = ("ee_pos", "ee_vel", "arm_base_vel", "target_pos", "target_vel")
J0_MODES = ("probe", "nominal")


@dataclass(frozen=True)
class NNBCConfig:
    """Gains and choices of the paper's NNBC. Spec keys: `nnbc:gamma=10,mu=10,j0=probe,...`."""

    gamma: float = 10.0
    """Position feedback gain of eq. (8)/(11), 1/s (the paper: 10)."""
    mu: float = 10.0
    """Convergence rate of the Jacobian estimator, eq. (13)/(15), 1/s (the paper: 10)."""
    j0: str = "probe"
    """Initial J_hat: "probe" (model-free, measured in the first 16 steps) or "nominal" (the nominal model's
    Jacobian at the first observation: model knowledge). A matrix is given through the Python API (`J0=`)."""
    probe_amp: float = 0.02
    """Probe doublet amplitude as a fraction of each actuator's speed limit (0.02: 0.06 rad/s for joints 1-3,
    0.2 rad/s for the wheels; the end-effector moves about 0.5 mm during the probe)."""
    eps_u: float = 1e-6
    """Regularisation of the vector pseudo-inverse u^+ = u^T / (u^T u + eps_u), (rad/s)^2."""
    damping: float = 0.02
    """Maximum damping lambda of J_hat's pseudo-inverse, m/rad (see the module docstring)."""
    sigma_threshold: float = 0.02
    """Smallest singular value of J_hat below which damping starts, m/rad."""
    full: bool = False
    """False: the paper's formulation (J_hat explains r_a_dot - [p_c_dot; 0]). True: `nnbc-full`, J_hat explains
    the whole r_a_dot and the platform's translation is learned too."""

    def __post_init__(self):
        for name in ("gamma", "mu", "probe_amp", "eps_u", "damping", "sigma_threshold"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"NNBCConfig.{name} must be a finite number, got {value!r}")
        for name in ("gamma", "mu", "probe_amp", "eps_u", "damping", "sigma_threshold"):
            if getattr(self, name) <= 0:
                raise ValueError(f"NNBCConfig.{name} must be > 0, got {getattr(self, name)!r}")
        if self.j0 not in J0_MODES:
            raise ValueError(
                f"NNBCConfig.j0 must be one of {', '.join(J0_MODES)} (a matrix goes through the Python API, "
                f"NNBC(facts, J0=...)), got {self.j0!r}"
            )


class NNBCLaw(BatchedController):
    """The paper's NNBC for N robots at once (the one implementation; `NNBC` is its N = 1 case).

    `NNBCLaw(facts, config=None, n=1, seed=None, *, J0=None, nominal_params=None)`: as `NNBC`, with
    `nominal_params` a `RobotParams` or a callable f(i) returning row i's nominal robot. State per row: `J_hat`
    (N, 3, n + 2), `residual` (N, 3), `steps` (N,) (controller steps since the row's episode start). Rows probe,
    finish the probe and run the ZNN law each at its own step, so rows restarted by `episode_start` rejoin at
    their own pace; while every row is past the probe, a step is a few whole-array operations.
    """

    name = "nnbc"

    def __init__(
        self,
        facts: EnvFacts,
        config: NNBCConfig | None = None,
        n: int = 1,
        seed: int | None = None,
        *,
        J0: Any = None,
        nominal_params: Any = None,
    ):
        super().__init__(facts, n, seed)
        self.config = config or NNBCConfig()
        m = len(self._scale)
        missing = [k for k in NNBC_OBS_KEYS if facts.obs_keys and k not in facts.obs_keys]
        if missing:
            raise ValueError(f"NNBC needs the observation keys {list(NNBC_OBS_KEYS)}; the env lacks {missing}")
        if J0 is not None:
            if self.config.j0 == "nominal":
                raise ValueError("give either J0=<matrix> or config.j0='nominal', not both")
            J0 = np.array(J0, dtype=float)
            if J0.shape != (3, m) or not np.all(np.isfinite(J0)):
                raise ValueError(f"J0 must be a finite 3 x {m} matrix, got shape {J0.shape}")
            self.j0_source = "matrix"
        else:
            self.j0_source = self.config.j0
        if self.j0_source == "nominal" and nominal_params is None:
            raise ValueError(
                "NNBC with j0='nominal' needs nominal_params (the registry passes the env's nominal "
                "model); use j0='probe' for the model-free start"
            )
        self._J0 = J0
        self._model: ModelJacobians | None = None
        if self.j0_source == "nominal":
            provider = nominal_params if callable(nominal_params) else (lambda i: nominal_params)
            self._model = ModelJacobians(n, provider)
        self._full = bool(self.config.full)
        self.jacobian_kind = "whole_body" if self._full else "paper"
        self._decay = 1.0 - self.config.mu * facts.dt  # eps_k = (1 - mu dt) eps_{k-1}: the discrete eq. (13)
        self.uses_keys = NNBC_OBS_KEYS + (("joint_pos", "base_yaw") if self.j0_source == "nominal" else ())
        self._probe_u = self.config.probe_amp * self._scale  # rad/s per actuator
        self._n_probe = 2 * m if self.j0_source == "probe" else 0
        self.J_hat = np.zeros((n, 3, m))
        self.residual = np.zeros((n, 3))
        self._y_plus = np.zeros((n, 3))
        self.steps = np.zeros(n, dtype=int)
        self._all = np.arange(n)
        self._lo = 0  # the smallest step count of the rows (every row past the probe: the whole-array path)

    def jacobian_estimate_row(self, i: int) -> np.ndarray | None:
        if not self.initialised[i] or (self._n_probe and self.steps[i] <= self._n_probe):
            return None
        return self.J_hat[i].copy()

    # --- helpers -------------------------------------------------------------------------------------
    def _measured_y(self, obs: dict) -> np.ndarray:
        """y = r_a_dot - [p_c_dot; 0] (paper) or r_a_dot (full), (N, 3)."""
        y = obs["ee_vel"].copy()
        if not self._full:
            y[:, :2] -= obs["arm_base_vel"]
        return y

    # --- BatchedController ---------------------------------------------------------------------------
    def _reset_rows(self, rows: np.ndarray, obs: dict) -> None:
        self.steps[rows] = 0
        self._lo = 0
        self._y_plus[rows] = 0.0
        if self._n_probe:
            self.J_hat[rows] = 0.0
            self.residual[rows] = 0.0
            return
        if self._model is not None:
            self._model.load(rows)
            self.J_hat[rows] = self._model(obs["joint_pos"][rows], obs["base_yaw"][rows], self._full, rows)
        else:
            self.J_hat[rows] = self._J0
        # eps_0 = y_0 - J_hat u_{-1} with u_{-1} = 0 (nothing issued yet). The residual carries everything the
        # update needs from the past (y_{k-1} and u_{k-2}; see _znn_update).
        self.residual[rows] = self._measured_y(obs)[rows]

    def _act(self, obs: dict) -> np.ndarray:
        k = self.steps
        self.steps = k + 1
        lo, self._lo = self._lo, self._lo + 1
        y = self._measured_y(obs)
        u1 = self.last_u  # u_{k-1}: the command issued (and clipped) at the previous step, (N, n + 2)
        n_probe = self._n_probe
        if lo > n_probe:  # every row runs the ZNN law: whole arrays, no masks
            self._znn_update(None, y, u1)
            return self._command(None, obs)
        u = np.zeros_like(u1)
        probe = k < n_probe
        if probe.any():
            rows = np.flatnonzero(probe)
            u[rows] = self._probe_step(rows, k[rows], y)
        if n_probe:
            rows = np.flatnonzero(k == n_probe)
            if rows.size:
                self._set_probe_columns(rows, np.full(rows.size, len(self._scale) - 1), y)
                eps0 = np.empty((rows.size, 3))
                _residual_rows(self.J_hat, y, u1, rows, eps0)
                self.residual[rows] = eps0  # eps_k0 with the measured J_hat(0)
        rows = np.flatnonzero(k > n_probe)
        if rows.size:
            self._znn_update(rows, y, u1)
        rows = np.flatnonzero(~probe)
        if rows.size:
            u[rows] = self._command(rows, obs)
        return u

    def _command(self, rows: np.ndarray | None, obs: dict) -> np.ndarray:
        """Eq. (11) for the rows `rows` (an index array; None: every row)."""
        c = self.config
        tv, tp, ee, J = obs["target_vel"], obs["target_pos"], obs["ee_pos"], self.J_hat
        if rows is not None:
            tv, tp, ee, J = tv[rows], tp[rows], ee[rows], J[rows]
        v = tv + c.gamma * (tp - ee)
        if not self._full:
            v[:, :2] -= obs["arm_base_vel"] if rows is None else obs["arm_base_vel"][rows]
        return damped_pinv_apply_rows(J, v, c.damping, c.sigma_threshold)

    def _znn_update(self, rows: np.ndarray | None, y: np.ndarray, u1: np.ndarray) -> None:
        """One explicit-Euler step of eq. (15) with backward differences (module docstring), for the rows `rows`
        (an index array; None: every row, in place).

        Computed in an algebraically identical, cheaper form. With eps_{k-1} = y_{k-1} - J_{k-1} u_{k-2} (the
        stored a-posteriori residual) the bracket
            (y_k - y_{k-1}) - J_{k-1} (u_{k-1} - u_{k-2}) + mu dt eps_{k-1}
        equals a_k - (1 - mu dt) eps_{k-1} with a_k = y_k - J_{k-1} u_{k-1} (the a-priori residual), and the new
        residual is eps_k = y_k - J_k u_{k-1} = a_k - rho b with rho = u^T u / (u^T u + eps_u): one 3 x 8
        product per step instead of three.
        """
        _znn_rows(self.J_hat, self.residual, y, u1, self._all if rows is None else rows, self._decay, self.config.eps_u)

    def _probe_step(self, rows: np.ndarray, k: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Steps 0..15 of the rows `rows` (at their steps k): +a_i at step 2i, -a_i at step 2i+1; the responses
        arrive one step later."""
        prev = k - 1
        plus = (k > 0) & (prev % 2 == 0)  # the previous command was +a_i: remember its response
        self._y_plus[rows[plus]] = y[rows[plus]]
        minus = (k > 0) & (prev % 2 == 1)  # it was -a_i: column i from the two responses
        if minus.any():
            self._set_probe_columns(rows[minus], prev[minus] // 2, y)
        i = k // 2
        amp = self._probe_u[i]
        u = np.zeros((rows.size, len(self._scale)))
        u[np.arange(rows.size), i] = np.where(k % 2 == 1, -amp, amp)
        return u

    def _set_probe_columns(self, rows: np.ndarray, cols: np.ndarray, y_minus: np.ndarray) -> None:
        self.J_hat[rows, :, cols] = (self._y_plus[rows] - y_minus[rows]) / (2.0 * self._probe_u[cols])[:, None]


@njit(cache=True)
def _znn_rows(J, eps, y, u, rows, decay, eps_u):
    """`NNBCLaw._znn_update` for the rows `rows`, in place on J (N, 3, m) and eps (N, 3): per row
    a = y - J u, b = a - decay eps, J += b u^T / (u^T u + eps_u), eps = a - (u^T u / (u^T u + eps_u)) b; the sums
    written out (no BLAS)."""
    m = J.shape[2]
    for r in range(rows.shape[0]):
        i = rows[r]
        uu = 0.0
        for j in range(m):
            uu += u[i, j] * u[i, j]
        inv = 1.0 / (uu + eps_u)
        for k in range(3):
            a = y[i, k]
            for j in range(m):
                a -= J[i, k, j] * u[i, j]
            b = a - decay * eps[i, k]
            for j in range(m):
                J[i, k, j] += b * (u[i, j] * inv)
            eps[i, k] = a - (uu * inv) * b


@njit(cache=True)
def _residual_rows(J, y, u, rows, out):
    """out[r] = y_i - J_i u_i for i = rows[r] (the sums written out)."""
    m = J.shape[2]
    for r in range(rows.shape[0]):
        i = rows[r]
        for k in range(3):
            a = y[i, k]
            for j in range(m):
                a -= J[i, k, j] * u[i, j]
            out[r, k] = a


class NNBC(LawView):
    """The paper's model-free controller; see the module docstring for every discretisation choice.

    `NNBC(facts, config=None, seed=None, *, J0=None, nominal_params=None)`: `facts` is the `EnvFacts` of the
    env (dt, speed limits, observation keys); `J0` an optional 3 x 8 initial estimate; `nominal_params` is only
    needed (and only allowed to matter) with `config.j0 == "nominal"`. It is the one-row case of `NNBCLaw`
    (`self.law`), the law every batched `nnbc` policy runs.

    Diagnostics: `J_hat` (the current estimate, 3 x 8; `jacobian_estimate` is its documented copy), `residual`
    (eps of eq. (12) after the last update), `probing` (True while J_hat(0) is being measured), `step_count`
    (controller steps this episode).
    """

    name = "nnbc"

    def __init__(
        self,
        facts: EnvFacts,
        config: NNBCConfig | None = None,
        seed: int | None = None,
        *,
        J0: Any = None,
        nominal_params: Any = None,
        **extra: Any,
    ):
        reject_extra(self, extra, "J0, nominal_params")
        nominal = None if nominal_params is None else (lambda i: current_model(nominal_params))
        self.law: NNBCLaw = NNBCLaw(facts, config, 1, seed, J0=J0, nominal_params=nominal)
        super().__init__(facts, seed)
        self.config = self.law.config
        self.j0_source = self.law.j0_source
        self._n_probe = self.law._n_probe

    @classmethod
    def batched(cls, facts: EnvFacts, config: NNBCConfig, n: int, seed: int | None, **models: Any) -> NNBCLaw:
        """The batched law for n robots (`policies.make(spec, vector_env)`); `models`: row-indexed providers."""
        return NNBCLaw(facts, config, n, seed, **models)

    @property
    def knowledge(self) -> str:
        """The knowledge class (`policies.knowledge`): "none" with the probe (`j0=probe`), "nominal" with the
        nominal model's J_hat(0) (`j0=nominal`), "unknown" with a `J0=` matrix (its origin is the caller's)."""
        return {"probe": "none", "nominal": "nominal"}.get(self.j0_source, "unknown")

    @property
    def J_hat(self) -> np.ndarray:
        return self.law.J_hat[0]

    @property
    def residual(self) -> np.ndarray:
        return self.law.residual[0]

    @property
    def step_count(self) -> int:
        return int(self.law.steps[0])

    @property
    def probing(self) -> bool:
        return self._initialised and self.step_count < self._n_probe

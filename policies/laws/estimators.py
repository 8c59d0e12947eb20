"""Online Jacobian estimators behind one interface, for the model-free controllers of `policies.laws.nnbc_plus`.

Each estimator learns the 3 x n matrix J of the linear measurement y = J x, with x the measured actuator speeds
(rad/s) and y the measured task velocity (m/s), from one (x, y) pair per control step. The controller around it
(`policies.laws.nnbc_plus.EstimatingController`: probe, excitation, control law) is the same for all of them, so a
comparison between `nnbc-plus`, `broyden` and `rls` compares estimators and nothing else.

Interface (`JacobianEstimator`):

* `reset()` - forget everything (episode start): J = 0, J_dot = 0.
* `init(J0)` - start from the probed J_hat(0) (3 x n, m/rad), J_dot = 0.
* `update(x, y)` - one measurement: x (n,) rad/s, y (3,) m/s.
* `J` (3 x n, m/rad) and `Jdot` (3 x n, m/rad/s): the current estimate and its time rate (zero for the
  estimators that model no rate). Both are views the estimator keeps updating: copy them to keep a value.

The three estimators (units as above; "per step" means per control step dt):

* `KalmanEstimator` (`nnbc-plus`): each row of [J | J_dot] is the state of a linear Kalman filter with a
  constant-rate model J(t + dt) = J(t) + dt J_dot(t) and random-walk process noise; the rows share one 2n x 2n
  covariance and one gain. See `policies.laws.nnbc_plus` for its parameters.
* `BroydenEstimator` (`broyden`): Broyden's "good" secant update, J <- J + step (y - J x) x^T / (x^T x), which
  makes J reproduce the newest pair along x and changes nothing orthogonal to it; skipped (step gating) when
  ||x|| < min_speed, where the pair carries more noise than information.
* `RLSEstimator` (`rls`): recursive least squares with exponential forgetting (factor lambda per step) and an
  optional random-walk covariance q: K = P x / (lambda + x^T P x), J <- J + (y - J x) K^T,
  P <- (P - K x^T P) / lambda + q I, the trace of P bounded by p_max n (no wind-up when the excitation is poor).

The arithmetic is written once, in `policies.kernels.model_free` (`est_reset`, `est_init`, `est_update`,
`est_observe`: scalar numba code over one row's state); these classes are its Python face for one estimator:
each owns a state segment (`est_layout`) or, for the estimator of a controller's row, views that row's segment
of the batched law (`view`), so `policy.estimator` is the estimate the law runs, not a copy.

Imports numpy and `policies.kernels.model_free` only.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from policies.kernels import model_free as K

#: (m/s)^2: initial running mean square of the Kalman filter's innovations (10 mm/s RMS: permissive).
INNOV_MS0 = K.INNOV_MS0


class JacobianEstimator(Protocol):
    """What the model-free scaffolding needs from an estimator (see the module docstring)."""

    @property
    def J(self) -> np.ndarray: ...

    @property
    def Jdot(self) -> np.ndarray: ...

    def reset(self) -> None: ...

    def init(self, J0: np.ndarray) -> None: ...

    def update(self, x: np.ndarray, y: np.ndarray) -> None: ...


def estimator_params(dt: float = 0.0, **kw: float) -> np.ndarray:
    """The estimator's constants `ep` (`policies.kernels.model_free.EP_*`) from keyword values (missing: 0)."""
    ep = np.zeros(K.EP_LEN)
    names = {
        "q_jacobian": K.EP_QJ,
        "q_rate": K.EP_QR,
        "innov_clip": K.EP_CLIP,
        "innov_rate": K.EP_RATE,
        "p0_jacobian": K.EP_P0J,
        "p0_rate": K.EP_P0R,
        "noise_rate": K.EP_NOISE_RATE,
        "midpoint": K.EP_MIDPOINT,
        "sym_phase": K.EP_SYM_PHASE,
        "q_platform": K.EP_QPLAT,
        "heading_filter": K.EP_HEADING,
        "step": K.EP_STEP,
        "forgetting": K.EP_LAMBDA,
        "q_rls": K.EP_QRLS,
        "p0": K.EP_P0RLS,
        "probe_noise_start": K.EP_PROBE_NOISE,
    }
    ep[K.EP_DT] = dt
    for key, value in kw.items():
        if key == "meas_std":
            ep[K.EP_R0] = value**2
        elif key == "platform_std":
            ep[K.EP_RPLAT] = value**2
        elif key == "min_speed":
            ep[K.EP_MIN2] = value * value
        elif key == "trace_max":
            ep[K.EP_TRMAX] = value
        else:
            ep[names[key]] = float(value)
    ep[K.EP_CLIP2] = ep[K.EP_CLIP] ** 2
    return ep


class _Estimator:
    """One estimator's state segment (own arrays, or a view of a law's row) and the kernel calls on it."""

    kind = K.KALMAN

    def __init__(self, n: int, ep: np.ndarray):
        self._n = n
        self._ep = ep
        self._e = np.zeros(K.est_layout(self.kind, n)[1])
        self._ie = np.zeros(2, dtype=np.int64)
        self._scratch = (np.empty(2 * n), np.empty(2 * n))
        self.reset()

    @classmethod
    def view(cls, n: int, ep: np.ndarray, e: np.ndarray, ie: np.ndarray) -> Any:
        """The estimator whose state is the segment e (floats) and ie (ints) of a law's row (no copy)."""
        self = object.__new__(cls)
        self._n, self._ep, self._e, self._ie = n, ep, e, ie
        self._scratch = (np.empty(2 * n), np.empty(2 * n))
        return self

    @property
    def J(self) -> np.ndarray:
        n = self._n
        return self._e[: 3 * n].reshape(3, n)

    @property
    def Jdot(self) -> np.ndarray:
        n = self._n
        return self._e[3 * n : 6 * n].reshape(3, n)

    def reset(self) -> None:
        K.est_reset(self.kind, self._n, self._ep, self._e, self._ie)

    def init(self, J0: np.ndarray) -> None:
        K.est_init(self.kind, self._n, self._ep, self._e, self._ie, np.ascontiguousarray(J0, dtype=float))

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        y0, y1, y2 = (float(v) for v in np.asarray(y, dtype=float))
        h, ph = self._scratch
        K.est_update(
            self.kind, self._n, self._ep, self._e, self._ie, np.ascontiguousarray(x, dtype=float), y0, y1, y2, h, ph
        )


class KalmanEstimator(_Estimator):
    """[J | J_dot] as the state of a linear Kalman filter (the estimator of `nnbc-plus`).

    dt: control period, s. q_jacobian, q_rate: process noise per step of each J and J_dot entry, (m/rad)^2 and
    (m/rad/s)^2. meas_std: measurement noise of one y component, m/s. innov_clip, innov_rate: robust update
    (an innovation longer than innov_clip x the running RMS is shortened; innov_rate weights the newest one in
    that running mean square; innov_clip = 0 turns it off). p0_jacobian, p0_rate: initial covariances.
    midpoint: the measurement is a finite difference over the last step, which holds at the interval's
    middle, so the regressor gets -dt/2 x on the rate states. noise_rate > 0: the measurement noise R is
    estimated online by covariance matching (a running mean, with that per-step weight, of the (clipped)
    innovation's mean square per component minus its predicted part h P h^T), never below meas_std^2; 0 keeps
    R = meas_std^2. P is re-symmetrised every 64 updates, at updates m with (m + sym_phase) % 64 == 0
    (nnbc-plus passes its probe length + 1, the phase its results were first published with).
    """

    kind = K.KALMAN

    def __init__(self, n: int, dt: float, **kw: Any):
        super().__init__(n, estimator_params(dt, **kw))

    @property
    def _ns(self) -> int:
        return 2 * K.est_nk(self.kind, self._n)

    @property
    def X(self) -> np.ndarray:
        """[J | J_dot] (3 x 2n), the filter's state (a view the filter keeps updating)."""
        ns, base = self._ns, 6 * self._n
        return self._e[base : base + 3 * ns].reshape(3, ns)

    @property
    def P(self) -> np.ndarray:
        """The shared 2n x 2n covariance (a view the filter keeps updating)."""
        return self.arm_P

    @property
    def arm_P(self) -> np.ndarray:
        """The Kalman filter's own covariance (2k x 2k, k = n, or the arm's joints with the structured estimate;
        a view)."""
        ns, base = self._ns, 6 * self._n
        return self._e[base + 3 * ns : base + (3 + ns) * ns].reshape(ns, ns)


class WheelMap:
    """M (3 x 2), the structured estimate's map from the two wheel speeds to the platform's velocity in its own
    frame (forward, sideways, yaw rate): a view of its Kalman filter's state (rows and the shared 2 x 2 P)."""

    def __init__(self, e: np.ndarray):
        self._e = e

    @property
    def rows(self) -> list[list[float]]:
        m = self._e[K.S_M : K.S_M + 6].tolist()
        return [m[0:2], m[2:4], m[4:6]]

    @rows.setter
    def rows(self, value: Any) -> None:
        self._e[K.S_M : K.S_M + 6] = np.asarray(value, dtype=float).reshape(6)

    @property
    def M(self) -> np.ndarray:
        return np.array(self.rows)

    @property
    def P(self) -> np.ndarray:
        a, b, d = self._e[K.S_P : K.S_P + 3]
        return np.array([[a, b], [b, d]])


class StructuredEstimator(KalmanEstimator):
    """The whole-body J of an arm on a platform, from an arm Jacobian in the platform's frame and a learnt
    wheel map (`policies.laws.structured`'s docstring). n actuators: n - 2 arm joints, then the two wheels.

    `observe(obs)` must be called at every control step before `update` (and during the probe, so the wheel
    map learns from it); `arm_kw` are the `KalmanEstimator` options of the arm's filter. X and `arm_P` are the arm
    filter's state [A | A_dot] and covariance, `platform` the wheel map (`WheelMap`), P both covariances as blocks
    of a 2n x 2n."""

    kind = K.STRUCTURED

    def __init__(
        self, n: int, dt: float, *, q_platform: float, platform_std: float, heading_filter: float, arm_kw: dict
    ):
        ep = estimator_params(
            dt, **arm_kw, q_platform=q_platform, platform_std=platform_std, heading_filter=heading_filter
        )
        _Estimator.__init__(self, n, ep)

    @property
    def _tail(self) -> np.ndarray:
        return self._e[K.est_layout(self.kind, self._n)[1] - K.S_LEN :]

    @property
    def platform(self) -> WheelMap:
        return WheelMap(self._tail)

    @property
    def omega(self) -> float:
        """rad/s: the (filtered) heading's rate over the last step."""
        return float(self._tail[K.S_OMEGA])

    @property
    def P(self) -> np.ndarray:
        """2n x 2n: the arm filter's covariance of A's entries in the arm block and the wheel map's in the wheel
        block (per row; every other entry is zero). A new array (the arm filter's own is `arm_P`)."""
        n, na = self._n, self._n - 2
        P = np.zeros((2 * n, 2 * n))
        P[:na, :na] = self.arm_P[:na, :na]
        P[na:n, na:n] = self.platform.P
        return P

    def observe(self, obs: dict) -> None:
        """This step's platform measurements: heading and its rate, the lever r_a - p_c, and the wheel map's
        update (when the wheels turn)."""
        na = self._n - 2
        w0, w1 = (float(v) for v in obs["joint_vel"][na : na + 2])
        e0, e1 = (float(v) for v in obs["ee_pos"][:2])
        p0, p1 = (float(v) for v in obs["arm_base_pos"][:2])
        v0, v1 = (float(v) for v in obs["ee_vel"][:2])
        b0, b1 = (float(v) for v in obs["arm_base_vel"][:2])
        yaw = float(np.asarray(obs["base_yaw"]).reshape(-1)[0])
        K.est_observe(self._n, self._ep, self._e, self._ie, yaw, w0, w1, e0, e1, p0, p1, v0, v1, b0, b1)


class BroydenEstimator(_Estimator):
    """Broyden's secant update with step gating (the estimator of `broyden`).

    step: relaxation of the update, 0 < step <= 1 (1: the classic update, J x = y exactly after it).
    min_speed: updates are skipped while ||x|| < min_speed, rad/s.
    """

    kind = K.BROYDEN

    def __init__(self, n: int, *, step: float, min_speed: float):
        super().__init__(n, estimator_params(step=step, min_speed=min_speed))

    @property
    def n_skipped(self) -> int:
        """Updates skipped (step gate) since the last reset."""
        return int(self._ie[0])


class RLSEstimator(_Estimator):
    """Recursive least squares with exponential forgetting and random-walk covariance (the estimator of `rls`).

    forgetting: lambda, 0 < lambda <= 1 per step (old pairs fade with a time constant of dt / (1 - lambda)).
    q_jacobian: variance added to each J entry's covariance per step, (m/rad)^2 (0: off).
    p0: initial covariance of each J entry (m/rad)^2 over (rad/s)^2 units of the regressor; p_max: bound on the
    covariance trace per entry, applied after every update.
    """

    kind = K.RLS

    def __init__(self, n: int, *, forgetting: float, q_jacobian: float, p0: float, p_max: float):
        super().__init__(n, rls_params(n, forgetting, q_jacobian, p0, p_max))

    @property
    def P(self) -> np.ndarray:
        """The shared n x n covariance (a view the estimator keeps updating)."""
        n = self._n
        return self._e[6 * n : 6 * n + n * n].reshape(n, n)


def rls_params(n: int, forgetting: float, q_jacobian: float, p0: float, p_max: float) -> np.ndarray:
    """`RLSEstimator`'s constants."""
    return estimator_params(forgetting=forgetting, q_rls=q_jacobian, p0=p0, trace_max=p_max * n)


ESTIMATOR_CLASSES: dict[int, type[_Estimator]] = {
    K.KALMAN: KalmanEstimator,
    K.STRUCTURED: StructuredEstimator,
    K.BROYDEN: BroydenEstimator,
    K.RLS: RLSEstimator,
}

"""Online Jacobian estimators behind one interface, for the model-free controllers of `policies.nnbc_plus`.

Each estimator learns the 3 x n matrix J of the linear measurement y = J x, with x the measured actuator speeds
(rad/s) and y the measured task velocity (m/s), from one (x, y) pair per control step. The controller around it
(`policies.nnbc_plus.EstimatingController`: probe, excitation, control law) is the same for all of them, so a
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
  covariance and one gain. See `policies.nnbc_plus` for its parameters.
* `BroydenEstimator` (`broyden`): Broyden's "good" secant update, J <- J + step (y - J x) x^T / (x^T x), which
  makes J reproduce the newest pair along x and changes nothing orthogonal to it; skipped (step gating) when
  ||x|| < min_speed, where the pair carries more noise than information.
* `RLSEstimator` (`rls`): recursive least squares with exponential forgetting (factor lambda per step) and an
  optional random-walk covariance q: K = P x / (lambda + x^T P x), J <- J + (y - J x) K^T,
  P <- (P - K x^T P) / lambda + q I, the trace of P bounded by p_max n (no wind-up when the excitation is poor).

Pure numpy; imports nothing from the package.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

#: (m/s)^2: initial running mean square of the Kalman filter's innovations (10 mm/s RMS: permissive).
INNOV_MS0 = 1e-4


class JacobianEstimator(Protocol):
    """What the model-free scaffolding needs from an estimator (see the module docstring)."""

    @property
    def J(self) -> np.ndarray: ...

    @property
    def Jdot(self) -> np.ndarray: ...

    def reset(self) -> None: ...

    def init(self, J0: np.ndarray) -> None: ...

    def update(self, x: np.ndarray, y: np.ndarray) -> None: ...


class KalmanEstimator:
    """[J | J_dot] as the state of a linear Kalman filter (the estimator of `nnbc-plus`).

    dt: control period, s. q_jacobian, q_rate: process noise per step of each J and J_dot entry, (m/rad)^2 and
    (m/rad/s)^2. meas_std: measurement noise of one y component, m/s. innov_clip, innov_rate: robust update
    (an innovation longer than innov_clip x the running RMS is shortened; innov_rate weights the newest one in
    that running mean square; innov_clip = 0 turns it off). p0_jacobian, p0_rate: initial covariances.
    midpoint: the measurement is a finite difference over the last step, which holds at the interval's
    middle, so the regressor gets -dt/2 x on the rate states. noise_rate > 0: the measurement noise R is
    estimated online by covariance matching (a running mean, with that per-step weight, of the (clipped)
    innovation's mean square per component minus its predicted part h P h^T), never below meas_std^2; 0 keeps
    R = meas_std^2.
    """

    def __init__(
        self,
        n: int,
        dt: float,
        *,
        q_jacobian: float,
        q_rate: float,
        meas_std: float,
        innov_clip: float,
        innov_rate: float,
        p0_jacobian: float,
        p0_rate: float,
        midpoint: bool,
        sym_phase: int = 0,
        noise_rate: float = 0.0,
    ):
        self._n = n
        self._dt = dt
        ns = 2 * n
        self._r0 = self._r = meas_std**2
        self._noise_rate = noise_rate
        self._r_est = self._r0
        self._midpoint = midpoint
        self._h = np.zeros(ns)
        q = np.r_[np.full(n, q_jacobian), np.full(n, q_rate)]
        self._q = q if q.any() else None
        self._clip = innov_clip
        self._clip2 = innov_clip**2
        self._rate = innov_rate
        # [X; P] in one (3 + 2n) x 2n array (`X` and `P` are views of it): the constant-rate prediction of X and
        # the column step of F P F^T are then one operation (the same per-entry arithmetic as two)
        self._M0 = np.zeros((3 + ns, ns))
        self._M0[3:] = np.diag(np.r_[np.full(n, p0_jacobian), np.full(n, p0_rate)])
        # P is re-symmetrised every 64 updates, at updates m with (m + sym_phase) % 64 == 0 (nnbc-plus passes
        # its probe length + 1, the phase its results were first published with)
        self._sym_phase = sym_phase
        self._M = self._M0.copy()
        self._innov_ms: float = INNOV_MS0
        self._m = 0

    @property
    def X(self) -> np.ndarray:
        """[J | J_dot] (3 x 2n), the filter's state (a view the filter keeps updating)."""
        return self._M[:3]

    @property
    def P(self) -> np.ndarray:
        """The shared 2n x 2n covariance (a view the filter keeps updating)."""
        return self._M[3:]

    @property
    def J(self) -> np.ndarray:
        return self._M[:3, : self._n]

    @property
    def Jdot(self) -> np.ndarray:
        return self._M[:3, self._n :]

    def reset(self) -> None:
        self._M = self._M0.copy()
        self._innov_ms = INNOV_MS0
        self._r = self._r_est = self._r0
        self._m = 0

    def init(self, J0: np.ndarray) -> None:
        self._M[:3, : self._n] = J0
        self._M[:3, self._n :] = 0.0

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        """Predict [J | J_dot] one step (constant rate, process noise), then update all rows with
        y = J x (the same regressor h for the three rows: one gain). P is updated in place: F P F^T by the
        block structure of F = [[I, dt I], [0, I]] (rows, then columns), the process noise on its diagonal."""
        n = self._n
        dt = self._dt
        self._m += 1
        M = self._M
        X = M[:3]
        P = M[3:]
        P[:n] += dt * P[n:]  # the rows of F P
        M[:, :n] += dt * M[:, n:]  # X's constant-rate prediction and the columns of (F P) F^T
        if self._q is not None:
            diag = P.reshape(-1)[:: 2 * n + 1]  # a view of P's diagonal (made here: a kept view would not
            diag += self._q  # survive copy.deepcopy or pickling of the estimator)
        h = self._h
        h[:n] = x
        if self._midpoint:
            h[n:] = -0.5 * dt * x  # a finite difference over the last step holds at its middle
        Ph = P.dot(h)  # (.dot: the same BLAS call as @ at about half the overhead)
        hPh = float(h.dot(Ph))
        innov = y - X.dot(h)
        n2 = float(innov.dot(innov))
        K = Ph / (hPh + self._r)
        if self._clip > 0:
            lim2 = self._clip2 * self._innov_ms
            if n2 > lim2:
                innov *= (lim2 / n2) ** 0.5
                n2 = lim2
            self._innov_ms += self._rate * (n2 - self._innov_ms)
        if self._noise_rate > 0:  # covariance matching: E[innov_i^2] = h P h + R per component
            self._r_est += self._noise_rate * (n2 / 3.0 - hPh - self._r_est)
            self._r = max(self._r0, self._r_est)
        X += innov[:, None] * K
        P -= K[:, None] * Ph
        if (self._m + self._sym_phase) % 64 == 0:  # P is symmetric in exact arithmetic; remove the round-off
            P += P.T.copy()
            P *= 0.5


class BroydenEstimator:
    """Broyden's secant update with step gating (the estimator of `broyden`).

    step: relaxation of the update, 0 < step <= 1 (1: the classic update, J x = y exactly after it).
    min_speed: updates are skipped while ||x|| < min_speed, rad/s.
    """

    def __init__(self, n: int, *, step: float, min_speed: float):
        self._n = n
        self._step = step
        self._min2 = min_speed * min_speed
        self._J = np.zeros((3, n))
        self._Jdot = np.zeros((3, n))
        self.n_skipped = 0

    @property
    def J(self) -> np.ndarray:
        return self._J

    @property
    def Jdot(self) -> np.ndarray:
        return self._Jdot

    def reset(self) -> None:
        self._J = np.zeros((3, self._n))
        self.n_skipped = 0

    def init(self, J0: np.ndarray) -> None:
        self._J[:] = J0

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        xx = float(x @ x)
        if xx < self._min2 or xx == 0.0:
            self.n_skipped += 1
            return
        self._J += (self._step / xx) * np.outer(y - self._J @ x, x)


class RLSEstimator:
    """Recursive least squares with exponential forgetting and random-walk covariance (the estimator of `rls`).

    forgetting: lambda, 0 < lambda <= 1 per step (old pairs fade with a time constant of dt / (1 - lambda)).
    q_jacobian: variance added to each J entry's covariance per step, (m/rad)^2 (0: off).
    p0: initial covariance of each J entry (m/rad)^2 over (rad/s)^2 units of the regressor; p_max: bound on the
    covariance trace per entry, applied after every update.
    """

    def __init__(self, n: int, *, forgetting: float, q_jacobian: float, p0: float, p_max: float):
        self._n = n
        self._lambda = forgetting
        self._q = q_jacobian
        self._p0 = p0
        self._trace_max = p_max * n
        self._J = np.zeros((3, n))
        self._Jdot = np.zeros((3, n))
        self.P = p0 * np.eye(n)

    @property
    def J(self) -> np.ndarray:
        return self._J

    @property
    def Jdot(self) -> np.ndarray:
        return self._Jdot

    def reset(self) -> None:
        self._J = np.zeros((3, self._n))
        self.P = self._p0 * np.eye(self._n)

    def init(self, J0: np.ndarray) -> None:
        self._J[:] = J0
        self.P = self._p0 * np.eye(self._n)

    def update(self, x: np.ndarray, y: np.ndarray) -> None:
        P = self.P
        Px = P @ x
        K = Px / (self._lambda + x @ Px)
        self._J += np.outer(y - self._J @ x, K)
        P = (P - np.outer(K, Px)) / self._lambda
        P = 0.5 * (P + P.T)
        if self._q > 0:
            P[np.diag_indices(self._n)] += self._q
        tr = P.trace()
        if tr > self._trace_max:
            P *= self._trace_max / tr
        self.P = P

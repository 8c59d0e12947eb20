"""The model-free law of `nnbc-plus`, `broyden` and `rls` as scalar per-row kernels, over N rows.

One implementation (STYLE 14, 17): the scaffolding of `policies.laws.nnbc_plus` (probe, measurement, position filter,
actuator-model bank, joint-stop check and learnt stops, low-passed dither, posture pull, half-step lookahead,
damped pseudo-inverse) and the
four estimators of `policies.laws.estimators` (Kalman filter on [J | J_dot], its structured form with the wheel map
and the heading filter, Broyden's secant update, recursive least squares) are plain float code compiled with
numba (`@njit(cache=True)`), looped over the rows, with no matrix product (no BLAS): every sum is written out in
a fixed order, so row i of a batch equals the N = 1 call on row i bit for bit. The single-env controllers are
the N = 1 case (`policies.laws.nnbc_plus.EstimatingController` is a `LawView`). Random numbers stay in Python (each
row's Generator): the kernel flags the rows that need new dither signs or the J_hat(0) noise at their next step
(`I_NEED`), and the law draws them before that step, in the order and shapes the numpy version drew them.

Arrays (row i: robot i; n actuators, na = n - 2 arm joints, D = max_delay + 1 ring entries)

| array | shape | holds |
|---|---|---|
| `prm` | (PRM_LEN,) float | the law's constants (`PRM_*`) |
| `ipr` | (IPR_LEN,) int | the law's integer constants and switches (`IPR_*`) |
| `ep` | (EP_LEN,) float | the estimator's constants (`EP_*`) |
| `lay` | (LAY_LEN,) int | the offsets of the float state's blocks: `lay[LAY.hist]` (`FloatBlocks` names them) |
| `fst` | (N, F) float | the float state: the scaffolding's blocks, then the estimator's segment (`est_layout`) |
| `ist` | (N, I_LEN) int | step count, sign index, actuator model, delay, blocking flags, the draws due, estimator ints |
| `signs` | (N, SIGN_BLOCK, n + 3) float | each row's current block of random signs (dither, task dither) |
| `noise` | (N, 3, n) float | each row's standard-normal draw for J_hat(0)'s perturbation (`j0_noise`) |

Where the state is named: the blocks of `fst` are `FloatBlocks` (their order, names and widths, in one place:
`layout` computes the offsets `lay` from it; the kernels read `f[lay[LAY.hist] + ...]`, Python
`blocks(lay).hist`); the constants and integer state by their `PRM_*`, `IPR_*`, `EP_*` and `I_*` offsets below.

The estimator's segment (relative offsets; `kind`: `KALMAN`, `STRUCTURED`, `BROYDEN`, `RLS`): J (3 x n) at 0,
J_dot (3 x n) at 3n, then the kind's own state: the Kalman filter's [X; P] ((3 + 2k) x 2k, k = n or na) and its
innovation mean square, R and R's estimate; the structured estimate adds the heading, its rate, cos/sin, the lever,
its rate, the platform's velocity, the wheel map M (3 x 2) and its covariance (a, b, d); RLS its P (n x n).

May import: numpy, numba (through `mobman_env.numba_cache`), the standard library.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from mobman_env.numba_cache import njit

KALMAN, STRUCTURED, BROYDEN, RLS = 0, 1, 2, 3
SIGN_BLOCK = 256  # random dither signs are drawn this many steps at a time (one RNG call per row)
BLOCK_SPEED = 0.05  # rad/s: a command at least this fast that does not move the actuator marks it blocked
BLOCK_CHECKS = 2  # consecutive checks
BLOCK_WEIGHT = 1e-3  # pseudo-inverse weight of a blocked actuator
STOP_TIME = 0.1  # s: near a learnt stop an arm joint approaches it at most at (distance / STOP_TIME)
DELAY_SETTLE = 200  # steps during which the actuator model is refreshed every step
DELAY_EVERY = 10  # afterwards, every this many steps
N_LAGS = 6  # len(LAG_TAUS)
INNOV_MS0 = 1e-4  # (m/s)^2: initial running mean square of the Kalman filter's innovations
NEED_SIGNS, NEED_NOISE = 1, 2  # bits of ist[:, I_NEED]: what the row's next step draws

# --- the law's constants ---
(PRM_DT, PRM_HALF_DT, PRM_GAMMA, PRM_DAMPING, PRM_DITHER, PRM_TASK_DITHER, PRM_POSTURE, PRM_PROBE_SPEED) = range(8)
(PRM_J0_NOISE, PRM_POS_FILTER, PRM_EPS2, PRM_SING_DAMPING, PRM_BLOCK_RELEASE, PRM_DELAY_RATE, PRM_PROBE_RIDGE) = range(
    8, 15
)
PRM_DITHER_ALPHA = 15  # the dither's low-pass weight dt / (dt + dither_time) (1: white)
PRM_STOP_MARGIN = 16  # rad: the learnt stops' damper acts within this distance (0: off)
PRM_LAG_DECAY = 17  # N_LAGS entries: e^{-dt/tau}
PRM_LAG_RISE = PRM_LAG_DECAY + N_LAGS  # N_LAGS entries: tau (1 - e^{-dt/tau}) / dt
PRM_LEN = PRM_LAG_RISE + N_LAGS
(IPR_N, IPR_NA, IPR_NPROBE, IPR_D, IPR_MAXD, IPR_WHOLE, IPR_STRUCT, IPR_USEVEL) = range(8)
(IPR_LOOKAHEAD, IPR_PROBE_TRACK, IPR_BLOCK_EVERY, IPR_KIND, IPR_ANGLES) = range(8, 13)
IPR_LEN = 13
# --- the estimator's constants ---
(EP_DT, EP_QJ, EP_QR, EP_R0, EP_CLIP, EP_CLIP2, EP_RATE, EP_P0J, EP_P0R, EP_NOISE_RATE, EP_MIDPOINT) = range(11)
(EP_SYM_PHASE, EP_QPLAT, EP_RPLAT, EP_HEADING, EP_STEP, EP_MIN2, EP_LAMBDA, EP_QRLS, EP_P0RLS, EP_TRMAX) = range(11, 21)
EP_PROBE_NOISE = 21  # 1: the Kalman kinds' R starts at the probe's residual variance (`probe_noise_start`)
EP_LEN = 22
# --- the integer state ---
I_K, I_SIGN, I_MODEL, I_DELAY, I_COUNTING, I_ANYBLK, I_NEED, I_EST = range(8)
I_LEN = I_EST + 2  # the estimator's: Kalman update count or Broyden's skipped steps; heading initialised


# --- the float state's blocks (`layout`) ---
class FloatBlocks(NamedTuple):
    """The blocks of a row of `fst`, in order: `layout(n, max_delay, kind)` holds their offsets (an int array,
    `lay`, which the kernels index as `lay[LAY.hist]`) and `blocks` the same offsets by name. n actuators,
    na = n - 2 arm joints, D = max_delay + 1 ring entries; the widths are `layout`'s."""

    q0: int  # na: the arm angles at the reset (the posture pull's target), rad
    prev_q: int  # n: the last observed actuator angles, rad
    prev_s: int  # 3: the last measured position (r_a, or r_a - p_c in the paper's formulation), m
    s_filtered: int  # 3: the position filter's estimate, m
    prev_vd: int  # 3: the last target velocity (the lookahead's), m/s
    task_dither: int  # 3: this pair of steps' task dither, m/s
    lag_ms: int  # D + N_LAGS: the actuator models' running mean squares (delays 0..max_delay, then the lags)
    block_count: int  # n: consecutive checks each actuator looked blocked
    blocked: int  # n: the direction each actuator is blocked in (+1, -1; 0: free)
    block_q: int  # n: the angle where it was blocked, rad
    weights: int  # n: the pseudo-inverse's weights (`BLOCK_WEIGHT` for a blocked actuator)
    probe_a: int  # n x n: the probe's sum of x x^T
    probe_b: int  # 3 x n: the probe's sum of y x^T
    probe_yy: int  # 1: the probe's sum of |y|^2
    j_probe: int  # 3 x n: the probe's fit of J
    hist: int  # D x n: the commands issued (a ring, entry k % D holds step k - 1's)
    lag_x: int  # N_LAGS x n: each lag model's actuator speeds
    dither_z: int  # n: the low-passed dither
    stop: int  # n: the learnt stops' angles, rad
    stop_dir: int  # n: their directions (0: none)
    est: int  # the estimator's segment (`est_layout`)
    length: int  # the end: the row's length


#: the entries of `lay` by name: `lay[LAY.hist]` is the offset of the ring of commands
LAY = FloatBlocks(*range(len(FloatBlocks._fields)))
LAY_LEN = len(LAY)
# --- the structured estimate's scalars, after the Kalman filter's three ---
(S_YAW, S_YAWM, S_OMEGA, S_C, S_S, S_LX, S_LY, S_RX, S_RY, S_BX, S_BY) = range(3, 14)
S_M = 14  # the wheel map's rows (m0, n0, m1, n1, m2, n2)
S_P = 20  # its covariance (a, b, d)
S_LEN = 23


@njit(cache=True)
def est_nk(kind: int, n: int) -> int:
    """Columns of the Kalman filter's J (the arm's with the structured estimate), or n (a kernel: the Kalman
    kinds' kernels call it too)."""
    return n - 2 if kind == STRUCTURED else n


def est_layout(kind: int, n: int) -> tuple[int, int]:
    """(offset of the kind's state after J and J_dot, length of the estimator's segment)."""
    base = 6 * n
    if kind in (KALMAN, STRUCTURED):
        ns = 2 * est_nk(kind, n)
        return base, base + (3 + ns) * ns + (S_LEN if kind == STRUCTURED else 3)
    if kind == RLS:
        return base, base + n * n
    return base, base


def layout(n: int, max_delay: int, kind: int) -> np.ndarray:
    """The offsets `lay` of the float state's blocks (`FloatBlocks` order) for n actuators; lay[LAY.length] is
    the row's length."""
    d = max_delay + 1
    widths = FloatBlocks(
        q0=n - 2, prev_q=n, prev_s=3, s_filtered=3, prev_vd=3, task_dither=3, lag_ms=d + N_LAGS, block_count=n,
        blocked=n, block_q=n, weights=n, probe_a=n * n, probe_b=3 * n, probe_yy=1, j_probe=3 * n, hist=d * n, lag_x=N_LAGS * n,
        dither_z=n, stop=n, stop_dir=n, est=est_layout(kind, n)[1], length=0,
    )  # fmt: skip
    return np.concatenate([[0], np.cumsum(widths[:-1])]).astype(np.int64)


def blocks(lay: np.ndarray) -> FloatBlocks:
    """The offsets `lay` by name."""
    return FloatBlocks(*(int(o) for o in lay))


# --- the estimators ----------------------------------------------------------------------------------------
@njit(cache=True)
def est_reset(kind, n, ep, e, ie):
    """Forget everything (episode start): J = 0, J_dot = 0 and the kind's initial state."""
    base = 6 * n
    for j in range(base):
        e[j] = 0.0
    ie[0] = 0
    ie[1] = 0
    if kind <= STRUCTURED:  # the two Kalman kinds (KALMAN, STRUCTURED)
        nk = n - 2 if kind == STRUCTURED else n
        ns = 2 * nk
        for j in range((3 + ns) * ns):
            e[base + j] = 0.0
        for a in range(ns):
            e[base + (3 + a) * ns + a] = ep[EP_P0J] if a < nk else ep[EP_P0R]
        o = base + (3 + ns) * ns
        e[o] = INNOV_MS0
        e[o + 1] = ep[EP_R0]
        e[o + 2] = ep[EP_R0]
        if kind == STRUCTURED:
            for j in range(S_YAW, S_LEN):
                e[o + j] = 0.0
            e[o + S_C] = 1.0
            e[o + S_P] = ep[EP_P0J]
            e[o + S_P + 2] = ep[EP_P0J]
    elif kind == RLS:
        for a in range(n):
            for b in range(n):
                e[base + a * n + b] = ep[EP_P0RLS] if a == b else 0.0


@njit(cache=True)
def _compose(n, e):
    """The structured estimate's J and J_dot (world frame) from A, A_dot, M and the step's heading, rate and lever."""
    na = n - 2
    ns = 2 * na
    base = 6 * n
    o = base + (3 + ns) * ns
    c, s, w = e[o + S_C], e[o + S_S], e[o + S_OMEGA]
    lx, ly, rx, ry = e[o + S_LX], e[o + S_LY], e[o + S_RX], e[o + S_RY]
    m0, n0, m1, n1, m2, n2 = e[o + S_M], e[o + S_M + 1], e[o + S_M + 2], e[o + S_M + 3], e[o + S_M + 4], e[o + S_M + 5]
    jd = 3 * n
    for j in range(na):
        a0, a1, a2 = e[base + j], e[base + ns + j], e[base + 2 * ns + j]
        j0 = c * a0 - s * a1
        j1 = s * a0 + c * a1
        e[j] = j0
        e[n + j] = j1
        e[2 * n + j] = a2
        d0, d1, d2 = e[base + na + j], e[base + ns + na + j], e[base + 2 * ns + na + j]  # A_dot
        e[jd + j] = (c * d0 - s * d1) - w * j1
        e[jd + n + j] = (s * d0 + c * d1) + w * j0
        e[jd + 2 * n + j] = d2
    f0, f1 = c * m0 - s * m1, c * n0 - s * n1
    g0, g1 = s * m0 + c * m1, s * n0 + c * n1
    e[na] = f0 - ly * m2
    e[na + 1] = f1 - ly * n2
    e[n + na] = g0 + lx * m2
    e[n + na + 1] = g1 + lx * n2
    e[2 * n + na] = 0.0
    e[2 * n + na + 1] = 0.0
    e[jd + na] = -w * g0 - ry * m2
    e[jd + na + 1] = -w * g1 - ry * n2
    e[jd + n + na] = w * f0 + rx * m2
    e[jd + n + na + 1] = w * f1 + rx * n2
    e[jd + 2 * n + na] = 0.0
    e[jd + 2 * n + na + 1] = 0.0


@njit(cache=True)
def _kalman_to_j(n, e):
    """The whole-body (or paper) Kalman filter's J and J_dot: copies of X's two blocks."""
    base = 6 * n
    ns = 2 * n
    for r in range(3):
        for j in range(n):
            e[r * n + j] = e[base + r * ns + j]
            e[3 * n + r * n + j] = e[base + r * ns + n + j]


@njit(cache=True)
def est_init(kind, n, ep, e, ie, J0):
    """Start from the probed J_hat(0) (3 x n), J_dot = 0 (the structured estimate: A(0) from J0's arm columns
    turned into the platform's frame by the last observed heading)."""
    base = 6 * n
    if kind == KALMAN:
        ns = 2 * n
        for r in range(3):
            for j in range(n):
                e[base + r * ns + j] = J0[r, j]
                e[base + r * ns + n + j] = 0.0
        _kalman_to_j(n, e)
    elif kind == STRUCTURED:
        na = n - 2
        ns = 2 * na
        o = base + (3 + ns) * ns
        c, s = e[o + S_C], e[o + S_S]
        sn = -s
        for j in range(na):
            a0, a1 = J0[0, j], J0[1, j]
            e[base + j] = c * a0 - sn * a1
            e[base + ns + j] = sn * a0 + c * a1
            e[base + 2 * ns + j] = J0[2, j]
            for r in range(3):
                e[base + r * ns + na + j] = 0.0
        _compose(n, e)
    else:
        for r in range(3):
            for j in range(n):
                e[r * n + j] = J0[r, j]
        if kind == RLS:
            for a in range(n):
                for b in range(n):
                    e[base + a * n + b] = ep[EP_P0RLS] if a == b else 0.0


@njit(cache=True)
def est_noise_start(kind, n, ep, e, r0):
    """The Kalman kinds' measurement noise R (and its running estimate) start at r0 (m/s)^2, never below
    meas_std^2; the other kinds have no R."""
    if kind <= STRUCTURED and ep[EP_NOISE_RATE] > 0.0:
        ns = 2 * est_nk(kind, n)
        o = 6 * n + (3 + ns) * ns
        r = max(ep[EP_R0], r0)
        e[o + 1] = r
        e[o + 2] = r


@njit(cache=True, inline="always")
def probe_residual_variance(f, n, m, opa, opb, opyy, ojp):
    """The variance of one measured velocity component about the probe's least-squares fit J_hat(0), (m/s)^2:
    the residual sum of squares of its m pairs (sum |y|^2 - 2 tr(J B^T) + tr(J A J^T), A = sum x x^T, B = sum
    y x^T) over its 3 (m - n) degrees of freedom. It is what the sensors' noise adds to y (and what J's change
    over the probe's few steps adds, a little)."""
    rss = f[opyy]
    for r in range(3):
        jb = 0.0
        jaj = 0.0
        for a in range(n):
            ja = f[ojp + r * n + a]
            jb += ja * f[opb + r * n + a]
            aj = 0.0
            for b in range(n):
                aj += f[opa + a * n + b] * f[ojp + r * n + b]
            jaj += ja * aj
        rss += jaj - 2.0 * jb
    return max(rss, 0.0) / (3.0 * (m - n))


@njit(cache=True)
def _matvec(e, off, n, lim, v, out):
    """out[a] = sum over b < lim of M[a, b] v[b], for a < n and the n x n matrix M row-major at e[off:]; returns
    sum over a < lim of v[a] out[a] (v^T M v when v is 0 beyond lim)."""
    for a in range(n):
        acc = 0.0
        for b in range(lim):
            acc += e[off + a * n + b] * v[b]
        out[a] = acc
    q = 0.0
    for a in range(lim):
        q += v[a] * out[a]
    return q


@njit(cache=True)
def _symmetrise(e, off, n):
    """The n x n matrix row-major at e[off:] replaced by its symmetric part (round-off removed)."""
    for a in range(n):
        for b in range(a + 1, n):
            v = 0.5 * (e[off + a * n + b] + e[off + b * n + a])
            e[off + a * n + b] = v
            e[off + b * n + a] = v


@njit(cache=True)
def _kalman_update(ep, e, ie, base, nk, x, y0, y1, y2, h, ph):
    """One predict-update of the Kalman filter on [J | J_dot] (k = nk columns each) at e[base:]: constant-rate
    prediction, random-walk process noise, the robust gain-shared update of the three rows, R by covariance
    matching, P re-symmetrised every 64 updates (see `policies.laws.estimators.KalmanEstimator`)."""
    dt = ep[EP_DT]
    ns = 2 * nk
    ie[0] += 1
    m = ie[0]
    p0 = base + 3 * ns  # P's first entry
    for a in range(nk):  # the rows of F P
        for b in range(ns):
            e[p0 + a * ns + b] += dt * e[p0 + (nk + a) * ns + b]
    for r in range(3 + ns):  # X's constant-rate prediction and the columns of (F P) F^T
        for b in range(nk):
            e[base + r * ns + b] += dt * e[base + r * ns + nk + b]
    qj, qr = ep[EP_QJ], ep[EP_QR]
    if qj != 0.0 or qr != 0.0:
        for a in range(ns):
            e[p0 + a * ns + a] += qj if a < nk else qr
    midpoint = ep[EP_MIDPOINT] != 0.0
    for j in range(nk):
        h[j] = x[j]
        h[nk + j] = -0.5 * dt * x[j] if midpoint else 0.0
    lim = ns if midpoint else nk  # (the entries of h beyond are 0)
    hph = _matvec(e, p0, ns, lim, h, ph)
    i0, i1, i2 = y0, y1, y2
    for b in range(lim):
        i0 -= e[base + b] * h[b]
        i1 -= e[base + ns + b] * h[b]
        i2 -= e[base + 2 * ns + b] * h[b]
    n2 = i0 * i0 + i1 * i1 + i2 * i2
    o = base + (3 + ns) * ns
    s = hph + e[o + 1]
    if ep[EP_CLIP] > 0.0:
        lim2 = ep[EP_CLIP2] * e[o]
        if n2 > lim2:
            f = (lim2 / n2) ** 0.5
            i0, i1, i2 = i0 * f, i1 * f, i2 * f
            n2 = lim2
        e[o] += ep[EP_RATE] * (n2 - e[o])
    if ep[EP_NOISE_RATE] > 0.0:
        e[o + 2] += ep[EP_NOISE_RATE] * (n2 / 3.0 - hph - e[o + 2])
        e[o + 1] = max(ep[EP_R0], e[o + 2])
    for b in range(ns):
        k = ph[b] / s
        e[base + b] += i0 * k
        e[base + ns + b] += i1 * k
        e[base + 2 * ns + b] += i2 * k
    for a in range(ns):
        ka = ph[a] / s
        for b in range(ns):
            e[p0 + a * ns + b] -= ka * ph[b]
    if (m + int(ep[EP_SYM_PHASE])) % 64 == 0:
        _symmetrise(e, p0, ns)


@njit(cache=True)
def est_observe(n, ep, e, ie, measured, w0, w1, e0, e1, p0, p1, v0, v1, b0, b1):
    """The structured estimate's platform measurements of this step: the heading (filtered with the wheel map's
    rate, `heading_filter`) and its rate, the lever r_a - p_c, and the wheel map's update when the wheels turn."""
    na = n - 2
    ns = 2 * na
    o = 6 * n + (3 + ns) * ns
    dt = ep[EP_DT]
    yaw = measured
    omega_measured = 0.0
    if ie[1] != 0:
        omega_measured = (measured - e[o + S_YAWM]) / dt
        a = ep[EP_HEADING]
        if a < 1.0:
            predicted = e[o + S_YAW] + dt * (e[o + S_M + 4] * w0 + e[o + S_M + 5] * w1)
            yaw = predicted + a * _remainder_2pi(measured - predicted)
        e[o + S_OMEGA] = (yaw - e[o + S_YAW]) / dt
    ie[1] = 1
    e[o + S_YAWM] = measured
    e[o + S_YAW] = yaw
    c, s = math.cos(yaw), math.sin(yaw)
    e[o + S_C] = c
    e[o + S_S] = s
    e[o + S_LX] = e0 - p0
    e[o + S_LY] = e1 - p1
    e[o + S_BX] = b0
    e[o + S_BY] = b1
    e[o + S_RX] = v0 - b0
    e[o + S_RY] = v1 - b1
    if w0 != 0.0 or w1 != 0.0:  # the wheel map: a 2 x 2-covariance Kalman filter shared by its three rows
        q, r = ep[EP_QPLAT], ep[EP_RPLAT]
        pa, pb, pd = e[o + S_P] + q, e[o + S_P + 1], e[o + S_P + 2] + q
        h0 = pa * w0 + pb * w1
        h1 = pb * w0 + pd * w1
        sv = w0 * h0 + w1 * h1 + r
        k0, k1 = h0 / sv, h1 / sv
        z0, z1, z2 = c * b0 + s * b1, c * b1 - s * b0, omega_measured
        for row in range(3):
            zi = z0 if row == 0 else (z1 if row == 1 else z2)
            ma, mb = e[o + S_M + 2 * row], e[o + S_M + 2 * row + 1]
            err = zi - (ma * w0 + mb * w1)
            e[o + S_M + 2 * row] = ma + k0 * err
            e[o + S_M + 2 * row + 1] = mb + k1 * err
        pb = pb - k0 * h1
        e[o + S_P] = pa - k0 * h0
        e[o + S_P + 1] = pb
        e[o + S_P + 2] = pd - k1 * h1
    _compose(n, e)


@njit(cache=True)
def _remainder_2pi(x):
    """math.remainder(x, 2 pi): x minus the nearest multiple of 2 pi (ties to even)."""
    y = 2.0 * math.pi
    q = x / y
    k = math.floor(q + 0.5)
    if k - q == 0.5 and k % 2.0 != 0.0:  # a tie: to the even multiple
        k -= 1.0
    if k == 0.0:
        return x
    return x - k * y


@njit(cache=True)
def est_update(kind, n, ep, e, ie, x, y0, y1, y2, h, ph):
    """One measurement y = J x (x: the n actuator speeds, rad/s; y: m/s) for the estimator of `kind`."""
    base = 6 * n
    if kind == KALMAN:
        _kalman_update(ep, e, ie, base, n, x, y0, y1, y2, h, ph)
        _kalman_to_j(n, e)
    elif kind == STRUCTURED:  # A learns the arm's share of y, in the platform's frame
        na = n - 2
        ns = 2 * na
        o = base + (3 + ns) * ns
        c, s, w = e[o + S_C], e[o + S_S], e[o + S_OMEGA]
        a0 = y0 - e[o + S_BX] + w * e[o + S_LY]
        a1 = y1 - e[o + S_BY] - w * e[o + S_LX]
        _kalman_update(ep, e, ie, base, na, x, c * a0 + s * a1, c * a1 - s * a0, y2, h, ph)
        _compose(n, e)
    elif kind == BROYDEN:
        xx = 0.0
        for j in range(n):
            xx += x[j] * x[j]
        if xx < ep[EP_MIN2] or xx == 0.0:
            ie[0] += 1
            return
        f = ep[EP_STEP] / xx
        for r in range(3):
            res = y0 if r == 0 else (y1 if r == 1 else y2)
            for j in range(n):
                res -= e[r * n + j] * x[j]
            for j in range(n):
                e[r * n + j] += f * (res * x[j])
    else:  # RLS: K = P x / (lambda + x^T P x), J += (y - J x) K^T, P <- (P - K (P x)^T) / lambda, bounded
        lam = ep[EP_LAMBDA]
        den = lam + _matvec(e, base, n, n, x, ph)
        for a in range(n):
            h[a] = ph[a] / den
        for r in range(3):
            res = y0 if r == 0 else (y1 if r == 1 else y2)
            for j in range(n):
                res -= e[r * n + j] * x[j]
            for j in range(n):
                e[r * n + j] += res * h[j]
        for a in range(n):
            for b in range(n):
                e[base + a * n + b] = (e[base + a * n + b] - h[a] * ph[b]) / lam
        _symmetrise(e, base, n)
        q = ep[EP_QRLS]
        tr = 0.0
        for a in range(n):
            if q > 0.0:
                e[base + a * n + a] += q
            tr += e[base + a * n + a]
        if tr > ep[EP_TRMAX]:
            f = ep[EP_TRMAX] / tr
            for j in range(n * n):
                e[base + j] *= f


# --- the scaffolding ---------------------------------------------------------------------------------------
@njit(cache=True)
def reset_rows(prm, ipr, ep, lay, fst, ist, rows, jp, ee_pos, abp, tv):
    """Re-initialise the rows `rows` from their observations (the episode start)."""
    n, na, whole, kind = ipr[IPR_N], ipr[IPR_NA], ipr[IPR_WHOLE], ipr[IPR_KIND]
    for r in range(rows.shape[0]):
        i = rows[r]
        f = fst[i]
        for j in range(lay[LAY.est]):
            f[j] = 0.0
        for j in range(ist.shape[1]):
            ist[i, j] = 0
        for j in range(na):
            f[lay[LAY.q0] + j] = jp[i, j]
        for j in range(n):
            f[lay[LAY.prev_q] + j] = jp[i, j]
            f[lay[LAY.weights] + j] = 1.0
        s0, s1, s2 = ee_pos[i, 0], ee_pos[i, 1], ee_pos[i, 2]
        if whole == 0:
            s0, s1 = s0 - abp[i, 0], s1 - abp[i, 1]
        o, osf = lay[LAY.prev_s], lay[LAY.s_filtered]
        f[o], f[o + 1], f[o + 2] = s0, s1, s2
        f[osf], f[osf + 1], f[osf + 2] = s0, s1, s2
        for j in range(3):
            f[lay[LAY.prev_vd] + j] = tv[i, j]
        est_reset(kind, n, ep, f[lay[LAY.est] :], ist[i, I_EST:])


@njit(cache=True)
def _solve3(a, b, c, d, e, f, g, h, i, p, q, r, damping, eps2, extra):
    """(A + damping I + d I)^-1 rhs for the symmetric 3 x 3 A (its nine entries a..i), by cofactors. damping I is
    added entry by entry (off the diagonal + 0.0); d = 0, unless eps2 > 0 and the damped A's smallest eigenvalue
    (estimated as det(A) / e2(A), e2 the sum of the principal 2 x 2 minors) is below eps2: then d = extra
    (1 - estimate / eps2), the singularity-robust damping of `policies.laws.nnbc_plus.ModelFreeConfig.sing_damping`."""
    off = damping * 0.0
    a, b, c = a + damping, b + off, c + off
    d, e, f = d + off, e + damping, f + off
    g, h, i = g + off, h + off, i + damping
    if eps2 > 0.0:
        e2 = (e * i - f * h) + (a * i - c * g) + (a * e - b * d)
        det = a * (e * i - f * h) + b * (f * g - d * i) + c * (d * h - e * g)
        low = det / e2 if e2 > 0.0 else 0.0
        if low < eps2:
            add = extra * (1.0 - max(low, 0.0) / eps2)
            a += add
            e += add
            i += add
    c00, c01, c02 = e * i - f * h, c * h - b * i, b * f - c * e
    c10, c11, c12 = f * g - d * i, a * i - c * g, c * d - a * f
    c20, c21, c22 = d * h - e * g, b * g - a * h, a * e - b * d
    inv_det = 1.0 / (a * c00 + b * c10 + c * c20)
    return (
        (c00 * p + c01 * q + c02 * r) * inv_det,
        (c10 * p + c11 * q + c12 * r) * inv_det,
        (c20 * p + c21 * q + c22 * r) * inv_det,
    )


@njit(cache=True)
def _cholesky_solve(A, B, n, ridge, L, X):
    """X (n x 3) = (A + ridge I)^-1 B^T for the symmetric positive definite n x n A (row-major in a flat array)
    and B (3 x n, flat), by Cholesky (L: n x n scratch); returns False when the matrix is not positive definite."""
    for j in range(n):
        s = A[j * n + j] + ridge
        for k in range(j):
            s -= L[j * n + k] * L[j * n + k]
        if not s > 0.0:
            return False
        ljj = math.sqrt(s)
        L[j * n + j] = ljj
        for i in range(j + 1, n):
            t = A[i * n + j]
            for k in range(j):
                t -= L[i * n + k] * L[j * n + k]
            L[i * n + j] = t / ljj
    for c in range(3):
        for i in range(n):  # L z = b
            t = B[c * n + i]
            for k in range(i):
                t -= L[i * n + k] * X[k * 3 + c]
            X[i * 3 + c] = t / L[i * n + i]
        for i in range(n - 1, -1, -1):  # L^T x = z
            t = X[i * 3 + c]
            for k in range(i + 1, n):
                t -= L[k * n + i] * X[k * 3 + c]
            X[i * 3 + c] = t / L[i * n + i]
    return True


@njit(cache=True)
def act_rows(prm, ipr, ep, lay, fst, ist, ee_pos, ee_vel, abp, abv, jp, jv, tp, tv, yaw, last_u, signs, noise, u):
    """One control step of every row: u (N, n) rad/s before the speed clip. Returns the number of rows whose next
    step draws random numbers (flagged in ist[:, I_NEED]). The step's sections are the helpers below, in order:
    `_measure`, `_actuator_model`, `_check_blocked`, `_estimate`, `_target`, `_excitation`, `_solve_row`."""
    nrow = fst.shape[0]
    n, na, n_probe, dd = ipr[IPR_N], ipr[IPR_NA], ipr[IPR_NPROBE], ipr[IPR_D]
    structured, angles = ipr[IPR_STRUCT] != 0, ipr[IPR_ANGLES] != 0
    oest = lay[LAY.est]
    x = np.empty(n)
    avg = np.empty(n)
    pred = np.empty(n)
    lagavg = np.empty(N_LAGS * n)
    h = np.empty(2 * n)
    ph = np.empty(2 * n)
    z = np.empty(n)
    jc = np.empty((3, n))
    jw = np.empty((3, n))
    moved = np.empty(n)
    qa = np.empty(n)
    lsc = np.empty(n * n)
    xs = np.empty(3 * n)
    j0 = np.empty((3, n))
    need = 0
    for i in range(nrow):
        f = fst[i]
        it = ist[i]
        e = f[oest:]
        ie = it[I_EST:]
        k = it[I_K]
        it[I_K] = k + 1
        ring = k % dd
        for j in range(n):
            f[lay[LAY.hist] + ring * n + j] = last_u[i, j]  # the command issued at step k - 1
        probing = k < n_probe
        # --- the measurement (x, y), the position filter, the actuator model
        y0, y1, y2 = _measure(prm, ipr, lay, f, i, probing, ee_pos, ee_vel, abp, abv, jp, jv, x, avg)
        _actuator_model(prm, ipr, lay, f, it, i, k, ring, last_u, jp, x, avg, pred, lagavg)
        if structured:  # the platform's measurements (every step: the wheel map learns from the probe too)
            w0, w1 = (x[na], x[na + 1]) if angles else (jv[i, na], jv[i, na + 1])
            est_observe(
                n, ep, e, ie, yaw[i, 0], w0, w1, ee_pos[i, 0], ee_pos[i, 1], abp[i, 0], abp[i, 1], ee_vel[i, 0],
                ee_vel[i, 1], abv[i, 0], abv[i, 1],
            )  # fmt: skip
        if prm[PRM_BLOCK_RELEASE] > 0.0 and k > 1 and k % ipr[IPR_BLOCK_EVERY] == 0:
            _check_blocked(prm, lay, f, it, n, na, avg if angles else x, pred, jp[i])
        # --- the estimate
        _estimate(prm, ipr, ep, lay, f, e, ie, i, k, x, y0, y1, y2, noise, h, ph, lsc, xs, j0)
        # --- control: u = z + J_c^+ (v - J_c z)
        v0, v1, v2 = _target(prm, ipr, lay, f, e, it, i, ring, probing, abp, abv, jp, tp, tv, jc, moved, qa)
        v0, v1, v2 = _excitation(prm, ipr, lay, f, it, i, k, probing, signs, qa, z, v0, v1, v2)
        _solve_row(prm, lay, f, it, i, k, n, probing, qa, jc, jw, z, v0, v1, v2, u)
        # --- the random numbers the row's next step draws
        k1 = k + 1
        flag = 0
        if k1 >= n_probe and (k1 - n_probe) % SIGN_BLOCK == 0:
            flag |= NEED_SIGNS
        if k1 == n_probe and prm[PRM_J0_NOISE] > 0.0:
            flag |= NEED_NOISE
        it[I_NEED] = flag
        if flag:
            need += 1
    return need


@njit(cache=True, inline="always")
def _measure(prm, ipr, lay, f, i, probing, ee_pos, ee_vel, abp, abv, jp, jv, x, avg):
    """This step's measurement: y (returned) and x (with `measurement="angles"`, x is set by `_actuator_model`;
    avg: the actuators' mean speeds over the last step, from the joint angles), and the position filter."""
    n, dt = ipr[IPR_N], prm[PRM_DT]
    whole, use_vel, angles = ipr[IPR_WHOLE] != 0, ipr[IPR_USEVEL] != 0, ipr[IPR_ANGLES] != 0
    oprevq, oprevs, osf = lay[LAY.prev_q], lay[LAY.prev_s], lay[LAY.s_filtered]
    ax, ay = (0.0, 0.0) if whole else (abp[i, 0], abp[i, 1])
    s0, s1, s2 = ee_pos[i, 0] - ax, ee_pos[i, 1] - ay, ee_pos[i, 2]
    if use_vel:
        y0, y1, y2 = ee_vel[i, 0], ee_vel[i, 1], ee_vel[i, 2]
        if not whole:
            y0, y1 = y0 - abv[i, 0], y1 - abv[i, 1]
        ds0, ds1, ds2 = dt * y0, dt * y1, dt * y2
        for j in range(n):
            if angles:
                avg[j] = (jp[i, j] - f[oprevq + j]) / dt
                f[oprevq + j] = jp[i, j]
            else:
                x[j] = jv[i, j]
    else:
        oj = lay[LAY.j_probe] if probing else lay[LAY.est]  # J_probe, or the estimator's J (both 3 x n at their offset)
        ds0 = ds1 = ds2 = 0.0
        for j in range(n):
            dq = jp[i, j] - f[oprevq + j]
            x[j] = dq / dt
            avg[j] = x[j]
            ds0 += f[oj + j] * dq
            ds1 += f[oj + n + j] * dq
            ds2 += f[oj + 2 * n + j] * dq
            f[oprevq + j] = jp[i, j]
        y0 = (s0 - f[oprevs]) / dt
        y1 = (s1 - f[oprevs + 1]) / dt
        y2 = (s2 - f[oprevs + 2]) / dt
        f[oprevs], f[oprevs + 1], f[oprevs + 2] = s0, s1, s2
    a = prm[PRM_POS_FILTER]
    g0, g1, g2 = f[osf] + ds0, f[osf + 1] + ds1, f[osf + 2] + ds2
    f[osf], f[osf + 1], f[osf + 2] = g0 + a * (s0 - g0), g1 + a * (s1 - g1), g2 + a * (s2 - g2)
    return y0, y1, y2


@njit(cache=True, inline="always")
def _actuator_model(prm, ipr, lay, f, it, i, k, ring, last_u, jp, x, avg, pred, lagavg):
    """Advance the lag models by the command of step k - 1, choose the actuator model that best matches the
    measured speeds (`policies.laws.nnbc_plus.LAG_TAUS`), and fill pred with its speeds. `measurement="velocity"`:
    the measured joint_vel (x) against each model's speeds at t_k; `"angles"`: the mean speeds over the step from
    the joint angles (avg) against each model's mean, and x is then avg turned into the speeds at t_k under the
    chosen model (a lag: u(t_k) = c + (mean - c) e^{-dt/tau} / (tau (1 - e^{-dt/tau}) / dt), c the command; a
    delay: the speed is constant over the step, x = avg)."""
    n, dd, maxd = ipr[IPR_N], ipr[IPR_D], ipr[IPR_MAXD]
    angles = ipr[IPR_ANGLES] != 0
    olagx, ohist, olagms = lay[LAY.lag_x], lay[LAY.hist], lay[LAY.lag_ms]
    for m in range(N_LAGS):  # each lag model's actuator speeds after the command of step k - 1
        dec, rise = prm[PRM_LAG_DECAY + m], prm[PRM_LAG_RISE + m]
        for j in range(n):
            lu = last_u[i, j]
            old = f[olagx + m * n + j] - lu
            lagavg[m * n + j] = lu + old * rise
            f[olagx + m * n + j] = lu + old * dec
    meas = avg if angles else x
    n_seen = k + 1
    if n_seen >= 2 and (n_seen <= DELAY_SETTLE or n_seen % DELAY_EVERY == 0):
        rate = prm[PRM_DELAY_RATE]
        best = 0
        for m in range(dd + N_LAGS):
            ss = 0.0
            for j in range(n):
                if m < dd:
                    df = f[ohist + ((ring - m) % dd) * n + j] - meas[j]
                else:
                    df = (lagavg[(m - dd) * n + j] if angles else f[olagx + (m - dd) * n + j]) - meas[j]
                ss += df * df
            v = f[olagms + m] + rate * (ss - f[olagms + m])
            f[olagms + m] = v
            if v < f[olagms + best]:
                best = m
        it[I_MODEL] = best
        it[I_DELAY] = best if best <= maxd else 0
    mm = it[I_MODEL] - maxd - 1
    for j in range(n):
        if mm >= 0:
            pred[j] = lagavg[mm * n + j] if angles else f[olagx + mm * n + j]
        else:
            pred[j] = f[ohist + ((ring - it[I_DELAY]) % dd) * n + j]
    if angles:
        ost, osd = lay[LAY.stop], lay[LAY.stop_dir]
        for j in range(n):
            if f[osd + j] != 0.0 and jp[i, j] == f[ost + j]:
                x[j] = 0.0  # held at a learnt stop: it ended the step there, at rest
            elif mm >= 0:
                c = last_u[i, j]
                x[j] = c + (avg[j] - c) * (prm[PRM_LAG_DECAY + mm] / prm[PRM_LAG_RISE + mm])
            else:
                x[j] = avg[j]


@njit(cache=True, inline="always")
def _estimate(prm, ipr, ep, lay, f, e, ie, i, k, x, y0, y1, y2, noise, h, ph, lsc, xs, j0):
    """The estimate's step: the probe's least-squares fit (and at its end J_hat(0), perturbed by `j0_noise`), or
    the estimator's update."""
    n, n_probe, kind = ipr[IPR_N], ipr[IPR_NPROBE], ipr[IPR_KIND]
    ojp = lay[LAY.j_probe]
    if k <= n_probe:
        if k > 0:
            _probe_fit(
                prm, f, n, x, y0, y1, y2, k == n_probe, lay[LAY.probe_a], lay[LAY.probe_b], lay[LAY.probe_yy], ojp,
                lsc, xs,
            )  # fmt: skip
        if k == n_probe:
            for r in range(3):
                for j in range(n):
                    j0[r, j] = f[ojp + r * n + j]
            g = prm[PRM_J0_NOISE]
            if g > 0.0:
                nj = nn = 0.0
                for r in range(3):
                    for j in range(n):
                        nj += j0[r, j] * j0[r, j]
                        nn += noise[i, r, j] * noise[i, r, j]
                sc = g * math.sqrt(nj) / math.sqrt(nn)
                for r in range(3):
                    for j in range(n):
                        j0[r, j] = j0[r, j] + sc * noise[i, r, j]
            est_init(kind, n, ep, e, ie, j0)
            if ep[EP_PROBE_NOISE] != 0.0 and n_probe > n:
                r0 = probe_residual_variance(f, n, n_probe, lay[LAY.probe_a], lay[LAY.probe_b], lay[LAY.probe_yy], ojp)
                est_noise_start(kind, n, ep, e, r0)
    else:
        est_update(kind, n, ep, e, ie, x, y0, y1, y2, h, ph)


@njit(cache=True, inline="always")
def _target(prm, ipr, lay, f, e, it, i, ring, probing, abp, abv, jp, tp, tv, jc, moved, qa):
    """J_c (J_hat extrapolated half a step) into jc, the arm angles (predicted over the compensated delay) into
    qa, and the task velocity v (returned): the target's velocity half a step ahead plus the feedback on the
    filtered position, predicted forward by J_hat times the commands issued since the (delayed) observation."""
    n, na, dd, dt = ipr[IPR_N], ipr[IPR_NA], ipr[IPR_D], prm[PRM_DT]
    oj = lay[LAY.j_probe] if probing else lay[LAY.est]
    oprevvd, osf, ohist = lay[LAY.prev_vd], lay[LAY.s_filtered], lay[LAY.hist]
    v0, v1, v2 = tv[i, 0], tv[i, 1], tv[i, 2]
    look = ipr[IPR_LOOKAHEAD] != 0 and not probing
    hd = prm[PRM_HALF_DT]
    for r in range(3):
        for j in range(n):
            jr = f[oj + r * n + j]
            jc[r, j] = jr + hd * e[3 * n + r * n + j] if look else jr
    if look:
        p0, p1, p2 = f[oprevvd], f[oprevvd + 1], f[oprevvd + 2]
        v0, v1, v2 = 1.5 * v0 - 0.5 * p0, 1.5 * v1 - 0.5 * p1, 1.5 * v2 - 0.5 * p2
    f[oprevvd], f[oprevvd + 1], f[oprevvd + 2] = tv[i, 0], tv[i, 1], tv[i, 2]
    d0, d1, d2 = tp[i, 0], tp[i, 1], tp[i, 2]
    if ipr[IPR_WHOLE] == 0:
        d0, d1 = d0 - abp[i, 0], d1 - abp[i, 1]
        v0, v1 = v0 - abv[i, 0], v1 - abv[i, 1]
    f0, f1, f2 = f[osf], f[osf + 1], f[osf + 2]
    for j in range(na):
        qa[j] = jp[i, j]
    dly = it[I_DELAY]
    if dly > 0:  # the observation is dly steps old: predict it forward by the commands issued since
        for j in range(n):
            acc = f[ohist + ring * n + j]
            for m in range(1, dly):
                acc += f[ohist + ((ring - m) % dd) * n + j]
            moved[j] = acc * dt
        m0 = m1 = m2 = 0.0
        for j in range(n):
            m0 += f[oj + j] * moved[j]
            m1 += f[oj + n + j] * moved[j]
            m2 += f[oj + 2 * n + j] * moved[j]
        f0, f1, f2 = f0 + m0, f1 + m1, f2 + m2
        for j in range(na):
            qa[j] = qa[j] + moved[j]
    g = prm[PRM_GAMMA]
    return v0 + g * (d0 - f0), v1 + g * (d1 - f1), v2 + g * (d2 - f2)


@njit(cache=True, inline="always")
def _excitation(prm, ipr, lay, f, it, i, k, probing, signs, qa, z, v0, v1, v2):
    """The null-space motion z (the posture pull and the random-sign dither, low-passed with `dither_time`) and
    v with the task dither added (returned)."""
    n, na = ipr[IPR_N], ipr[IPR_NA]
    oq0, otd = lay[LAY.q0], lay[LAY.task_dither]
    pg = prm[PRM_POSTURE]
    for j in range(n):
        z[j] = (f[oq0 + j] - qa[j]) * pg if (pg > 0.0 and j < na) else 0.0
    if not probing:
        si = it[I_SIGN] % SIGN_BLOCK
        it[I_SIGN] += 1
        td = prm[PRM_TASK_DITHER]
        if td > 0.0:
            if k % 2 == 0:
                for j in range(3):
                    f[otd + j] = td * signs[i, si, n + j]
                v0, v1, v2 = v0 + f[otd], v1 + f[otd + 1], v2 + f[otd + 2]
            else:
                v0, v1, v2 = v0 - f[otd], v1 - f[otd + 1], v2 - f[otd + 2]
        dz, al = prm[PRM_DITHER], prm[PRM_DITHER_ALPHA]
        if dz > 0.0:
            odz = lay[LAY.dither_z]
            for j in range(n):
                dj = dz * signs[i, si, j]
                if al < 1.0:  # the low-passed signs (`dither_time`)
                    dj = f[odz + j] + al * (dj - f[odz + j])
                    f[odz + j] = dj
                z[j] = dj + z[j] if pg > 0.0 else dj
    if probing and ipr[IPR_PROBE_TRACK] == 0:
        v0 = v1 = v2 = 0.0
        for j in range(n):
            z[j] = 0.0
    return v0, v1, v2


@njit(cache=True, inline="always")
def _solve_row(prm, lay, f, it, i, k, n, probing, q, jc, jw, z, v0, v1, v2, u):
    """u[i] = z + J_w^T (J_c J_w^T + damping)^-1 (v - J_c z), J_w = J_c W (the joint-stop weights, and within
    `stop_margin` of a learnt stop a weight falling with the distance), the probe on top, never further into a
    stop, and towards a learnt stop at most at distance / STOP_TIME."""
    ow, obl, ost, osd = lay[LAY.weights], lay[LAY.blocked], lay[LAY.stop], lay[LAY.stop_dir]
    anyb = it[I_ANYBLK] != 0
    margin = prm[PRM_STOP_MARGIN]
    for j in range(n):
        wj = f[ow + j] if anyb else 1.0
        if margin > 0.0 and f[osd + j] != 0.0:
            dist = (f[ost + j] - q[j]) * f[osd + j]
            if dist < margin:
                wj = min(wj, max(BLOCK_WEIGHT, max(dist, 0.0) / margin))
        for r in range(3):
            jw[r, j] = jc[r, j] * wj if (anyb or wj != 1.0) else jc[r, j]
    r0 = r1 = r2 = 0.0
    a00 = a01 = a02 = a10 = a11 = a12 = a20 = a21 = a22 = 0.0
    for j in range(n):
        c0, c1, c2 = jc[0, j], jc[1, j], jc[2, j]
        w0, w1, w2 = jw[0, j], jw[1, j], jw[2, j]
        r0 += c0 * z[j]
        r1 += c1 * z[j]
        r2 += c2 * z[j]
        a00 += w0 * c0
        a01 += w0 * c1
        a02 += w0 * c2
        a10 += w1 * c0
        a11 += w1 * c1
        a12 += w1 * c2
        a20 += w2 * c0
        a21 += w2 * c1
        a22 += w2 * c2
    l0, l1, l2 = _solve3(
        a00, a01, a02, a10, a11, a12, a20, a21, a22, v0 - r0, v1 - r1, v2 - r2,
        prm[PRM_DAMPING], prm[PRM_EPS2], prm[PRM_SING_DAMPING],
    )  # fmt: skip
    for j in range(n):
        uj = z[j] + (jw[0, j] * l0 + jw[1, j] * l1 + jw[2, j] * l2)
        if probing and j == k // 2:  # actuator k // 2 at +probe_speed, then -probe_speed (back)
            uj += prm[PRM_PROBE_SPEED] if k % 2 == 0 else -prm[PRM_PROBE_SPEED]
        if anyb and f[obl + j] * uj > 0.0:  # never further into a stop
            uj = 0.0
        if margin > 0.0 and f[osd + j] != 0.0:  # the learnt stop's damper
            cap = max((f[ost + j] - q[j]) * f[osd + j], 0.0) / STOP_TIME
            if uj * f[osd + j] > cap:
                uj = cap * f[osd + j]
        u[i, j] = uj


@njit(cache=True)
def _check_blocked(prm, lay, f, it, n, na, x, cm, q):
    """Mark the actuators that were commanded (cm: the speeds the actuator model predicts) but did not move (x:
    the measured speeds); release those that moved `block_release` away
    (`policies.laws.nnbc_plus.ModelFreeConfig.block_release`). An arm joint's block is also learnt as a stop (its
    angle and direction, kept for the episode: `stop_margin`)."""
    obc, obl, obq, ow = lay[LAY.block_count], lay[LAY.blocked], lay[LAY.block_q], lay[LAY.weights]
    if it[I_COUNTING] == 0 and it[I_ANYBLK] == 0:
        quiet = True
        for j in range(n):
            cj = cm[j]
            if not cj * (x[j] - 0.1 * cj) >= 0.0:
                quiet = False
                break
        if quiet:
            return
    counting = False
    new_any = False
    for j in range(n):
        cj = cm[j]
        stuck = cj * (x[j] - 0.1 * cj) < 0.0 and cj * cj > BLOCK_SPEED * BLOCK_SPEED
        cnt = f[obc + j] + 1.0 if stuck else 0.0
        f[obc + j] = cnt
        counting = counting or stuck
        if cnt >= BLOCK_CHECKS and f[obl + j] == 0.0:
            f[obl + j] = 1.0 if cj > 0.0 else (-1.0 if cj < 0.0 else 0.0)
            f[obq + j] = q[j]
            new_any = True
            if j < na and prm[PRM_STOP_MARGIN] > 0.0:
                f[lay[LAY.stop] + j] = q[j]
                f[lay[LAY.stop_dir] + j] = f[obl + j]
    it[I_COUNTING] = 1 if counting else 0
    if it[I_ANYBLK] != 0 or new_any:
        anyb = False
        rel = prm[PRM_BLOCK_RELEASE]
        for j in range(n):
            if abs(q[j] - f[obq + j]) > rel:
                f[obl + j] = 0.0
            anyb = anyb or f[obl + j] != 0.0
        it[I_ANYBLK] = 1 if anyb else 0
        for j in range(n):
            f[ow + j] = BLOCK_WEIGHT if f[obl + j] != 0.0 else 1.0


@njit(cache=True)
def _probe_fit(prm, f, n, x, y0, y1, y2, final, opa, opb, opyy, ojp, lsc, xs):
    """J_hat during the probe: the ridge-regularised least squares of the (x, y) pairs so far (final: the tiny
    ridge of the finished probe, J_hat(0)); the pairs' sum of |y|^2 beside (`probe_residual_variance`)."""
    f[opyy] += y0 * y0 + y1 * y1 + y2 * y2
    tr = 0.0
    for a in range(n):
        for b in range(n):
            f[opa + a * n + b] += x[a] * x[b]
        f[opb + a] += y0 * x[a]
        f[opb + n + a] += y1 * x[a]
        f[opb + 2 * n + a] += y2 * x[a]
        tr += f[opa + a * n + a]
    if tr <= 0.0:  # no actuator moved: no information
        return
    ridge = 1e-9 * tr / n if final else prm[PRM_PROBE_RIDGE]
    if _cholesky_solve(f[opa : opa + n * n], f[opb : opb + 3 * n], n, ridge, lsc, xs):
        for a in range(n):
            for r in range(3):
                f[ojp + r * n + a] = xs[a * 3 + r]

"""The engine: the kinematic step of N wheeled mobile manipulators, written once as scalar per-robot code.

Everything the env computes about a robot's motion lives here, in plain float arithmetic that numba compiles
(`@njit(cache=True)`) and loops over robots: the DH chain (standard and modified, any n), the end-effector point,
the arm's and the whole-body Jacobian, the arm mount p_c, the unicycle platform, the actuators (clipping, the
joint-limit rule, the first-order lag `actuator_tau`), the wear drift, the targets of every path type, the
tracking error, the reward terms and the float32 observation with its sensor noise and delay. There is no matrix
product (no BLAS) anywhere: every sum is written out in a fixed order, so the bits do not depend on the BLAS
build or kernel, and the same source run as plain Python (`NUMBA_DISABLE_JIT=1`) gives the same bits (tested).

Users: the single env (`mobman_env.env.WheeledPumaEnv`) is N = 1 of these kernels; the vector env
(`mobman_env.vector`) is N; the model-based controllers and eval's Jacobian metrics call `jacobians` on the
robot models they may know; physics mode reads PyBullet's joint states and base pose and computes the
end-effector from them with `physics_observe` (the same chain). `mobman_env.kinematics` is the small Python face
of these kernels for one robot.

## Arrays (row i: robot i; m = n + 2 actuators)

Every column is named in one place, the layouts below (`# --- layouts`), by the names a reader already knows:
the env's `actuator_tau` is `prm[i, PRM.actuator_tau]` in the kernels and `RobotBatch.named("prm")["actuator_tau"]`
in Python; `info["tracking_error"]` is `io[i, IO.tracking_error]`; the step count is `st[i, S.steps]`.

| array | shape | dtype | layout | holds |
|---|---|---|---|---|
| `arm` | (N, 8, m) | float64 | `ARM` (rows) | per-joint constants: DH a, d, cos alpha, sin alpha, theta offset, joint limits (first n), action scale (m) |
| `prm` | (N, P_LEN) | float64 | `PRM` | per-robot scalars (geometry, the episode's conditions, reward weights, error bound, convention, episode steps) and the path's coefficients |
| `st` | (N, s_len(m)) | float64 | `state_columns(m)` | state: joint and wheel angles, realised speeds, base pose (x, y, yaw), step count, clip and limit counters, roll, pitch |
| `io` | (N, io_len(m)) | float64 | `io_columns(m)` | per call: actions in, standard-normal noise in, PyBullet readings in (physics), results out |
| `obs` | (N, 18 + 2m) | float32 | `sensor_columns(m)`, then the target | the observation, `mobman_env.env.OBS_KEYS` order |
| `hist` | (N, D + 1, 11 + 2m) | float32 | `sensor_columns(m)` | the delay lines of the sensor readings |

Robot lengths that wear (`prm`'s tool, r, b, mount and `arm`'s a and d) are those of the episode's robot at
t = 0; the robot of time t has them times 1 + wear t (`RobotParams.scaled`'s products), and the shoulder
height stays.

## The step (kinematic mode), per robot
1. the action is clipped to [-1, 1] and scaled to rad/s (u_c);
2. an arm joint at a limit whose command pushes further gets 0 (a limit hit);
3. actuator lag tau: the realised speed u follows u_c, u(t_k+1) = u_c + (u(t_k) - u_c) e^{-dt/tau}, and the
   angle moves by the exact integral of u over the step; tau = 0: u = u_c;
4. an arm joint that crosses its limit inside the step stops there (angle clamped, realised speed 0, a hit);
5. the platform moves along the no-slip unicycle's exact arc for the wheels' mean speeds over the step, with the
   robot of time t_k; the heading moves by r / (2 b) times the wheel angles' difference, exactly;
6. t_k+1 = (k + 1) dt; the robot of t_k+1 gives the end-effector r_a, its velocity J u, p_c and its velocity;
7. the target r_d(t), the error ||r_d - r_a||, the reward terms, the observation (noise, float32, clipped into
   the bounds, delayed).

May import: numpy, numba (through `mobman_env.numba_cache`), the standard library.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from mobman_env.numba_cache import njit


# --- layouts: the one place where the packed arrays' columns are named ----------------------------------------
# Each array's layout is a NamedTuple of offsets whose field names are the names a reader knows (the env's
# arguments, `RobotParams`' fields, `info` and observation keys): the kernels index `prm[i, PRM.actuator_tau]`,
# `st[i, S.steps]`, `io[i, IO.tracking_error]`; Python reads the same columns through record views
# (`record_view`, `RobotBatch.named`). A field's width is the distance to the next field's offset (the last
# field's: to the array's width), so a layout has no gap and no overlap by construction (tests/test_named_state.py
# checks it against the documented widths).
class ArmRows(NamedTuple):
    """The rows of `arm` (N, 8, m), each m wide (the joint rows: the first n entries)."""

    dh_a: int  # DH a, m (a length that wears)
    dh_d: int  # DH d, m (wears)
    cos_alpha: int  # cos of the DH twist
    sin_alpha: int  # sin of the DH twist
    theta_offset: int  # rad, added to the joint angle
    joint_lower: int  # rad
    joint_upper: int  # rad
    action_scale: int  # rad/s per unit of action: the speed limits (all m)


ARM = ArmRows(*range(8))
ARM_ROWS = len(ARM)

#: the path's coefficients (`prm`'s `path` block): start (3), duration T, linear term (3), number of terms K, then
#: per term (k, S x3, C x3)
PATH_HEAD = 8
PATH_TERM = 7
#: at most this many sinusoid terms per path (a random path's `n_terms` is at most 20)
MAX_PATH_TERMS = 20
PATH_LEN = PATH_HEAD + PATH_TERM * MAX_PATH_TERMS


class PrmColumns(NamedTuple):
    """The columns of `prm` (N, P_LEN): a robot's geometry (`RobotParams`' names), the episode's conditions (the
    env's argument names) and task."""

    tool: int  # m (wears)
    wheel_radius: int  # m (wears)
    half_track: int  # m (wears)
    mount_offset: int  # m (wears)
    base_height: int  # m, the shoulder's height (stays)
    wear_rate: int  # 1/s
    actuator_tau: int  # s, the lag's time constant (0: none)
    w_tracking: int  # reward weight of the tracking term
    w_effort: int  # reward weight of the effort term
    error_bound: int  # m (inf: never terminate on the error)
    modified: int  # 1.0: modified DH convention, 0.0: standard
    obs_delay: int  # control steps
    n_steps: int  # the episode's steps (truncation)
    obs_noise: int  # m, std on ee_pos and arm_base_pos
    obs_noise_vel: int  # m/s, std on ee_vel and arm_base_vel
    obs_noise_joint_vel: int  # rad/s, std on joint_vel
    obs_noise_yaw: int  # rad, std on base_yaw
    noisy: int  # 1.0 when any std is > 0 (the row has a noise plan)
    spare: int  # 2 unused columns (the path stayed at column 20)
    path: int  # PATH_LEN: the path's coefficients (`path_eval`)


PRM = PrmColumns._make([*range(18), 18, 20])  # 1 wide each, then spare (2) and path (PATH_LEN)
P_LEN = PRM.path + PATH_LEN
# short names of the geometry columns that `policies.laws.calib_qp` writes its estimates into
A_A, A_D = ARM.dh_a, ARM.dh_d
P_TOOL, P_R, P_B, P_MNT, P_H = PRM.tool, PRM.wheel_radius, PRM.half_track, PRM.mount_offset, PRM.base_height


class SensorColumns(NamedTuple):
    """The sensor readings' entries (`mobman_env.sensors.SENSOR_KEYS` order) in the observation, the noise draws
    (`IoColumns.noise`) and the noise-free readings (`IoColumns.readings`)."""

    ee_pos: int  # 3, m
    ee_vel: int  # 3, m/s
    arm_base_pos: int  # 2, m
    arm_base_vel: int  # 2, m/s
    base_yaw: int  # 1, rad
    joint_pos: int  # m, rad
    joint_vel: int  # m, rad/s


def sensor_columns(m: int) -> SensorColumns:
    return SensorColumns(0, 3, 6, 8, 10, 11, 11 + m)


def n_sensor(m: int) -> int:
    """Entries of the sensor readings of a robot with m actuators: ee_pos 3, ee_vel 3, arm_base_pos 2,
    arm_base_vel 2, base_yaw 1, joint_pos m, joint_vel m."""
    return 11 + 2 * m


def obs_size(m: int) -> int:
    """Entries of the flat observation: the readings, target_pos 3, target_vel 3, time 1."""
    return n_sensor(m) + 7


class StateColumns(NamedTuple):
    """The columns of `st` (N, s_len(m)): a robot's state."""

    q: int  # m: the n joint angles and the two wheel angles, rad
    u: int  # m: the realised speeds, rad/s
    x: int  # m, of P_0
    y: int  # m, of P_0
    yaw: int  # rad, continuous
    steps: int  # control steps since the reset
    n_clipped: int  # steps with a clipped action, this episode
    joint_limit_hits: int  # limit hits, this episode
    roll: int  # rad (physics)
    pitch: int  # rad (physics)


def state_columns(m: int) -> StateColumns:
    p = 2 * m
    return StateColumns(0, m, p, p + 1, p + 2, p + 3, p + 4, p + 5, p + 6, p + 7)


def s_len(m: int) -> int:
    """Columns of `st`: q (m), u (m), x, y, yaw, steps, n_clipped, limit hits, roll, pitch."""
    return 2 * m + 8


class IoColumns(NamedTuple):
    """The columns of `io` (N, io_len(m)): a call's inputs (the actions, the noise's standard normals, PyBullet's
    readings in physics mode) and results (a step's numbers under their `info` names, the motors' speeds, the
    noise-free readings)."""

    action: int  # m, in [-1, 1] (clipped by the kernel)
    noise: int  # n_sensor(m) standard normals, `SensorColumns` order
    phys_q: int  # m, PyBullet's joint and wheel angles, rad
    phys_q_dot: int  # m, their speeds, rad/s
    phys_pos: int  # 3, the base's position, m
    phys_quat: int  # 4, its orientation (x, y, z, w)
    phys_lin_vel: int  # 3, m/s
    phys_ang_vel: int  # 3, rad/s
    reward: int  # tracking + effort
    tracking: int  # the reward's tracking term
    effort: int  # the reward's effort term
    tracking_error: int  # m
    ee_pos_true: int  # 3, m
    action_clipped: int  # 1.0 when the action was clipped
    terminated: int  # 1.0 / 0.0
    truncated: int  # 1.0 / 0.0
    n_clipped: int  # the episode's count so far
    joint_limit_hits: int  # the episode's count so far
    tipped_over: int  # 1.0 / 0.0 (physics)
    action_norm2: int  # |a|^2 of the clipped action (physics: from `command_physics` to `physics`)
    step_limit_hits: int  # limit hits of `command_physics` (physics)
    motor_speed: int  # m, the speeds the motors are given (after the limit rule; with a lag the step's mean), rad/s
    readings: int  # n_sensor(m), the last noise-free readings (`SensorColumns` order)


def io_columns(m: int) -> IoColumns:
    ns = 11 + 2 * m
    ph = m + ns
    out = ph + 2 * m + 13
    return IoColumns(
        0, m, ph, ph + m, ph + 2 * m, ph + 2 * m + 3, ph + 2 * m + 7, ph + 2 * m + 10,
        out, out + 1, out + 2, out + 3, out + 4, out + 7, out + 8, out + 9, out + 10, out + 11, out + 12, out + 13,
        out + 14, out + 15, out + 15 + m,
    )  # fmt: skip


def io_len(m: int) -> int:
    return 8 * m + 50


# the first columns of `io`'s blocks, by their old names (tests and `sim` name them so)
def io_noise(m: int) -> int:
    """First `io` column of the standard normals of the noise (one per reading entry, `n_sensor(m)`)."""
    return io_columns(m).noise


def io_phys(m: int) -> int:
    """First `io` column of the PyBullet readings (after the noise's 11 + 2m): q (m), q_dot (m), base position
    (3), quaternion (x, y, z, w), base linear (3) and angular (3) velocity."""
    return io_columns(m).phys_q


def io_out(m: int) -> int:
    """First `io` column of the results, after the PyBullet readings' 2m + 13."""
    return io_columns(m).reward


def io_vals(m: int) -> int:
    """First `io` column of the last noise-free readings (`n_sensor(m)`, `SENSOR_KEYS` order)."""
    return io_columns(m).readings


#: the motors' speeds relative to the first result column (`io_vals(m) == io_out(m) + O_U + m`)
O_U = 15


def record_dtype(columns: Any, width: int) -> np.dtype:
    """A record dtype of float64 fields named and placed as `columns` (a layout NamedTuple, offsets ascending)
    in rows of `width` floats: a field one wide is a scalar, a wider one a sub-array."""
    offsets = [*columns, width]
    fields = []
    for k, name in enumerate(columns._fields):
        n = offsets[k + 1] - offsets[k]
        fields.append((name, np.float64) if n == 1 else (name, np.float64, (n,)))
    return np.dtype(fields)


def record_view(a: np.ndarray, columns: Any) -> np.ndarray:
    """The float64 array a (N, width), C-contiguous, as N records of `record_dtype(columns, width)`: the same
    memory, so `view["actuator_tau"]` reads and writes `a[:, PRM.actuator_tau]`."""
    return a.view(record_dtype(columns, a.shape[1]))[:, 0]


#: observation bounds by sensor block (m, m/s, rad, rad/s, s): wide enough for any physics overshoot
BIG_POS, BIG_VEL, BIG_ANGLE, BIG_JOINT_VEL, BIG_TIME = 1000.0, 100.0, 1e5, 1e3, 1e5
TIP_ANGLE = math.radians(30.0)  # rad, roll or pitch beyond which the platform counts as tipped over

_sensor_columns = njit(cache=True, inline="always")(sensor_columns)
_n_sensor = njit(cache=True, inline="always")(n_sensor)
_state_columns = njit(cache=True, inline="always")(state_columns)
_io_columns = njit(cache=True, inline="always")(io_columns)


# --- packing robots into rows (Python) -------------------------------------------------------------------------
def pack_arm(arm: np.ndarray, prm: np.ndarray, i: int, desc) -> None:
    """Write an arm (a `mobman_env.robots.ArmDescription`) into row i of `arm` and `prm`: its DH table, offsets,
    limits, speed limits (the first n action scales), tool and convention."""
    n = desc.n_joints
    a, d, ca, sa = desc.dh_constants
    row = arm[i]
    row[ARM.dh_a, :n] = a
    row[ARM.dh_d, :n] = d
    row[ARM.cos_alpha, :n] = ca
    row[ARM.sin_alpha, :n] = sa
    row[ARM.theta_offset, :n] = desc.theta_offset
    row[ARM.joint_lower, :n] = desc.joint_lower
    row[ARM.joint_upper, :n] = desc.joint_upper
    row[ARM.action_scale, :n] = desc.speed_limit
    prm[i, PRM.tool] = desc.tool
    prm[i, PRM.mount_offset] = desc.mount_offset
    prm[i, PRM.base_height] = desc.base_height
    prm[i, PRM.modified] = 1.0 if desc.modified else 0.0


def pack_robot(arm: np.ndarray, prm: np.ndarray, i: int, params) -> None:
    """Write a robot (a `mobman_env.params.RobotParams`: the arm on the platform) into row i of `arm` and `prm`
    (its geometry and limits; an episode's conditions and path are set apart)."""
    pack_arm(arm, prm, i, params.arm)
    arm[i, ARM.action_scale] = params.action_scale
    prm[i, PRM.wheel_radius] = params.wheel_radius
    prm[i, PRM.half_track] = params.half_track


def packed(robots) -> tuple[np.ndarray, np.ndarray]:
    """The (`arm`, `prm`) rows of these robots (`RobotParams`, all with the same number of joints), e.g. for
    `jacobians` on robot models."""
    m = robots[0].n_actuators
    arm = np.zeros((len(robots), ARM_ROWS, m))
    prm = np.zeros((len(robots), P_LEN))
    for i, p in enumerate(robots):
        if p.n_actuators != m:
            raise ValueError(
                f"robot {i} ({p.arm.name}) has {p.n_actuators} actuators, robot 0 has {m}: pack them apart"
            )
        pack_robot(arm, prm, i, p)
    return arm, prm


# --- the arm --------------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _chain(arm, i, n, modified, fac, tool, q, p, jac, axes):
    """The end-effector point of robot i's arm in its frame 0 into p (3) and d p / d q into jac[:, :n].

    q: the n joint angles; fac: the wear factor of the lengths (a, d, tool). The frame is carried as its axes x,
    y, z and origin o, component by component; `axes` (n, 6) receives each joint's axis and a point on it (frame
    i-1's z and origin in the standard convention, frame i's in the modified one); column k of the Jacobian is
    z_k x (p - o_k)."""
    xx, xy, xz = 1.0, 0.0, 0.0
    yx, yy, yz = 0.0, 1.0, 0.0
    zx, zy, zz = 0.0, 0.0, 1.0
    px, py, pz = 0.0, 0.0, 0.0
    for k in range(n):
        th = q[k] + arm[i, ARM.theta_offset, k]
        c, s = math.cos(th), math.sin(th)
        ca, sa = arm[i, ARM.cos_alpha, k], arm[i, ARM.sin_alpha, k]
        a, d = arm[i, ARM.dh_a, k] * fac, arm[i, ARM.dh_d, k] * fac
        if modified:
            # Rx(alpha) Tx(a): the origin moves along x, then y and z turn about x
            px, py, pz = px + a * xx, py + a * xy, pz + a * xz
            yx, yy, yz, zx, zy, zz = (
                ca * yx + sa * zx,
                ca * yy + sa * zy,
                ca * yz + sa * zz,
                ca * zx - sa * yx,
                ca * zy - sa * yy,
                ca * zz - sa * yz,
            )
            axes[k, 0], axes[k, 1], axes[k, 2], axes[k, 3], axes[k, 4], axes[k, 5] = zx, zy, zz, px, py, pz
            # Rz(theta) Tz(d): x and y turn about z, the origin moves along z
            xx, xy, xz, yx, yy, yz = (
                c * xx + s * yx,
                c * xy + s * yy,
                c * xz + s * yz,
                c * yx - s * xx,
                c * yy - s * xy,
                c * yz - s * xz,
            )
            px, py, pz = px + d * zx, py + d * zy, pz + d * zz
        else:
            axes[k, 0], axes[k, 1], axes[k, 2], axes[k, 3], axes[k, 4], axes[k, 5] = zx, zy, zz, px, py, pz
            # Rz(theta): u = the new x, w = the new y (before the twist)
            ux, uy, uz = c * xx + s * yx, c * xy + s * yy, c * xz + s * yz
            wx, wy, wz = c * yx - s * xx, c * yy - s * xy, c * yz - s * xz
            # Tz(d) Tx(a): the origin moves along the old z and the new x
            px, py, pz = px + d * zx + a * ux, py + d * zy + a * uy, pz + d * zz + a * uz
            # Rx(alpha): y and z turn about the new x
            xx, xy, xz = ux, uy, uz
            yx, yy, yz, zx, zy, zz = (
                ca * wx + sa * zx,
                ca * wy + sa * zy,
                ca * wz + sa * zz,
                ca * zx - sa * wx,
                ca * zy - sa * wy,
                ca * zz - sa * wz,
            )
    t = tool * fac
    rx, ry, rz = px + t * zx, py + t * zy, pz + t * zz
    p[0], p[1], p[2] = rx, ry, rz
    for k in range(n):
        ax, ay, az = axes[k, 0], axes[k, 1], axes[k, 2]
        vx, vy, vz = rx - axes[k, 3], ry - axes[k, 4], rz - axes[k, 5]
        jac[0, k] = ay * vz - az * vy
        jac[1, k] = az * vx - ax * vz
        jac[2, k] = ax * vy - ay * vx


@njit(cache=True, inline="always")
def _wheel_map(r, b, mnt, c, s, jpc):
    """d p_c_dot / d (w_l, w_r) into jpc (2, 2) at heading (cos, sin) = (c, s): phi_dot = r / (2 b) (w_r - w_l),
    v = r / 2 (w_l + w_r); p_c moves with v along the heading and turns about P_0 with phi_dot."""
    dv = 0.5 * r
    for w in range(2):
        dphi = -0.5 * r / b if w == 0 else 0.5 * r / b
        jpc[0, w] = c * dv - mnt * s * dphi
        jpc[1, w] = s * dv + mnt * c * dphi


@njit(cache=True, inline="always")
def _whole_body(arm, prm, i, n, fac, q, x, y, yaw, ee, pc, jac, jpc, axes, f, full=True):
    """Robot i (lengths times `fac`) at arm angles q and platform pose (x, y, yaw) of P_0: the end-effector r_a
    into ee (3), p_c into pc (2), the whole-body Jacobian (d r_a / d u, platform translation included; with
    full=False the paper's J, whose wheel columns act only through the yaw) into jac (3, m) and d p_c / d u's
    wheel columns into jpc (2, 2). f (3) is scratch."""
    _chain(arm, i, n, prm[i, PRM.modified] != 0.0, fac, prm[i, PRM.tool], q, f, jac, axes)
    c, s = math.cos(yaw), math.sin(yaw)
    r, b, mnt = prm[i, PRM.wheel_radius] * fac, prm[i, PRM.half_track] * fac, prm[i, PRM.mount_offset] * fac
    # g = R(yaw) f and the arm columns R(yaw) df/dq
    g0, g1, g2 = c * f[0] - s * f[1], s * f[0] + c * f[1], f[2]
    for k in range(n):
        j0, j1 = jac[0, k], jac[1, k]
        jac[0, k] = c * j0 - s * j1
        jac[1, k] = s * j0 + c * j1
    pc[0], pc[1] = x + mnt * c, y + mnt * s
    ee[0], ee[1], ee[2] = pc[0] + g0, pc[1] + g1, prm[i, PRM.base_height] + g2
    # r_a turns about p_c with phi_dot and moves with p_c
    _wheel_map(r, b, mnt, c, s, jpc)
    for w in range(2):
        dphi = -0.5 * r / b if w == 0 else 0.5 * r / b
        if full:
            jac[0, n + w] = jpc[0, w] - g1 * dphi
            jac[1, n + w] = jpc[1, w] + g0 * dphi
        else:
            jac[0, n + w] = -g1 * dphi
            jac[1, n + w] = g0 * dphi
        jac[2, n + w] = 0.0


@njit(cache=True)
def model(arm, prm, rows, q, pose, full, ee, pc, jac):
    """The robot models `rows` (rows of `arm`, `prm`; lengths as packed, no wear factor) at arm angles q
    (k, >= n) and platform poses (k, 3): r_a into ee (k, 3), p_c into pc (k, 2) and the whole-body Jacobian (full)
    or the paper's J of eq. (6) (r_a_dot = [p_c_dot; 0] + J u: the wheel columns act only through the yaw) into
    jac (k, 3, m)."""
    m = jac.shape[2]
    n = m - 2
    axes = np.empty((n, 6))
    f = np.empty(3)
    jpc = np.empty((2, 2))
    for r in range(rows.shape[0]):
        _whole_body(
            arm,
            prm,
            rows[r],
            n,
            1.0,
            q[r],
            pose[r, 0],
            pose[r, 1],
            pose[r, 2],
            ee[r],
            pc[r],
            jac[r],
            jpc,
            axes,
            f,
            full,
        )


def jacobians(arm, prm, rows, q, yaw, full, out):
    """The Jacobians of the robot models `rows` at arm angles q (k, >= n) and headings yaw (k,) into out
    (k, 3, m): `model`'s, at P_0 = 0 (the Jacobians do not depend on where the platform is)."""
    k = len(rows)
    pose = np.zeros((k, 3))
    pose[:, 2] = yaw
    model(arm, prm, rows, q, pose, full, np.empty((k, 3)), np.empty((k, 2)), out)


def ee_points(arm, prm, q, pose, ee, pc):
    """r_a (N, 3) and p_c (N, 2) of N robot models at arm angles q (N, >= n) and platform poses (N, 3)."""
    n = len(q)
    model(arm, prm, np.arange(n), q, pose, True, ee, pc, np.empty((n, 3, arm.shape[2])))


@njit(cache=True)
def arm_base_jacobians(arm, prm, yaw, out):
    """d p_c_dot / d u of N robot models at headings yaw (N,) into out (N, 2, m) (only the wheel columns are
    written: the arm's are zero)."""
    nrow, m = out.shape[0], out.shape[2]
    jpc = np.empty((2, 2))
    for i in range(nrow):
        _wheel_map(
            prm[i, PRM.wheel_radius], prm[i, PRM.half_track], prm[i, PRM.mount_offset], math.cos(yaw[i]),
            math.sin(yaw[i]), jpc,
        )  # fmt: skip
        for a in range(2):
            out[i, a, m - 2] = jpc[a, 0]
            out[i, a, m - 1] = jpc[a, 1]


@njit(cache=True)
def arm_points(arm, prm, q, points, jac):
    """The end-effector points of N arms in their frame 0 (N, 3) and d p / d q (N, 3, n) at angles q (N, >= n)."""
    nrow, n = jac.shape[0], jac.shape[2]
    axes = np.empty((n, 6))
    for i in range(nrow):
        _chain(arm, i, n, prm[i, PRM.modified] != 0.0, 1.0, prm[i, PRM.tool], q[i], points[i], jac[i], axes)


@njit(cache=True, inline="always")
def arc(x, y, yaw, ds, dphi):
    """The no-slip unicycle's pose after moving P_0 by the arc length ds while turning by dphi (constant
    curvature): (x, y, yaw + dphi). The chord is ds sinc(dphi / 2) long along the mid heading yaw + dphi / 2, which
    is exact and has no cancellation for small turns (the series 1 - h^2 / 6 below |h| = 1e-4, exact there to
    float precision)."""
    h = 0.5 * dphi
    f = 1.0 - h * h / 6.0 if abs(h) < 1e-4 else math.sin(h) / h
    mid = yaw + h
    chord = ds * f
    return x + chord * math.cos(mid), y + chord * math.sin(mid), yaw + dphi


# --- paths ----------------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def path_eval(c, t, out):
    """r_d(t), r_d_dot(t), r_d_ddot(t) of the path with coefficients c (`PATH_LEN`, see `mobman_env.paths`) into
    out (3, 3): per axis a, start_a + lin_a ph + sum_j (S_ja (sin(k_j ph)) + C_ja (cos(k_j ph) - 1)), ph = 2 pi s(t),
    with the rest-to-rest timing s(t) = sin^2(0.5 pi t / T) held at the ends. One sine and one cosine per term,
    shared by the three axes."""
    T = c[3]
    tt = min(max(t, 0.0), T)
    w = math.pi / T
    cw, sw = math.cos(w * tt), math.sin(w * tt)
    two_pi = 2.0 * math.pi
    ph = two_pi * (0.5 * (1.0 - cw))
    phd = two_pi * (0.5 * w * sw)
    phdd = two_pi * (0.5 * w * w * cw)
    p0, p1, p2 = c[4] * ph, c[5] * ph, c[6] * ph
    d0, d1, d2 = c[4], c[5], c[6]
    a0, a1, a2 = 0.0, 0.0, 0.0
    for j in range(int(c[7])):
        base = PATH_HEAD + PATH_TERM * j
        k = c[base]
        sk, ck = math.sin(k * ph), math.cos(k * ph)
        cm = ck - 1.0
        s0, s1, s2, c0, c1, c2 = c[base + 1], c[base + 2], c[base + 3], c[base + 4], c[base + 5], c[base + 6]
        p0 += s0 * sk + c0 * cm
        p1 += s1 * sk + c1 * cm
        p2 += s2 * sk + c2 * cm
        d0 += k * (s0 * ck - c0 * sk)
        d1 += k * (s1 * ck - c1 * sk)
        d2 += k * (s2 * ck - c2 * sk)
        kk = k * k
        a0 -= kk * (s0 * sk + c0 * ck)
        a1 -= kk * (s1 * sk + c1 * ck)
        a2 -= kk * (s2 * sk + c2 * ck)
    out[0, 0], out[0, 1], out[0, 2] = c[0] + p0, c[1] + p1, c[2] + p2
    out[1, 0], out[1, 1], out[1, 2] = d0 * phd, d1 * phd, d2 * phd
    out[2, 0] = a0 * phd * phd + d0 * phdd
    out[2, 1] = a1 * phd * phd + d1 * phdd
    out[2, 2] = a2 * phd * phd + d2 * phdd


# --- the observation --------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _clip32(v, lim):
    """v as float32, clipped into [-lim, lim] (the observation space's bounds)."""
    x = np.float32(v)
    hi = np.float32(lim)
    if x > hi:
        return hi
    if x < -hi:
        return -hi
    return x


@njit(cache=True, inline="always")
def _finish(prm, st, io, obs, hist, i, m, t, vals, ee, a2, step, pv):
    """The rest of a step (or a reset) of robot i from its noise-free readings `vals` (`n_sensor(m)`, float64,
    `SensorColumns` order; the noise is added to them in place), its true end-effector ee and the squared norm a2
    of its clipped action: the target, the error, the reward terms, the observation (noise, float32, clipped into
    the bounds, the delay) and the outputs. pv (3, 3) is scratch."""
    ns = _n_sensor(m)
    IO = _io_columns(m)
    R = _sensor_columns(m)
    for j in range(ns):
        io[i, IO.readings + j] = vals[j]
    path_eval(prm[i, PRM.path :], t, pv)
    rd0, rd1, rd2, vd0, vd1, vd2 = pv[0, 0], pv[0, 1], pv[0, 2], pv[1, 0], pv[1, 1], pv[1, 2]
    e0, e1, e2 = rd0 - ee[0], rd1 - ee[1], rd2 - ee[2]
    err = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    track = -prm[i, PRM.w_tracking] * err
    effort = -prm[i, PRM.w_effort] * a2
    io[i, IO.reward] = track + effort
    io[i, IO.tracking] = track
    io[i, IO.effort] = effort
    io[i, IO.tracking_error] = err
    io[i, IO.ee_pos_true], io[i, IO.ee_pos_true + 1], io[i, IO.ee_pos_true + 2] = ee[0], ee[1], ee[2]
    io[i, IO.terminated] = 1.0 if err > prm[i, PRM.error_bound] else 0.0
    io[i, IO.truncated] = 1.0 if st[i, _state_columns(m).steps] >= prm[i, PRM.n_steps] else 0.0
    # the readings with their noise (standard normals drawn by the caller, scaled here), float32, clipped into the
    # bounds block by block: ee_pos, ee_vel, arm_base_pos, arm_base_vel, base_yaw, joint_pos, joint_vel
    if prm[i, PRM.noisy] != 0.0:  # the scaled standard normals, added to a copy of the readings
        spos, svel = prm[i, PRM.obs_noise], prm[i, PRM.obs_noise_vel]
        syaw, sjv = prm[i, PRM.obs_noise_yaw], prm[i, PRM.obs_noise_joint_vel]
        for j in range(ns):
            if j < R.ee_vel or R.arm_base_pos <= j < R.arm_base_vel:
                std = spos
            elif j < R.base_yaw:
                std = svel
            elif j == R.base_yaw:
                std = syaw
            elif j < R.joint_vel:
                std = 0.0
            else:
                std = sjv
            if std > 0.0:
                vals[j] = vals[j] + std * io[i, IO.noise + j]
    _observe(prm, st, obs, hist, i, m, t, vals, rd0, rd1, rd2, vd0, vd1, vd2, step)


@njit(cache=True, inline="always")
def _observe(prm, st, obs, hist, i, m, t, vals, rd0, rd1, rd2, vd0, vd1, vd2, step):
    """Robot i's observation from its (noisy) readings vals and the target: float32, clipped into the bounds,
    through the delay line."""
    ns = _n_sensor(m)
    R = _sensor_columns(m)
    for j in range(3):
        obs[i, R.ee_pos + j] = _clip32(vals[R.ee_pos + j], BIG_POS)
        obs[i, R.ee_vel + j] = _clip32(vals[R.ee_vel + j], BIG_VEL)
    for j in range(2):
        obs[i, R.arm_base_pos + j] = _clip32(vals[R.arm_base_pos + j], BIG_POS)
        obs[i, R.arm_base_vel + j] = _clip32(vals[R.arm_base_vel + j], BIG_VEL)
    for j in range(R.base_yaw, R.joint_vel):  # base_yaw and joint_pos
        obs[i, j] = _clip32(vals[j], BIG_ANGLE)
    for j in range(R.joint_vel, ns):
        obs[i, j] = _clip32(vals[j], BIG_JOINT_VEL)
    # the task's reference after the readings: target_pos, target_vel, time
    obs[i, ns] = _clip32(rd0, BIG_POS)
    obs[i, ns + 1] = _clip32(rd1, BIG_POS)
    obs[i, ns + 2] = _clip32(rd2, BIG_POS)
    obs[i, ns + 3] = _clip32(vd0, BIG_VEL)
    obs[i, ns + 4] = _clip32(vd1, BIG_VEL)
    obs[i, ns + 5] = _clip32(vd2, BIG_VEL)
    x = np.float32(t)
    obs[i, ns + 6] = min(max(x, np.float32(0.0)), np.float32(BIG_TIME))
    # the delay: at a reset fill the line with this reading; after step k hand out the one of k - D and keep this
    delay = int(prm[i, PRM.obs_delay])
    if delay > 0:
        if not step:
            for s in range(delay + 1):
                for j in range(ns):
                    hist[i, s, j] = obs[i, j]
        else:
            k = int(st[i, _state_columns(m).steps])
            put, get = (k - 1) % (delay + 1), k % (delay + 1)
            for j in range(ns):
                now = obs[i, j]
                obs[i, j] = hist[i, get, j]
                hist[i, put, j] = now


# --- the step ---------------------------------------------------------------------------------------------------
@njit(cache=True, inline="always")
def _check_actions(io, rows, m):
    """The first row of `rows` whose action holds NaN or inf (checked before any robot moves), or -1."""
    for r in range(rows.shape[0]):
        i = rows[r]
        for j in range(m):
            if not math.isfinite(io[i, j]):
                return i
    return -1


@njit(cache=True, inline="always")
def _clip_action(io, i, j, clipped):
    """Action entry j of robot i clipped to [-1, 1]; flags the row's `action_clipped` (column `clipped`) when it
    was outside."""
    x = io[i, j]
    if x > 1.0:
        io[i, clipped] = 1.0
        return 1.0
    if x < -1.0:
        io[i, clipped] = 1.0
        return -1.0
    return x


@njit(cache=True, inline="always")
def _actuate(arm, prm, st, io, i, m, dt, dq):
    """Clip robot i's action, scale it, apply the joint-limit rule and the lag (see the module docstring): the
    realised speeds at the end of the step go to st's u, each actuator's angle change over the step into dq (m),
    the speeds to give the motors (physics: the mean over the step) into io's `motor_speed`; returns (|a|^2 of
    the clipped action, limit hits so far this step)."""
    n = m - 2
    IO = _io_columns(m)
    su = _state_columns(m).u
    io[i, IO.action_clipped] = 0.0
    tau = prm[i, PRM.actuator_tau]
    decay, rise = 1.0, 0.0
    if tau > 0.0:
        decay = math.exp(-dt / tau)
        rise = -tau * math.expm1(-dt / tau)  # tau (1 - e^{-dt/tau}): the integral of e^{-s/tau} over the step
    a2 = 0.0
    hits = 0
    for j in range(m):
        x = _clip_action(io, i, IO.action + j, IO.action_clipped)
        a2 += x * x
        uc = x * arm[i, ARM.action_scale, j]
        if j < n:
            q = st[i, j]
            if (uc > 0.0 and q >= arm[i, ARM.joint_upper, j]) or (uc < 0.0 and q <= arm[i, ARM.joint_lower, j]):
                uc = 0.0
                hits += 1
        if tau > 0.0:
            u0 = st[i, su + j]
            st[i, su + j] = uc + (u0 - uc) * decay
            dq[j] = uc * dt + (u0 - uc) * rise
            io[i, IO.motor_speed + j] = uc + (u0 - uc) * (rise / dt)
        else:
            st[i, su + j] = uc
            dq[j] = uc * dt
            io[i, IO.motor_speed + j] = uc
    return a2, hits


@njit(cache=True, inline="always")
def _count(st, io, i, m, hits):
    """Add this step's clip and limit-hit counts to robot i's counters and report them in its outputs."""
    IO = _io_columns(m)
    S = _state_columns(m)
    st[i, S.n_clipped] += io[i, IO.action_clipped]
    st[i, S.joint_limit_hits] += hits
    io[i, IO.n_clipped] = st[i, S.n_clipped]
    io[i, IO.joint_limit_hits] = st[i, S.joint_limit_hits]


@njit(cache=True, inline="always")
def _read_kinematic(arm, prm, st, io, obs, hist, i, m, dt, a2, step, scratch):
    """Robot i's readings from its state (the robot of its current time), then `_finish`."""
    axes, f, ee, pc, jac, jpc, vals, pv = scratch
    n = m - 2
    S = _state_columns(m)
    R = _sensor_columns(m)
    t = st[i, S.steps] * dt
    fac = 1.0 + prm[i, PRM.wear_rate] * t
    x, y, yaw = st[i, S.x], st[i, S.y], st[i, S.yaw]
    _whole_body(arm, prm, i, n, fac, st[i, S.q :], x, y, yaw, ee, pc, jac, jpc, axes, f)
    for a in range(3):
        v = 0.0
        for j in range(m):
            v += jac[a, j] * st[i, S.u + j]
        vals[R.ee_vel + a] = v
    vals[R.ee_pos], vals[R.ee_pos + 1], vals[R.ee_pos + 2] = ee[0], ee[1], ee[2]
    vals[R.arm_base_pos], vals[R.arm_base_pos + 1] = pc[0], pc[1]
    ul, ur = st[i, S.u + n], st[i, S.u + n + 1]
    vals[R.arm_base_vel] = jpc[0, 0] * ul + jpc[0, 1] * ur
    vals[R.arm_base_vel + 1] = jpc[1, 0] * ul + jpc[1, 1] * ur
    vals[R.base_yaw] = yaw
    for j in range(m):
        vals[R.joint_pos + j] = st[i, S.q + j]
        vals[R.joint_vel + j] = st[i, S.u + j]
    _finish(prm, st, io, obs, hist, i, m, t, vals, ee, a2, step, pv)


@njit(cache=True)
def _scratch(m):
    """Per-call scratch arrays of the kernels (never per robot)."""
    n = m - 2
    return (
        np.empty((n, 6)),
        np.empty(3),
        np.empty(3),
        np.empty(2),
        np.empty((3, m)),
        np.empty((2, 2)),
        np.empty(_n_sensor(m)),
        np.empty((3, 3)),
    )


#: the modes of the kernels `kinematic` and `physics`
READ, OBSERVE, STEP = 0, 1, 2


@njit(cache=True, inline="always")
def _move(arm, prm, st, io, i, m, dt, dq):
    """Steps 1-5 of the module docstring for robot i: the actuators, the joint limits inside the step and the
    platform's arc (the robot of t_k); the step count advances. Returns (|a|^2 of the clipped action, limit
    hits)."""
    n = m - 2
    S = _state_columns(m)
    a2, hits = _actuate(arm, prm, st, io, i, m, dt, dq)
    for j in range(m):
        q = st[i, S.q + j] + dq[j]
        if j < n:
            lo, hi = arm[i, ARM.joint_lower, j], arm[i, ARM.joint_upper, j]
            if q > hi or q < lo:  # the joint reached its limit inside the step: it stops there
                q = min(max(q, lo), hi)
                st[i, S.u + j] = 0.0
                hits += 1
        st[i, S.q + j] = q
    # the platform: the exact arc of the unicycle for the wheels' angle changes, the robot of t_k
    fac = 1.0 + prm[i, PRM.wear_rate] * (st[i, S.steps] * dt)
    r_w, b_w = prm[i, PRM.wheel_radius] * fac, prm[i, PRM.half_track] * fac
    dl, dr = dq[n], dq[n + 1]
    ds = 0.5 * r_w * (dl + dr)
    dphi = 0.5 * r_w / b_w * (dr - dl)
    st[i, S.x], st[i, S.y], st[i, S.yaw] = arc(st[i, S.x], st[i, S.y], st[i, S.yaw], ds, dphi)
    st[i, S.steps] += 1.0
    return a2, hits


@njit(cache=True)
def kinematic(arm, prm, st, io, obs, hist, dt, rows, mode):
    """Kinematic mode for the robots `rows`, by `mode`:

    * `READ`: the end-effector r_a at the current state into io's `ee_pos_true` (a reset's start point, before
      the path is set; nothing else is written);
    * `OBSERVE`: the observation at the current state without stepping (a reset: the delay line is filled with
      it, the outputs hold its error and target);
    * `STEP`: one control step (see the module docstring), then the observation.

    Returns -1, or (`STEP`) the first row whose action is not finite: then no robot has moved."""
    m = arm.shape[2]
    n = m - 2
    IO = _io_columns(m)
    S = _state_columns(m)
    if mode == STEP:
        bad = _check_actions(io, rows, m)
        if bad >= 0:
            return bad
    scratch = _scratch(m)
    dq = np.empty(m)
    for r in range(rows.shape[0]):
        i = rows[r]
        if mode == READ:
            axes, f, ee, pc, jac, jpc, vals, pv = scratch
            fac = 1.0 + prm[i, PRM.wear_rate] * (st[i, S.steps] * dt)
            x, y, yaw = st[i, S.x], st[i, S.y], st[i, S.yaw]
            _whole_body(arm, prm, i, n, fac, st[i, S.q :], x, y, yaw, ee, pc, jac, jpc, axes, f)
            io[i, IO.ee_pos_true], io[i, IO.ee_pos_true + 1], io[i, IO.ee_pos_true + 2] = ee[0], ee[1], ee[2]
            continue
        a2, hits = 0.0, 0
        if mode == STEP:
            a2, hits = _move(arm, prm, st, io, i, m, dt, dq)
        else:
            io[i, IO.action_clipped] = 0.0
        _read_kinematic(arm, prm, st, io, obs, hist, i, m, dt, a2, mode == STEP, scratch)
        io[i, IO.tipped_over] = 0.0
        _count(st, io, i, m, hits)
    return -1


# --- physics mode: the motors' commands and the readings from PyBullet's state -------------------------------------
@njit(cache=True)
def command_physics(arm, prm, st, io, dt, rows):
    """The motor speeds of the robots `rows` (physics mode) into io's `motor_speed`: the action clipped, scaled,
    the joint-limit rule on the arm angles of the last reading, the lag (the motors get the realised speed's mean
    over the step). Returns -1, or the first row whose action is not finite: then nothing is commanded."""
    m = arm.shape[2]
    bad = _check_actions(io, rows, m)
    if bad >= 0:
        return bad
    dq = np.empty(m)
    IO = _io_columns(m)
    for r in range(rows.shape[0]):
        i = rows[r]
        a2, hits = _actuate(arm, prm, st, io, i, m, dt, dq)
        io[i, IO.action_norm2] = a2
        io[i, IO.step_limit_hits] = hits
    return -1


@njit(cache=True, inline="always")
def _read_physics(arm, prm, st, io, i, m, scratch):
    """Robot i's noise-free readings (into the scratch's `vals`) and end-effector (its `ee`) from the PyBullet
    state in io's `phys_*` columns (joint angles and speeds, base position, quaternion (x, y, z, w), linear and
    angular velocity, world frame): the end-effector and its velocity from the same chain as kinematic mode (the
    base's full rotation included), p_c and its velocity in the plane, the continuous heading (kept in st);
    returns (roll, pitch). The joint angles go to st too (the limit rule's)."""
    axes, f, ee, pc, jac, jpc, vals, pv = scratch
    n = m - 2
    IO = _io_columns(m)
    S = _state_columns(m)
    R = _sensor_columns(m)
    qx, qy, qz, qw = io[i, IO.phys_quat], io[i, IO.phys_quat + 1], io[i, IO.phys_quat + 2], io[i, IO.phys_quat + 3]
    # the base's rotation matrix and its roll, pitch, yaw (Z-Y-X Euler angles, as getEulerFromQuaternion)
    r00 = 1.0 - 2.0 * (qy * qy + qz * qz)
    r01 = 2.0 * (qx * qy - qz * qw)
    r02 = 2.0 * (qx * qz + qy * qw)
    r10 = 2.0 * (qx * qy + qz * qw)
    r11 = 1.0 - 2.0 * (qx * qx + qz * qz)
    r12 = 2.0 * (qy * qz - qx * qw)
    r20 = 2.0 * (qx * qz - qy * qw)
    r21 = 2.0 * (qy * qz + qx * qw)
    r22 = 1.0 - 2.0 * (qx * qx + qy * qy)
    roll = math.atan2(r21, r22)
    pitch = math.asin(min(max(-r20, -1.0), 1.0))
    yaw_w = math.atan2(r10, r00)
    st[i, S.roll], st[i, S.pitch] = roll, pitch
    # the continuous heading: the wrapped angle's representative nearest the last one
    yaw = st[i, S.yaw]
    yaw = yaw + ((yaw_w - yaw + math.pi) % (2.0 * math.pi) - math.pi)
    st[i, S.yaw] = yaw
    bx, by, bz = io[i, IO.phys_pos], io[i, IO.phys_pos + 1], io[i, IO.phys_pos + 2]
    st[i, S.x], st[i, S.y] = bx, by
    for j in range(m):
        st[i, S.q + j] = io[i, IO.phys_q + j]
    _chain(arm, i, n, prm[i, PRM.modified] != 0.0, 1.0, prm[i, PRM.tool], st[i, S.q :], f, jac, axes)
    # the arm's frame 0 sits at (mount, 0, h - r) in the base link (the URDF's layout)
    mnt = prm[i, PRM.mount_offset]
    vx, vy, vz = mnt + f[0], f[1], prm[i, PRM.base_height] - prm[i, PRM.wheel_radius] + f[2]
    ox = r00 * vx + r01 * vy + r02 * vz
    oy = r10 * vx + r11 * vy + r12 * vz
    oz = r20 * vx + r21 * vy + r22 * vz
    ee[0], ee[1], ee[2] = bx + ox, by + oy, bz + oz
    # velocity: the base's, its rotation about the offset, and the arm's joints (turned into the world)
    jx, jy, jz = 0.0, 0.0, 0.0
    for k in range(n):
        qd = io[i, IO.phys_q_dot + k]
        jx += jac[0, k] * qd
        jy += jac[1, k] * qd
        jz += jac[2, k] * qd
    lx, ly, lz = io[i, IO.phys_lin_vel], io[i, IO.phys_lin_vel + 1], io[i, IO.phys_lin_vel + 2]
    wx, wy, wz = io[i, IO.phys_ang_vel], io[i, IO.phys_ang_vel + 1], io[i, IO.phys_ang_vel + 2]
    vals[R.ee_pos], vals[R.ee_pos + 1], vals[R.ee_pos + 2] = ee[0], ee[1], ee[2]
    vals[R.ee_vel] = lx + (wy * oz - wz * oy) + (r00 * jx + r01 * jy + r02 * jz)
    vals[R.ee_vel + 1] = ly + (wz * ox - wx * oz) + (r10 * jx + r11 * jy + r12 * jz)
    vals[R.ee_vel + 2] = lz + (wx * oy - wy * ox) + (r20 * jx + r21 * jy + r22 * jz)
    cy, sy = math.cos(yaw), math.sin(yaw)
    vals[R.arm_base_pos], vals[R.arm_base_pos + 1] = bx + mnt * cy, by + mnt * sy
    vals[R.arm_base_vel], vals[R.arm_base_vel + 1] = lx - mnt * wz * sy, ly + mnt * wz * cy
    vals[R.base_yaw] = yaw
    for j in range(m):
        vals[R.joint_pos + j] = io[i, IO.phys_q + j]
        vals[R.joint_vel + j] = io[i, IO.phys_q_dot + j]
    return roll, pitch


@njit(cache=True)
def physics(arm, prm, st, io, obs, hist, dt, rows, mode):
    """Physics mode's readings of the robots `rows` from their PyBullet state (`_read_physics`), by `mode`:
    `READ`: the end-effector into io's `ee_pos_true` only (a reset's start point, before the path is set);
    `OBSERVE`: the observation of a reset; `STEP`: after a control step (the step count advances, the counters of
    `command_physics` are added). Then `_finish` and the tip-over check (roll or pitch beyond `TIP_ANGLE`
    terminates)."""
    m = arm.shape[2]
    scratch = _scratch(m)
    IO = _io_columns(m)
    S = _state_columns(m)
    for r in range(rows.shape[0]):
        i = rows[r]
        roll, pitch = _read_physics(arm, prm, st, io, i, m, scratch)
        ee = scratch[2]
        if mode == READ:
            io[i, IO.ee_pos_true], io[i, IO.ee_pos_true + 1], io[i, IO.ee_pos_true + 2] = ee[0], ee[1], ee[2]
            continue
        a2, hits = 0.0, 0
        if mode == STEP:
            st[i, S.steps] += 1.0
            a2, hits = io[i, IO.action_norm2], int(io[i, IO.step_limit_hits])
        else:
            io[i, IO.action_clipped] = 0.0
        _finish(prm, st, io, obs, hist, i, m, st[i, S.steps] * dt, scratch[6], ee, a2, mode == STEP, scratch[7])
        tipped = max(abs(roll), abs(pitch)) > TIP_ANGLE
        io[i, IO.tipped_over] = 1.0 if tipped else 0.0
        if tipped:
            io[i, IO.terminated] = 1.0
        _count(st, io, i, m, hits)


# --- the compile cache ---------------------------------------------------------------------------------------------
def warm() -> float:
    """Compile every kernel (or load it from numba's cache) for the argument types the package passes; returns the
    seconds it took. `python -m mobman_env` runs it: CI and a fresh install call it once, so no test process
    or command pays the first compile (numba caches the machine code next to this file, or, where that folder is
    not writable, in a user-wide cache folder; `NUMBA_CACHE_DIR` chooses another)."""
    import time

    t0 = time.perf_counter()
    m = 8
    arm = np.zeros((1, ARM_ROWS, m))
    arm[0, ARM.cos_alpha] = 1.0
    arm[0, ARM.joint_upper] = 1.0
    arm[0, ARM.joint_lower] = -1.0
    arm[0, ARM.action_scale] = 1.0
    prm = np.zeros((1, P_LEN))
    prm[0, PRM.wheel_radius] = prm[0, PRM.half_track] = 0.2
    prm[0, PRM.path + 3] = 1.0  # the path's duration
    prm[0, PRM.error_bound] = math.inf
    prm[0, PRM.n_steps] = 10.0
    st = np.zeros((1, s_len(m)))
    io = np.zeros((1, io_len(m)))
    io[0, io_columns(m).phys_quat + 3] = 1.0  # a unit quaternion
    obs = np.empty((1, obs_size(m)), dtype=np.float32)
    hist = np.zeros((1, 1, n_sensor(m)), dtype=np.float32)
    rows = np.arange(1)
    for mode in (READ, OBSERVE, STEP):
        kinematic(arm, prm, st, io, obs, hist, 0.01, rows, mode)
    command_physics(arm, prm, st, io, 0.01, rows)
    physics(arm, prm, st, io, obs, hist, 0.01, rows, STEP)
    model(
        arm,
        prm,
        rows,
        np.zeros((1, m)),
        np.zeros((1, 3)),
        True,
        np.empty((1, 3)),
        np.empty((1, 2)),
        np.empty((1, 3, m)),
    )
    arm_base_jacobians(arm, prm, np.zeros(1), np.zeros((1, 2, m)))
    arm_points(arm, prm, np.zeros((1, m)), np.empty((1, 3)), np.empty((1, 3, m - 2)))
    path_eval(prm[0, PRM.path :].copy(), 0.5, np.empty((3, 3)))
    arc(0.0, 0.0, 0.0, 0.1, 0.1)
    return time.perf_counter() - t0

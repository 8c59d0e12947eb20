"""Start configuration and heading of each named arm for the four tasks, with the kinematic checks behind them.

The tasks (`mobman_env.TASKS`) are fixed in the world: the circle (radius 0.4 m, tilt pi/6) has its centre 0.4 m
towards -x from its start, the line runs 3 m along -x, the lemniscate is 0.6 x 0.3 m, the random path moves
each axis at most 0.3 m; all start at the end-effector point. Every arm therefore starts at heading pi (facing
-x, so each path lies ahead of the platform), the platform at the origin.

## How the starts were chosen

For the PUMA, the paper's theta(0). For the UR5 and the Panda, `select_start` (run by
`python -m mobman_env.robots select`) draws 400 configurations uniformly inside the joint limits
shrunk by 0.3 rad and cut to [-pi, pi] (`default_rng(0)`), keeps those that pass the random-arm start rule
(`mobman_env.robots.random_arms.start_ok`: sigma_min >= 0.15 m/rad, point >= 0.45 m above the ground) and
whose circle's far side lies within 95% of the reach, tracks the circle from each with the arm-only damped least squares
below, and keeps the one whose whole tracked circle has the largest smallest singular value of the position
Jacobian, among those that track it to < 1 mm without coming within 0.1 rad of a joint limit. The winner is
rounded to 0.01 rad and checked again (the table below is for the rounded values).

## The checks (all kinematic, numpy only; the env-level check with the known-model ceiling comes later)

* reach: the largest distance of the end-effector point from the shoulder (the point of joint 2's axis that
  `link_frames` gives: frame 1's origin in standard DH, frame 2's in modified DH) over all configurations,
  ignoring the joint limits (least-squares stretches from 16 random starts, `reach`). For the PUMA this is
  hypot(d3, a2 + hypot(a3, d4)) + tool = 1.077 m (the wrist centre as far as it goes, the tool pointing
  straight away from the shoulder; a test checks it to 1e-6 m).
* circle far side / circle max: the distance from the shoulder of the circle's far side (its start plus 0.8 m
  along the heading) and of its farthest point, as a fraction of the reach, the platform at rest.
* sigma_min: the smallest singular value of the 3 x n position Jacobian at the start (m/rad); margin: the
  smallest distance of a start joint angle to its limit (rad).
* arm-only DLS: the platform fixed, joint speeds qdot = W J_W^T (J_W J_W^T + lambda^2 I)^-1 (v_d + K e) with
  W = diag(speed limits) (the normalised action, clipped to [-1, 1] by scaling the whole vector), K = 20 1/s,
  lambda = 0.05, Euler at 100 Hz for the 20 s circle; joint angles are clipped at the limits (a "hit"). Max
  error is the largest ||r_d - r|| over the 2001 samples; min sigma the smallest sigma_min along the way.
* whole-body DLS: the same law on the n + 2 actuators (wheels with the PUMA platform's r = 0.2 m, b = 0.32 m,
  10 rad/s), the exact unicycle, plus a null-space pull of the arm towards q0, a0 = 0.5 1/s (q0 - q) / speed
  limit, projected by (I - J_W^+ J_W): without it the minimum-norm law lets the arm drift into its limits on
  the 3 m line (UR5: 6.7 mm, 1077 clipped steps; Panda: 2.4 mm, 228) and the PUMA's circle (6.2 mm, 436). All
  four tasks (random path: spec seeds 10000-10004, the worst is shown); hits are summed over the eight runs.

| arm | q0 (rad) | reach (m) | circle far side | circle max | sigma_min (m/rad) | margin (rad) | arm-only circle: max error (m), hits, min sigma | whole body, max error (m) circle / line / lemniscate / random, hits |
|---|---|---|---|---|---|---|---|---|
| puma560 | [0.00, 0.79, 0.00, 2.09, -0.79, 0.00] | 1.077 | 88.0% | 94.9% | 0.188 | 0.79 | 1.1e-01, 854, 0.041 | 2.6e-04 / 1.4e-05 / 6.4e-05 / 8.0e-05, 0 |
| ur5 | [-2.72, 1.72, 1.83, -0.64, -1.29, -1.40] | 1.075 | 50.1% | 53.3% | 0.303 | 1.31 | 2.5e-05, 0, 0.256 | 1.9e-05 / 2.5e-04 / 3.6e-05 / 6.6e-05, 0 |
| panda | [-1.03, -0.68, -1.00, -1.64, -1.22, 0.37, -1.56] | 0.947 | 53.5% | 64.1% | 0.213 | 0.39 | 3.2e-05, 0, 0.213 | 8.2e-05 / 6.2e-05 / 3.8e-05 / 8.0e-05, 0 |

Reading it: the UR5's and the Panda's circles stay within 53% and 64% of the reach, so the arm alone tracks them
(< 0.04 mm, no joint limit met, sigma_min never below 0.21 m/rad along the way). The PUMA's "circle max" is the
docs' "1.022 m of 1.074 m" (95.1%, docs/tasks.md) over the true reach, 1.077 m (that formula keeps the tool along
the forearm; pointing it away from the shoulder reaches 2.6 mm farther). The PUMA's arm alone cannot follow the
paper's circle from theta(0): plain DLS drives joints 1 and 5 into their limits (111 mm error); the platform's
yaw is needed, and with it all four tasks are tracked within 0.3 mm. These are kinematic checks of the starts,
not results: `qp-oracle` in the integrated env is the ceiling that counts.

May import: numpy, the standard library, `mobman_env.robots.*`, `mobman_env.paths`, `mobman_env.params` (the
platform's wheel numbers), `mobman_env.engine` (`track` steps the env's own kinematics).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from mobman_env import engine
from mobman_env.params import RobotParams
from mobman_env.paths import TASK_SPECS, path_from_spec
from mobman_env.robots.catalogue import ROBOTS
from mobman_env.robots.description import ArmDescription
from mobman_env.robots.kinematics import arm_point_and_jacobian, link_frames
from mobman_env.robots.random_arms import RandomArm, random_arm, start_ok

__all__ = [
    "STARTS",
    "TASK_SPECS",
    "Start",
    "ceiling_acceptance",
    "circle_geometry",
    "kinematic_ceiling",
    "reach",
    "select_start",
    "table",
    "track",
]

GAIN = 20.0  # 1/s, the release's task-space gain
DAMPING = 0.05  # DLS lambda (the Jacobian is scaled by the speed limits, so lambda is in m/s)
DT = 0.01  # s, 100 Hz
POSTURE_GAIN = 0.5  # 1/s, whole-body null-space pull of the arm towards q0
RANDOM_PATH_SEEDS = range(10_000, 10_005)  # held-out path seeds (nothing here was tuned on random paths)
_PLATFORM = RobotParams.nominal()


@dataclass(frozen=True)
class Start:
    """Where an arm starts: joint angles q0 (rad) and the platform heading (rad), the platform at the origin."""

    q0: tuple[float, ...]
    heading: float = math.pi


#: name -> start of each named arm (see the module docstring for how they were chosen).
STARTS = {
    "puma560": Start((0.0, math.pi / 4, 0.0, 2 * math.pi / 3, -math.pi / 4, 0.0)),
    # select_start(UR5) and select_start(PANDA), rounded to 0.01 rad
    "ur5": Start((-2.72, 1.72, 1.83, -0.64, -1.29, -1.4)),
    "panda": Start((-1.03, -0.68, -1.0, -1.64, -1.22, 0.37, -1.56)),
}


# --- geometry ------------------------------------------------------------------------------------------
def shoulder(arm: ArmDescription) -> np.ndarray:
    """The point of joint 2's axis in frame 0 (m): frame 1's origin (standard DH) or frame 2's (modified);
    it does not depend on q."""
    frames = link_frames(arm, np.zeros(arm.n_joints))
    return frames[2 if arm.modified else 1, :3, 3].copy()


def reach(arm: ArmDescription, n_starts: int = 16, seed: int = 0) -> float:
    """The largest distance of the end-effector point from the shoulder over all q, limits ignored (m).

    From `n_starts` random configurations, least-squares steps towards a point 0.1 m farther along the current
    direction, halved until the distance grows (at most 300 steps each); the best end point counts.
    """
    s = shoulder(arm)
    rng = np.random.default_rng(seed)
    best = 0.0
    for _ in range(n_starts):
        q = rng.uniform(-math.pi, math.pi, arm.n_joints)
        for _ in range(300):
            p, J = arm_point_and_jacobian(arm, q)
            dist = float(np.linalg.norm(p - s))
            step = np.linalg.lstsq(J, 0.1 * (p - s) / dist, rcond=1e-6)[0]
            for _ in range(20):
                if np.linalg.norm(arm_point_and_jacobian(arm, q + step)[0] - s) > dist:
                    break
                step = 0.5 * step
            else:
                break  # no step in this direction grows the distance: a local maximum
            q = q + step
        best = max(best, float(np.linalg.norm(arm_point_and_jacobian(arm, q)[0] - s)))
    return best


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ee_world(arm: ArmDescription, q: Sequence[float] | np.ndarray, pose: Sequence[float] | np.ndarray) -> np.ndarray:
    """The end-effector point in the world (m) for joint angles q and platform pose (x, y, yaw) of P_0."""
    x, y, yaw = pose
    base = np.array([x + arm.mount_offset * math.cos(yaw), y + arm.mount_offset * math.sin(yaw), arm.base_height])
    return base + _rot_z(yaw) @ arm_point_and_jacobian(arm, q)[0]


def _shoulder_world(arm: ArmDescription, heading: float) -> np.ndarray:
    base = np.array([arm.mount_offset * math.cos(heading), arm.mount_offset * math.sin(heading), arm.base_height])
    return base + _rot_z(heading) @ shoulder(arm)


def circle_geometry(arm: ArmDescription, start: Start, arm_reach: float | None = None) -> dict:
    """Reach, far-side and max circle reach ratios, sigma_min and limit margin at the start (see the docstring)."""
    q0 = np.array(start.q0)
    R = reach(arm) if arm_reach is None else arm_reach
    r0 = ee_world(arm, q0, (0.0, 0.0, start.heading))
    sh = _shoulder_world(arm, start.heading)
    path = path_from_spec(TASK_SPECS["circle"], r0)
    pts = np.array([path.position(t) for t in np.linspace(0.0, path.duration, 721)])
    far = r0 + 0.8 * np.array([math.cos(math.pi), math.sin(math.pi), 0.0])
    J = arm_point_and_jacobian(arm, q0)[1]
    lo, hi = arm.limits
    return {
        "reach": R,
        "far_ratio": float(np.linalg.norm(far - sh)) / R,
        "max_ratio": float(np.max(np.linalg.norm(pts - sh, axis=1))) / R,
        "sigma_min": float(np.linalg.svd(J, compute_uv=False)[-1]),
        "margin": float(np.min(np.minimum(q0 - lo, hi - q0))),
        "height": float(r0[2]),
    }


# --- kinematic tracking check ----------------------------------------------------------------------------
def track(
    arm: ArmDescription, start: Start, spec: dict, *, whole_body: bool, path_seed: int = 0, posture_gain: float = 0.0
) -> dict:
    """Track the path of `spec` (started at the end-effector) with damped least squares, 100 Hz; see the
    module docstring. Returns max_error (m), limit_hits (steps with a clipped joint), min_sigma (m/rad, of
    the arm's position Jacobian) and min_margin (rad, closest approach to a joint limit)."""
    n = arm.n_joints
    lo, hi = arm.limits
    q0 = np.array(start.q0, dtype=float)
    q = q0.copy()
    pose = np.array([0.0, 0.0, start.heading])
    rows = engine.packed([RobotParams.nominal(arm)])  # the env's kernels on the nominal robot (platform: _PLATFORM's)
    J = np.empty((1, 3, n + 2))
    ee, pc = np.empty((1, 3)), np.empty((1, 2))
    row0 = np.zeros(1, dtype=np.intp)
    engine.model(*rows, row0, q[None], pose[None], True, ee, pc, J)
    path = path_from_spec(spec, ee[0], np.random.default_rng(path_seed))
    n_steps = int(round(path.duration / DT))
    m = n + 2 if whole_body else n
    scale = np.array([*arm.speed_limit, *([_PLATFORM.wheel_speed_limit] * 2 if whole_body else [])])
    rw, b = _PLATFORM.wheel_radius, _PLATFORM.half_track
    max_err, hits, min_sig, min_margin = 0.0, 0, math.inf, math.inf
    for k in range(n_steps + 1):
        t = k * DT
        engine.model(*rows, row0, q[None], pose[None], True, ee, pc, J)
        r_d, v_d = path.position_velocity(t)
        err = r_d - ee[0]
        max_err = max(max_err, float(np.linalg.norm(err)))
        min_sig = min(min_sig, float(np.linalg.svd(J[0, :, :n], compute_uv=False)[-1]))  # R(yaw) keeps the svd
        min_margin = min(min_margin, float(np.min(np.minimum(q - lo, hi - q))))
        if k == n_steps:
            break
        Js = J[0, :, :m] * scale
        pinv = Js.T @ np.linalg.inv(Js @ Js.T + DAMPING**2 * np.eye(3))
        a = pinv @ (v_d + GAIN * err)
        if posture_gain > 0.0:
            pull = np.zeros(len(scale))
            pull[:n] = posture_gain * (q0 - q) / scale[:n]
            a += pull - pinv @ (Js @ pull)
        peak = float(np.max(np.abs(a)))
        if peak > 1.0:
            a /= peak
        u = a * scale
        q_new = q + DT * u[:n]
        clipped = np.clip(q_new, lo, hi)
        hits += int(np.any(clipped != q_new))
        q = clipped
        if whole_body:
            dl, dr = u[n] * DT, u[n + 1] * DT
            pose = np.array(engine.arc(pose[0], pose[1], pose[2], 0.5 * rw * (dl + dr), 0.5 * rw / b * (dr - dl)))
    return {"max_error": max_err, "limit_hits": hits, "min_sigma": min_sig, "min_margin": min_margin}


def kinematic_ceiling(draw: RandomArm, tolerance: float = 1e-3) -> bool:
    """A stand-in for `random_arm`'s `accept` hook until the env and `qp-oracle` exist: True when the
    whole-body DLS of `track` follows the circle from the draw's start (heading pi) within `tolerance` (m)
    without clipping a joint at its limit."""
    rec = track(draw.arm, Start(draw.q0), TASK_SPECS["circle"], whole_body=True, posture_gain=POSTURE_GAIN)
    return rec["max_error"] < tolerance and rec["limit_hits"] == 0


def select_start(arm: ArmDescription, n_candidates: int = 400, seed: int = 0) -> tuple[Start, dict]:
    """The start search of the module docstring; returns the rounded winner and its circle-tracking record."""
    rng = np.random.default_rng(seed)
    lo, hi = arm.limits
    R = reach(arm)
    best: tuple[float, Start, dict] | None = None
    for _ in range(n_candidates):
        q0 = rng.uniform(np.maximum(lo + 0.3, -math.pi), np.minimum(hi - 0.3, math.pi))
        if not start_ok(arm, q0):
            continue
        cand = Start(tuple(float(v) for v in q0))
        if circle_geometry(arm, cand, R)["far_ratio"] > 0.95:
            continue
        rec = track(arm, cand, TASK_SPECS["circle"], whole_body=False)
        if rec["max_error"] < 1e-3 and rec["min_margin"] >= 0.1 and (best is None or rec["min_sigma"] > best[0]):
            best = (rec["min_sigma"], cand, rec)
    if best is None:
        raise RuntimeError(f"no start of {arm.name} found in {n_candidates} candidates")
    rounded = Start(tuple(round(v, 2) for v in best[1].q0))
    return rounded, track(arm, rounded, TASK_SPECS["circle"], whole_body=False)


# --- the table in the docstring --------------------------------------------------------------------------
def table() -> str:
    """The Markdown table of the module docstring, recomputed."""
    lines = [
        "| arm | q0 (rad) | reach (m) | circle far side | circle max | sigma_min (m/rad) | margin (rad) "
        "| arm-only circle: max error (m), hits, min sigma | whole body, max error (m) circle / line / "
        "lemniscate / random, hits |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, start in STARTS.items():
        arm = ROBOTS[name]
        geo = circle_geometry(arm, start)
        arm_only = track(arm, start, TASK_SPECS["circle"], whole_body=False)
        wb = {
            task: [track(arm, start, TASK_SPECS[task], whole_body=True, posture_gain=POSTURE_GAIN)]
            for task in ("circle", "line", "lemniscate")
        }
        wb["random"] = [
            track(arm, start, TASK_SPECS["random"], whole_body=True, path_seed=s, posture_gain=POSTURE_GAIN)
            for s in RANDOM_PATH_SEEDS
        ]
        errs = " / ".join(f"{max(r['max_error'] for r in recs):.1e}" for recs in wb.values())
        hits = sum(r["limit_hits"] for recs in wb.values() for r in recs)
        q0 = "[" + ", ".join(f"{v:.2f}" for v in start.q0) + "]"
        lines.append(
            f"| {name} | {q0} | {geo['reach']:.3f} | {100 * geo['far_ratio']:.1f}% | {100 * geo['max_ratio']:.1f}% "
            f"| {geo['sigma_min']:.3f} | {geo['margin']:.2f} | {arm_only['max_error']:.1e}, {arm_only['limit_hits']}, "
            f"{arm_only['min_sigma']:.3f} | {errs}, {hits} |"
        )
    return "\n".join(lines)


def ceiling_acceptance(seeds: range = range(200)) -> tuple[int, int, float]:
    """(arms, predicate calls, mean draws per arm) of `random_arm(default_rng(seed), kinematic_ceiling)`."""
    calls = []

    def counted(draw: RandomArm) -> bool:
        calls.append(draw)
        return kinematic_ceiling(draw)

    draws = [random_arm(np.random.default_rng(s), counted).n_draws for s in seeds]
    return len(draws), len(calls), sum(draws) / len(draws)

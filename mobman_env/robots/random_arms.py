"""The random-arm family: a new 6-joint serial arm (standard DH) and a start configuration per draw.

`random_arm(rng)` draws, from `rng` only (same stream, same arm), a design and a start configuration and redraws
both until the start passes `START_RULE`; an optional `accept(draw)` predicate (e.g. "the known-model ceiling
tracks the task", which needs the env and the controllers) rejects more draws from the same stream.

## The family (every range uniform, m and rad)

Two topologies, each with probability 1/2, both "shoulder + upper arm + forearm + 3-joint wrist" like
industrial arms, every dimension random:

| row | a | alpha | d |
|---|---|---|---|
| 1 | [0, 0.15] | s1 pi/2 + j | 0 (the pedestal is in `base_height`) |
| 2 | [0.30, 0.55] (upper arm) | 0 + j | [-0.20, 0.20] |
| 3 | PUMA-like: [-0.10, 0.10]; UR-like: [0.25, 0.50] (forearm) | PUMA-like: s3 pi/2 + j; UR-like: 0 + j | [-0.15, 0.15] |
| 4 | [-0.05, 0.05] | s4 pi/2 + j | PUMA-like: [0.25, 0.50] (forearm); UR-like: [0, 0.12] |
| 5 | [-0.05, 0.05] | s5 pi/2 + j | [0, 0.12] |
| 6 | 0 | 0 | [0, 0.10] |

s_i: a random sign; j: a twist jitter in [-10, 10] deg, so axes are near, not exactly, perpendicular or parallel
(no exactly intersecting wrist). Tool: [0.10, 0.25] m along z6. Mount: `base_height` 0.6 m and
`mount_offset` 0.1 m (the PUMA's).

Joint limits: joint i's range is [c_i - w_i, c_i + w_i] with c_i in [-0.3, 0.3] rad and w_i in [0.6 pi, pi]
(a range of 216 to 360 deg, as industrial arms have). Speed limits (rad/s): 3 for joints 1-3, 5 for 4-6 (the
PUMA's). Masses (ours, "plausible", not a real arm): a motor (2 kg for links 1-3, 0.5 kg for 4-6) plus a tube of
10 kg/m (links 1-3) or 3 kg/m (4-6) over the link's DH segment length L_i = |(a_i, d_i)|; the centre of mass at
the segment's midpoint; the inertia a solid cylinder of radius 0.05 m (0.04 m for 4-6) and length max(L_i, 0.05
m) along the segment. Torque limits: 3 times a bound on the worst static gravity load (9.81 m/s^2 times the sum
over the distal links of mass times the chain length from the joint to that link's centre; no payload), at
least 10 N m.

## The start rule (`START_RULE`)

q0 is drawn uniformly in [lower + 0.2, upper - 0.2] rad (so no joint starts within 0.2 rad of a limit), then the
draw (design and q0 together) is accepted when

* sigma_min of the 3 x 6 position Jacobian at q0 >= 0.15 m/rad (the PUMA at the paper's theta(0) has 0.188,
  the named arms' starts more: see `mobman_env.robots.starts`), and
* the end-effector point is at least 0.45 m above the ground (above the deck, whose top is at 0.32 m).

Measured acceptance (`python -m mobman_env.robots acceptance`, one `default_rng(seed)` per arm): on seeds 0-999
44.9% of draws pass the start rule, 2.23 draws per arm on average (2.2 s for the 1000 arms); on the held-out
seeds 10000-10999 42.8% of draws pass the start rule, 2.34 draws per arm on average. With
`accept=mobman_env.robots.starts.kinematic_ceiling` (whole-body DLS tracks the circle within 1 mm, no joint
limit met; `python -m mobman_env.robots ceiling`): on seeds 0-199 57.8% of the draws that pass the rule are
accepted (200 of 346), 3.85 draws per arm; on seeds 10000-10199 60.4% (200 of 331), 3.67 draws per arm.

May import: numpy, the standard library, `mobman_env.robots.description`, `mobman_env.robots.kinematics`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mobman_env.robots.description import ArmDescription, rod_inertia, standard_segment
from mobman_env.robots.kinematics import arm_point_and_jacobian

__all__ = ["SCALE_RANGE", "START_RULE", "RandomArm", "acceptance", "random_arm", "random_scaled_arm", "start_ok"]

G = 9.81  # m/s^2
JITTER = math.radians(10.0)  # rad, twist jitter
#: The start rule's constants: limit margin (rad), sigma_min threshold (m/rad), minimum point height (m).
START_RULE = {"limit_margin": 0.2, "min_sigma": 0.15, "min_height": 0.45}
BASE_HEIGHT = 0.6  # m, the PUMA's
MOUNT_OFFSET = 0.1  # m, the PUMA's
#: The scaled family (`random_scaled_arm`): every length of a family arm (DH a and d, tool) times one factor from
#: this range, drawn per arm (protocol v2's held-out arm family: smaller and larger arms than any of the dev track)
SCALE_RANGE = (0.7, 1.4)


@dataclass(frozen=True)
class RandomArm:
    """One accepted draw: the arm, its start configuration q0 (rad, 6 entries) and how many draws it took; for the
    scaled family also the design before scaling (`design`: what its catalogue lists, `arm` being the robot built)."""

    arm: ArmDescription
    q0: tuple[float, ...]
    n_draws: int
    design: ArmDescription | None = None


def _design(rng: np.random.Generator) -> ArmDescription:
    """One arm of the family (see the module docstring), drawn from `rng` in a fixed order."""
    u = rng.uniform
    puma_like = bool(rng.random() < 0.5)
    sign = np.where(rng.random(6) < 0.5, -1.0, 1.0)
    jit = u(-JITTER, JITTER, 6)
    base_alpha = (math.pi / 2, 0.0, math.pi / 2 if puma_like else 0.0, math.pi / 2, math.pi / 2, 0.0)
    alpha = [sign[i] * base_alpha[i] + jit[i] for i in range(5)] + [0.0]
    a = [
        u(0.0, 0.15),
        u(0.30, 0.55),
        u(-0.10, 0.10) if puma_like else u(0.25, 0.50),
        u(-0.05, 0.05),
        u(-0.05, 0.05),
        0.0,
    ]
    d = [
        0.0,
        u(-0.20, 0.20),
        u(-0.15, 0.15),
        u(0.25, 0.50) if puma_like else u(0.0, 0.12),
        u(0.0, 0.12),
        u(0.0, 0.10),
    ]
    tool = u(0.10, 0.25)
    centre = u(-0.3, 0.3, 6)
    half = u(0.6 * math.pi, math.pi, 6)
    seg = [standard_segment(a[i], alpha[i], d[i]) for i in range(6)]
    length = [math.hypot(a[i], d[i]) for i in range(6)]
    prox = [i < 3 for i in range(6)]
    masses = [(2.0 + 10.0 * length[i]) if prox[i] else (0.5 + 3.0 * length[i]) for i in range(6)]
    coms = [tuple(-0.5 * c for c in seg[i]) for i in range(6)]
    inertias = [
        rod_inertia(
            masses[i],
            0.05 if prox[i] else 0.04,
            max(length[i], 0.05),
            seg[i] if length[i] > 1e-3 else (0.0, 0.0, 1.0),
        )
        for i in range(6)
    ]
    # lever bound from joint i (at o_{i-1}) to link j's centre: the segments i..j-1 plus half of j
    torque = []
    for i in range(6):
        load = sum(masses[j] * (sum(length[i:j]) + 0.5 * length[j]) for j in range(i, 6))
        torque.append(max(10.0, 3.0 * G * load))
    return ArmDescription(
        name="random-" + ("puma" if puma_like else "ur"),
        convention="standard",
        a=tuple(a),
        alpha=tuple(alpha),
        d=tuple(d),
        theta_offset=(0.0,) * 6,
        joint_lower=tuple(centre - half),
        joint_upper=tuple(centre + half),
        speed_limit=(3.0, 3.0, 3.0, 5.0, 5.0, 5.0),
        torque_limit=tuple(torque),
        masses=tuple(masses),
        coms=tuple(coms),  # type: ignore[arg-type]
        inertias=tuple(inertias),
        tool=tool,
        base_height=BASE_HEIGHT,
        mount_offset=MOUNT_OFFSET,
    )


def start_ok(arm: ArmDescription, q0: np.ndarray) -> bool:
    """`START_RULE`: every joint >= 0.2 rad inside its limits, sigma_min of the position Jacobian >= 0.15 m/rad
    and the end-effector point >= 0.45 m above the ground."""
    lo, hi = arm.limits
    m = START_RULE["limit_margin"]
    if np.any(q0 < lo + m) or np.any(q0 > hi - m):
        return False
    p, J = arm_point_and_jacobian(arm, q0)
    if arm.base_height + p[2] < START_RULE["min_height"]:
        return False
    return bool(np.linalg.svd(J, compute_uv=False)[-1] >= START_RULE["min_sigma"])


def random_arm(
    rng: np.random.Generator,
    accept: Callable[[RandomArm], bool] | None = None,
    *,
    max_draws: int = 10_000,
) -> RandomArm:
    """Draw designs and start configurations from `rng` until one passes `start_ok` and `accept`.

    `accept`: an extra predicate on the candidate (e.g. "the known-model ceiling tracks the task in the env");
    it is called only on draws that already pass the start rule and may not draw from `rng`. The same `rng`
    state gives the same arm. Raises `RuntimeError` after `max_draws` draws (the message says how many passed
    the start rule, so a too-strict `accept` is visible).
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy Generator (np.random.default_rng(seed)), got {type(rng).__name__}")
    passed_rule = 0
    for k in range(1, max_draws + 1):
        arm = _design(rng)
        lo, hi = arm.limits
        m = START_RULE["limit_margin"]
        q0 = rng.uniform(lo + m, hi - m)
        if not start_ok(arm, q0):
            continue
        passed_rule += 1
        draw = RandomArm(arm, tuple(float(v) for v in q0), k)
        if accept is None or accept(draw):
            return draw
    raise RuntimeError(
        f"no random arm accepted in {max_draws} draws ({passed_rule} passed the start rule {START_RULE}; the rest "
        f"were refused by accept={accept!r}); loosen the predicate or raise max_draws"
    )


def random_scaled_arm(
    rng: np.random.Generator,
    accept: Callable[[RandomArm], bool] | None = None,
    *,
    max_draws: int = 10_000,
) -> RandomArm:
    """An arm of the scaled family: first a factor s from `SCALE_RANGE`, then `random_arm`'s draws, each design's
    lengths (every DH a and d, the tool; not the mount) multiplied by s. The start rule is checked on the unscaled
    design (so the start keeps its margins to the limits, which scaling does not move); `accept` sees the scaled
    arm. Masses and inertias stay the unscaled design's: the family is for kinematic mode (a scaled body's
    inertia would need its own model). The draw keeps the unscaled design (`RandomArm.design`): it is the arm's
    catalogue (the robot a model-based controller is given), so the scale factor is an error of the catalogue that
    only an estimate can find (release 0.4; in 0.3 the catalogue held the scaled arm and the condition tested
    nothing for the nominal-model controllers)."""
    s = float(rng.uniform(*SCALE_RANGE))

    def scaled(draw: RandomArm) -> RandomArm:
        arm = draw.arm.scaled_lengths([s] * len(draw.arm.length_slots)).replace(name=f"{draw.arm.name}-x{s:.3f}")
        return RandomArm(arm, draw.q0, draw.n_draws, design=draw.arm)

    draw = random_arm(rng, None if accept is None else (lambda d: accept(scaled(d))), max_draws=max_draws)
    return scaled(draw)


def acceptance(seeds: range, accept: Callable[[RandomArm], bool] | None = None) -> tuple[float, float]:
    """(accepted arms per draw, mean draws per arm) over `random_arm(default_rng(seed), accept)` for the seeds."""
    draws = [random_arm(np.random.default_rng(s), accept).n_draws for s in seeds]
    return len(draws) / sum(draws), sum(draws) / len(draws)

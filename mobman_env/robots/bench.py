"""`python -m mobman_env.robots bench`: time the generic kinematics against numpy 4 x 4 products.

Prints microseconds per call (best of 5 repeats of `timeit`) for the end-effector point and its position
Jacobian:

* `today numpy (PUMA)`: `mobman_env.kinematics.arm_point_and_jacobian`, the PUMA-only path of release 0.1
  (vectorised DH matrices, one `np.matmul` per link, crosses written out);
* `generic 4x4 numpy`: `link_frames` (a dense 4 x 4 product per link) plus `np.cross` for the columns: the
  obvious generic implementation;
* `generic kernel`: `arm_point_and_jacobian` (the float kernel of `mobman_env.robots.kinematics`);
* `generic kernel, batch of N, per row`: `arm_point_and_jacobian_batch` on N configurations, divided by N.

Speed is machine- and load-dependent: these are measurements, never assertions.

May import: numpy, the standard library, `mobman_env.kinematics`, `mobman_env.params`, `mobman_env.robots`.
"""

from __future__ import annotations

import timeit
from collections.abc import Callable

import numpy as np

from mobman_env import kinematics as puma_kinematics
from mobman_env.params import RobotParams
from mobman_env.robots.catalogue import PANDA, PUMA560, UR5
from mobman_env.robots.description import ArmDescription
from mobman_env.robots.kinematics import arm_point_and_jacobian, arm_point_and_jacobian_batch, link_frames


def dense_point_and_jacobian(arm: ArmDescription, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The obvious generic version: 4 x 4 frames, then z_k x (r - o_k) by `np.cross`."""
    F = link_frames(arm, q)
    r = F[-1, :3, 3] + arm.tool * F[-1, :3, 2]
    axes = F[1:, :3, :] if arm.modified else F[:-1, :3, :]
    return r, np.cross(axes[:, :, 2], r - axes[:, :, 3]).T


def _us(fn: Callable[[], object], number: int) -> float:
    return min(timeit.repeat(fn, number=number, repeat=5)) / number * 1e6


def measure(number: int = 5000, batch: int = 1000) -> list[tuple[str, str, float]]:
    """(arm, method, us per configuration) rows."""
    rng = np.random.default_rng(0)
    rows = []
    params = RobotParams.nominal()
    q6 = rng.uniform(-1.0, 1.0, 6)
    rows.append(
        ("puma560", "today numpy (PUMA)", _us(lambda: puma_kinematics.arm_point_and_jacobian(params, q6), number))
    )
    for arm in (PUMA560, UR5, PANDA):
        q = rng.uniform(-1.0, 1.0, arm.n_joints)
        Q = rng.uniform(-1.0, 1.0, (batch, arm.n_joints))
        rows.append((arm.name, "generic 4x4 numpy", _us(lambda: dense_point_and_jacobian(arm, q), number // 5)))  # noqa: B023
        rows.append((arm.name, "generic kernel", _us(lambda: arm_point_and_jacobian(arm, q), number)))  # noqa: B023
        per_row = _us(lambda: arm_point_and_jacobian_batch(arm, Q), max(1, number // 500)) / batch  # noqa: B023
        rows.append((arm.name, f"generic kernel, batch of {batch}, per row", per_row))
    return rows


def table(rows: list[tuple[str, str, float]]) -> str:
    """The Markdown table of `measure()`'s rows."""
    return "\n".join(
        ["| arm | method | us per configuration |", "|---|---|---|"]
        + [f"| {a} | {m} | {us:.2f} |" for a, m, us in rows]
    )

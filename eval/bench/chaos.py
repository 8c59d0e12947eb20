"""Measure how chaotic a controller is: the same episodes twice, the second with one constant moved by 1e-12.

`measure(policy, ...)` runs each (task, seed) episode with the paper's initial arm pose theta(0) and again with
the angle of joint 1 moved by `perturbation` rad (env argument `arm_joint_pos`; the path starts at the
end-effector, so it moves with it by the same ~1e-12 m) and returns the relative changes of the per-episode
max tracking error. A regular controller changes its result by about the perturbation times a modest factor
(1e-12 .. 1e-7 relative); a chaotic one by tens of percent or more. `eval.output.precision.SIGNIFICANT_DIGITS` holds
the figures measured with this function.

```python
from eval.bench.chaos import measure, digits
spreads = measure("nnbc", seeds=range(10))
digits(spreads)   # 1: one significant digit
```

Development seeds only (0-999): this is a property of the controller, not a reported result. Imports
`eval.rollout`, `mobman_env`, `policies`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from eval.rollout import make_env, rollout

#: The four PUMA tasks the measurement runs on.
TASK_IDS = ("WheeledPuma-Circle-v0", "WheeledPuma-Line-v0", "WheeledPuma-Lemniscate-v0", "WheeledPuma-Random-v0")


def measure(
    policy: str,
    envs: Sequence[str] = TASK_IDS,
    seeds: Iterable[int] = range(10),
    *,
    perturbation: float = 1e-12,
    dynamics: str = "kinematic",
    model_error: float = 0.05,
) -> list[float]:
    """Relative change |e' - e| / e of the max tracking error e of `policy` (a spec) per (env, seed) when the
    initial angle of joint 1 moves by `perturbation` rad. A failed episode gives inf (it cannot be compared)."""
    import policies as policy_registry
    from mobman_env.env import PAPER_ARM_JOINT_POS

    seeds = list(seeds)
    out: dict[tuple[str, int], list[float | None]] = {}
    for env_id in envs:
        for eps in (0.0, perturbation):
            q0 = list(PAPER_ARM_JOINT_POS)
            q0[0] += eps
            env = make_env(env_id, dynamics, model_error, None, {"arm_joint_pos": q0})
            try:
                pol = policy_registry.make(policy, env)
                for s in seeds:
                    rec, _ = rollout(env, pol, s)
                    out.setdefault((env_id, s), []).append(rec["max_error_m"] if rec["status"] == "ok" else None)
            finally:
                env.close()
    spreads = []
    for a, b in out.values():
        if a is None or b is None or not (a > 0):
            spreads.append(math.inf)
        else:
            spreads.append(abs(b - a) / a)
    return spreads


def digits(spreads: Sequence[float], low: int = 1, high: int = 4) -> int:
    """Significant digits a result keeps when it moves by the largest of `spreads` (relative):
    floor(-log10(max spread)), clipped to [low, high]."""
    worst = max(spreads) if spreads else 0.0
    if worst <= 0:
        return high
    if not math.isfinite(worst):
        return low
    return int(min(high, max(low, math.floor(-math.log10(worst)))))

"""Floor references: `zero` (stand still) and `random` (uniform random actions).

They bound the metrics from below: any controller worth reporting must beat `zero` (whose error is simply how
far the path moves away from the start) by a wide margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from policies.base import ControllerPolicy, EnvFacts


@dataclass(frozen=True)
class ZeroConfig:
    """`zero` has no options."""


@dataclass(frozen=True)
class RandomConfig:
    """Options of `random`. Spec keys: `random:amplitude=0.1`."""

    amplitude: float = 1.0
    """Actions are uniform in [-amplitude, amplitude] (normalised units; 1 = the full speed range)."""

    def __post_init__(self):
        a = self.amplitude
        if isinstance(a, bool) or not isinstance(a, (int, float)) or not (math.isfinite(a) and 0 < a <= 1):
            raise ValueError(f"RandomConfig.amplitude must be in (0, 1], got {a!r}")


class Zero(ControllerPolicy):
    """Always commands zero speed."""

    name = "zero"
    uses_keys = ()

    def __init__(self, facts: EnvFacts, config: ZeroConfig | None = None, seed: int | None = None, **extra: Any):
        if extra:
            raise TypeError(f"Zero got unexpected keyword argument(s) {sorted(extra)}")
        super().__init__(facts, seed)
        self.config = config or ZeroConfig()
        self._u = np.zeros(len(self._scale))

    def _reset(self, obs: dict) -> None:
        pass

    def _act(self, obs: dict) -> np.ndarray:
        return self._u


class Random(ControllerPolicy):
    """Uniform random actions from the controller's own Generator (`reset(seed=...)` makes them repeatable)."""

    name = "random"
    uses_keys = ()

    def __init__(self, facts: EnvFacts, config: RandomConfig | None = None, seed: int | None = None, **extra: Any):
        if extra:
            raise TypeError(f"Random got unexpected keyword argument(s) {sorted(extra)}")
        super().__init__(facts, seed)
        self.config = config or RandomConfig()

    def _reset(self, obs: dict) -> None:
        pass

    def _act(self, obs: dict) -> np.ndarray:
        a = self.config.amplitude
        return self.rng.uniform(-a, a, len(self._scale)) * self._scale

"""Floor references: `zero` (stand still) and `random` (uniform random actions).

They bound the metrics from below: any controller worth reporting must beat `zero` (whose error is simply how
far the path moves away from the start) by a wide margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from policies.base import EnvFacts
from policies.batched import BatchedController, LawView


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


class ZeroLaw(BatchedController):
    """`zero` for N robots (`Zero` is its N = 1 case)."""

    name = "zero"

    def __init__(self, facts: EnvFacts, config: ZeroConfig | None = None, n: int = 1, seed: int | None = None):
        super().__init__(facts, n, seed)
        self.config = config or ZeroConfig()
        self._u = np.zeros((n, len(self._scale)))

    def _reset_rows(self, rows: np.ndarray, obs: dict) -> None:
        pass

    def _act(self, obs: dict) -> np.ndarray:
        return self._u


class RandomLaw(BatchedController):
    """`random` for N robots: row i draws from its own Generator `rngs[i]` (one draw of n + 2 per row and step,
    as the single policy), so it equals a single `Random` seeded alike. `Random` is its N = 1 case."""

    name = "random"

    def __init__(self, facts: EnvFacts, config: RandomConfig | None = None, n: int = 1, seed: int | None = None):
        super().__init__(facts, n, seed)
        self.config = config or RandomConfig()

    def _reset_rows(self, rows: np.ndarray, obs: dict) -> None:
        pass

    def _act(self, obs: dict) -> np.ndarray:
        a = self.config.amplitude
        u = np.empty((self.num_envs, len(self._scale)))
        for i, rng in enumerate(self.rngs):
            u[i] = rng.uniform(-a, a, len(self._scale))
        return u * self._scale


class Zero(LawView):
    """Always commands zero speed."""

    name = "zero"

    def __init__(self, facts: EnvFacts, config: ZeroConfig | None = None, seed: int | None = None, **extra: Any):
        if extra:
            raise TypeError(f"Zero got unexpected keyword argument(s) {sorted(extra)}")
        self.law: ZeroLaw = ZeroLaw(facts, config, 1, seed)
        super().__init__(facts, seed)
        self.config = self.law.config

    @classmethod
    def batched(cls, facts: EnvFacts, config: ZeroConfig, n: int, seed: int | None) -> ZeroLaw:
        """The batched law for n robots (`policies.make(spec, vector_env)`)."""
        return ZeroLaw(facts, config, n, seed)


class Random(LawView):
    """Uniform random actions from the controller's own Generator (`reset(seed=...)` makes them repeatable)."""

    name = "random"

    def __init__(self, facts: EnvFacts, config: RandomConfig | None = None, seed: int | None = None, **extra: Any):
        if extra:
            raise TypeError(f"Random got unexpected keyword argument(s) {sorted(extra)}")
        self.law: RandomLaw = RandomLaw(facts, config, 1, seed)
        super().__init__(facts, seed)
        self.config = self.law.config

    @classmethod
    def batched(cls, facts: EnvFacts, config: RandomConfig, n: int, seed: int | None) -> RandomLaw:
        """The batched law for n robots: row i's Generator as a single `Random`'s."""
        return RandomLaw(facts, config, n, seed)

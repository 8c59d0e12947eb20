"""Floor references: `zero` (stand still) and `random` (uniform random actions).

They bound the metrics from below: any controller worth reporting must beat `zero` (whose error is simply how
far the path moves away from the start) by a wide margin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from policies.base import EnvFacts, reject_extra
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


class _PlainView(LawView):
    """The single-env view of a law built from its options alone (no model): `law_cls(facts, config, n, seed)`."""

    law_cls: type[ZeroLaw] | type[RandomLaw]
    law: ZeroLaw | RandomLaw
    #: the knowledge class (`policies.knowledge`): the floor references know nothing about the robot
    knowledge = "none"

    def __init__(self, facts: EnvFacts, config: Any = None, seed: int | None = None, **extra: Any):
        reject_extra(self, extra)
        self.law = self.law_cls(facts, config, 1, seed)
        super().__init__(facts, seed)
        self.config = self.law.config

    @classmethod
    def batched(cls, facts: EnvFacts, config: Any, n: int, seed: int | None) -> BatchedController:
        """The batched law for n robots (`policies.make(spec, vector_env)`): row i as a single policy seeded
        alike."""
        return cls.law_cls(facts, config, n, seed)


class Zero(_PlainView):
    """Always commands zero speed."""

    name = "zero"
    law_cls = ZeroLaw


class Random(_PlainView):
    """Uniform random actions from the controller's own Generator (`reset(seed=...)` makes them repeatable)."""

    name = "random"
    law_cls = RandomLaw

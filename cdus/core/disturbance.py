"""What pushes a vehicle off its reference: a bounded, seeded velocity disturbance.

d(t) = constant + g(t), with g an Ornstein-Uhlenbeck gust per axis (std ``gust`` m/s,
correlation time ``gust_tau`` s), clipped to ±3 std so it stays bounded. The random
stream is seeded by (scenario seed, vehicle id), so a run is reproducible and does not
depend on which process or in which order the vehicles are stepped.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from cdus.core.paths import Vec


@dataclass(frozen=True)
class DisturbanceSpec:
    constant: Vec
    gust: float = 0.0
    gust_tau: float = 2.0


class Disturbance:
    """Stateful sampler; ``step(h)`` advances the gust by h and returns d."""

    def __init__(self, spec: DisturbanceSpec | None, dim: int, seed: int, vehicle_id: str):
        self.spec = spec
        self.dim = dim
        self._rng = random.Random(f"{seed}/{vehicle_id}/gust")
        self._g = [0.0] * dim
        self.value: Vec = tuple(spec.constant) if spec else (0.0,) * dim

    @property
    def active(self) -> bool:
        return self.spec is not None

    def step(self, h: float) -> Vec:
        spec = self.spec
        if spec is None:
            return self.value
        if spec.gust > 0.0:
            decay = math.exp(-h / spec.gust_tau)
            sd = spec.gust * math.sqrt(1.0 - decay * decay)
            bound = 3.0 * spec.gust
            self._g = [max(-bound, min(bound, g * decay + sd * self._rng.gauss(0.0, 1.0))) for g in self._g]
        self.value = tuple(c + g for c, g in zip(spec.constant, self._g))
        return self.value

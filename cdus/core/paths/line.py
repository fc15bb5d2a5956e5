"""What is a line path? f = p₀ + βω·u, u the unit heading, with f' and f'' (= 0)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cdus.core.paths.registry import Family, Param, PathError, Vec, register


@dataclass(frozen=True)
class Line:
    """Straight line f = p0 + βω·u with u the unit direction: |f'| = β m per unit ω."""

    origin: Vec
    heading: Vec  # normalised at construction
    beta: float = 1.0
    direction: float = -1.0

    @property
    def dim(self) -> int:
        return len(self.origin)

    period = None

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        b = self.beta
        f = tuple(p + b * w * u for p, u in zip(self.origin, self.heading))
        f1 = tuple(b * u for u in self.heading)
        zero = tuple(0.0 for _ in self.heading)
        return f, f1, zero


def _line(origin: Vec, heading: Vec, beta: float, direction: float) -> Line:
    norm = math.sqrt(sum(x * x for x in heading))
    if norm == 0:
        raise PathError("heading", "must be a non-zero vector")
    return Line(origin, tuple(x / norm for x in heading), beta, direction)


register(Family(
    "line", "origin=[x, y(, z)], heading=[dx, dy(, dz)] (non-zero)",
    (Param("origin", "vector", required=True), Param("heading", "vector", required=True, dims="origin")),
    _line, speed="1"))

"""What is a circle path? f = c + r (cos βω, sin βω [, c_z]), with f' and f''."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cdus.core.paths.registry import Centred, Family, OneTurn, Param, Vec, register


@dataclass(frozen=True)
class Circle(Centred, OneTurn):
    """f = c + r (cos βω, sin βω [, c_z])."""

    center: Vec
    radius: float
    beta: float = 1.0
    direction: float = -1.0

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        b, r = self.beta, self.radius
        cs, sn = math.cos(b * w), math.sin(b * w)
        cx, cy = self.center[0], self.center[1]
        if len(self.center) == 3:
            return (
                (cx + r * cs, cy + r * sn, self.center[2]),
                (-r * b * sn, r * b * cs, 0.0),
                (-r * b * b * cs, -r * b * b * sn, 0.0),
            )
        return (
            (cx + r * cs, cy + r * sn),
            (-r * b * sn, r * b * cs),
            (-r * b * b * cs, -r * b * b * sn),
        )


register(Family(
    "circle", "center=[x, y(, z)], radius>0 (or speed>0 m/s instead of beta)",
    (Param("center", "vector", required=True), Param("radius", "positive", required=True)),
    Circle, speed="radius"))

"""What is a trefoil path? f = c + s (sin βω + 2 sin 2βω, cos βω - 2 cos 2βω, -h sin 3βω), with f' and f''."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cdus.core.paths.registry import Family, OneTurn, Param, Vec, register


@dataclass(frozen=True)
class Trefoil(OneTurn):
    """Trefoil knot: f = c + s (sin βω + 2 sin 2βω, cos βω - 2 cos 2βω, -h sin 3βω)."""

    center: Vec
    scale: float = 1.0
    height: float = 1.0
    beta: float = 1.0
    direction: float = -1.0

    dim = 3

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        b, s, h = self.beta, self.scale, self.height
        t = b * w
        s1, c1 = math.sin(t), math.cos(t)
        s2, c2 = math.sin(2 * t), math.cos(2 * t)
        s3, c3 = math.sin(3 * t), math.cos(3 * t)
        cx, cy, cz = self.center
        f = (cx + s * (s1 + 2 * s2), cy + s * (c1 - 2 * c2), cz - s * h * s3)
        f1 = (s * b * (c1 + 4 * c2), s * b * (-s1 + 4 * s2), -s * h * 3 * b * c3)
        f2 = (s * b * b * (-s1 - 8 * s2), s * b * b * (-c1 + 8 * c2), s * h * 9 * b * b * s3)
        return f, f1, f2


def _trefoil(scale: float, height: float, center: Vec, beta: float, direction: float) -> Trefoil:
    return Trefoil(center, scale, height, beta, direction)


register(Family(
    "trefoil", "center=[x, y, z], scale>0, height>0",
    # read in this order (scale, height, then center), as the refusals always have been
    (Param("scale", "positive", default=1.0), Param("height", "positive", default=1.0),
     Param("center", "vector", required=True, dims=(3,))),
    _trefoil))

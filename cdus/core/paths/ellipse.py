"""What is an ellipse path? f = c + R(ρ) (a cos βω, b sin βω) [, c_z], with f' and f''."""

from __future__ import annotations

import math
from dataclasses import dataclass

from cdus.core.paths.registry import Centred, Family, OneTurn, Param, Vec, register


@dataclass(frozen=True)
class Ellipse(Centred, OneTurn):
    """f = c + R(ρ) (a cos βω, b sin βω) [, c_z], R(ρ) a rotation by ``rotation`` rad."""

    center: Vec
    a: float
    b: float
    rotation: float = 0.0
    beta: float = 1.0
    direction: float = -1.0

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        k = self.beta
        cs, sn = math.cos(k * w), math.sin(k * w)
        cr, sr = math.cos(self.rotation), math.sin(self.rotation)
        # local components and their derivatives
        lx, ly = self.a * cs, self.b * sn
        dx, dy = -self.a * k * sn, self.b * k * cs
        ddx, ddy = -self.a * k * k * cs, -self.b * k * k * sn

        def rot(x: float, y: float) -> tuple[float, float]:
            return (cr * x - sr * y, sr * x + cr * y)

        f = rot(lx, ly)
        f1 = rot(dx, dy)
        f2 = rot(ddx, ddy)
        cx, cy = self.center[0], self.center[1]
        if len(self.center) == 3:
            return (cx + f[0], cy + f[1], self.center[2]), (*f1, 0.0), (*f2, 0.0)
        return (cx + f[0], cy + f[1]), f1, f2


register(Family(
    "ellipse", "center=[x, y(, z)], a>0, b>0, rotation (rad)",
    (Param("center", "vector", required=True), Param("a", "positive", required=True),
     Param("b", "positive", required=True), Param("rotation", "number", default=0.0)),
    Ellipse))

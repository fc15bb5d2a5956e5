"""What is a lemniscate of Gerono? A figure eight, f = c + (a cos βω, b sin βω cos βω), with f' and f''.

The curve and its derivatives, nothing else (as each of cdus's own families, cdus/core/paths/),
and its declaration: :data:`GERONO`, the object the ``cdus.paths`` entry point ``gerono`` names.
Its tangent f' = β (-a sin βω, b cos 2βω) never vanishes (sin βω = 0 makes cos 2βω = 1) and
f', f'' are bounded by β a, β b and β² a, 2 β² b: the DGVF's assumptions hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from cdus.core.paths import Family, Param

Vec = tuple[float, ...]


@dataclass(frozen=True)
class Gerono:
    """f = c + (a cos βω, (b/2) sin 2βω [, c_z]): ``a`` the half-width, ``b`` the height scale (m)."""

    center: Vec
    half_width: float
    half_height: float
    beta: float = 1.0
    direction: float = -1.0

    @property
    def dim(self) -> int:
        return len(self.center)

    @property
    def period(self) -> float:
        return 2.0 * math.pi / abs(self.beta)

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        a, b, beta = self.half_width, self.half_height, self.beta
        t = beta * w
        c1, s1 = math.cos(t), math.sin(t)
        c2, s2 = math.cos(2.0 * t), math.sin(2.0 * t)
        f = [self.center[0] + a * c1, self.center[1] + 0.5 * b * s2]
        f1 = [-a * beta * s1, b * beta * c2]
        f2 = [-a * beta * beta * c1, -2.0 * b * beta * beta * s2]
        if len(self.center) == 3:  # flown at the height of the center
            f.append(self.center[2])
            f1.append(0.0)
            f2.append(0.0)
        return tuple(f), tuple(f1), tuple(f2)


def _gerono(center: Vec, half_width: float, half_height: float, beta: float, direction: float) -> Gerono:
    return Gerono(center, half_width, half_height, beta, direction)


#: the family as a scenario names it: path = { family = "gerono", center = [0, 0], half_width = 20,
#: half_height = 10, beta = 0.05 }
GERONO = Family(
    "gerono", "center=[x, y(, z)], half_width>0, half_height>0 (m); beta sets the speed",
    (Param("center", "vector", required=True), Param("half_width", "positive", required=True),
     Param("half_height", "positive", required=True)),
    _gerono)

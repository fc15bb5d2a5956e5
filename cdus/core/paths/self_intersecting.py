"""What is the paper's self-intersecting path? f = (16 cos(βω/2), 6 cos(βω + π/2) - d, -2 cos βω) + c:
a :class:`~cdus.core.paths.lissajous.Lissajous`."""

from __future__ import annotations

import math

from cdus.core.paths.lissajous import Lissajous
from cdus.core.paths.registry import Family, Param, Vec, register


def self_intersecting(d: float = 0.0, center: Vec = (0.0, 0.0, 0.0), beta: float = 1.0,
                      direction: float = -1.0) -> Lissajous:
    """The paper's self-intersecting path: f = (16 cos(ω/2), 6 cos(ω + π/2) - d, -2 cos ω).

    ``center`` shifts the whole curve (e.g. a UAV altitude in z); d ∈ {0, ±7, ±14} in
    the paper's simulation. A USV uses the first two components.
    """
    cx, cy, cz = (tuple(center) + (0.0, 0.0, 0.0))[:3]
    return Lissajous(
        center=(cx, cy - d, cz),
        amplitude=(16.0, 6.0, -2.0),
        frequency=(0.5, 1.0, 1.0),
        phase=(0.0, math.pi / 2.0, 0.0),
        beta=beta,
        direction=direction,
    )


register(Family(
    "self_intersecting", "d (offset, paper: 0, ±7, ±14), center=[x, y, z]",
    (Param("d", "number", default=0.0), Param("center", "vector", default=(0.0, 0.0, 0.0), dims=(3,))),
    self_intersecting))

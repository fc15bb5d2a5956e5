"""How close did each vehicle come to an obstacle, and how long did obstacles deflect it?

The ``obstacles`` block of the metrics JSON (docs/metrics.md), from the recorded positions and
each vehicle's count of control steps at which an obstacle's row of its safety filter bound
(cdus.core.vehicle.Vehicle.deflected). Per vehicle, over the obstacles of its medium
(cdus.core.obstacles.seen_by: a boat the water shapes, in x, y; a drone the air shapes, in 3-D):

- ``min_clearance_m``: the smallest signed distance to an obstacle's surface over the run
  (negative: inside it), ``obstacle`` which one, ``t`` when, ``margin_m`` the margin it asks;
- ``deflected_s``: control steps deflected × the control period.

``below_margin`` lists the vehicles whose clearance fell below their obstacle's margin (with the
filter on, none: tests/sim/test_obstacles.py). Pure: arrays in, a dict out.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

from cdus.core.obstacles import Obstacle, clearance, seen_by

#: decimals kept in the JSON (µm, µs): the same figures from every runner
DECIMALS = 6


def obstacle_block(t: Sequence[float], q: Any, ids: Sequence[str], kinds: Sequence[str],
                   obstacles: Sequence[Obstacle], deflected: Sequence[int] | None, period: float) -> dict[str, Any]:
    """``t`` (ticks,), ``q`` (ticks, vehicles, 3) as the recorder keeps them (a boat's z is 0);
    ``deflected``: per vehicle, its deflected control steps (None: not known, reported as null)."""
    vehicles: dict[str, Any] = {}
    below = []
    for j, (vid, kind) in enumerate(zip(ids, kinds)):
        mine = seen_by(kind, obstacles)
        axes = 2 if kind == "usv" else 3
        best = (math.inf, None, None)
        worst_h = math.inf  # the smallest distance - margin over its obstacles
        for n in range(len(t)):
            point = tuple(float(x) for x in q[n][j][:axes])
            for o in mine:
                d = clearance(o, point).distance
                worst_h = min(worst_h, d - o.margin)
                if d < best[0]:
                    best = (d, o, float(t[n]))
        d, o, when = best
        row = {"min_clearance_m": None if o is None else round(d, DECIMALS),
               "obstacle": None if o is None else o.name,
               "t": None if when is None else round(when, DECIMALS),
               "margin_m": None if o is None else o.margin,
               "deflected_s": None if deflected is None else round(deflected[j] * period, DECIMALS)}
        if worst_h < 0.0:
            below.append(vid)
        vehicles[vid] = row
    finite = [r["min_clearance_m"] for r in vehicles.values() if r["min_clearance_m"] is not None]
    return {"count": len(obstacles), "min_clearance_m": min(finite) if finite else None, "below_margin": below,
            "vehicles": vehicles}

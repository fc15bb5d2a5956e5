"""Which vehicles does each vehicle see, and when? The proximity sensor (docs/safety.md).

The world runs it (it alone knows every position); a vehicle receives the positions of
the vehicles its sensor would see, never through the ω link, which carries ω only.

Who sees whom:

- a USV sees the USVs within ``sensing_range`` on the water (2-D distance);
- a UAV sees the UAVs within ``sensing_range`` (3-D distance);
- across domains (``cross_domain``, on by default) a UAV also sees a USV as a point on
  the water surface (x, y, 0), when that point is within ``sensing_range`` in 3-D, and
  takes that pair constraint whole (share 1): the boat does not see up and could not
  dodge a drone if it did, the drone can. UAVs flying at altitude above R never come
  within R of a boat, so this only acts when a UAV descends near one. A USV never sees
  UAVs.

Same-domain contacts carry share 1/2 (both vehicles run the filter). A vehicle that is no
longer live (killed, or paused: its process holds no token) stays where it was last seen,
an obstacle the others take whole (share 1); it receives no contacts. Contacts are listed
in id order, so the result does not depend on the order of the input.

The sensor samples at its own rate: :func:`sample_every` turns it into a number of
control ticks between samples; between samples a vehicle keeps its last contacts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from cdus.core.paths import Vec
from cdus.core.safety import Contact

DOMAIN_DIM = {"usv": 2, "uav": 3}
SURFACE_Z = 0.0  # altitude of the water surface, where a UAV sees a boat


@dataclass(frozen=True)
class Body:
    """One vehicle as the world sees it: id, domain ("usv" or "uav"), position, and whether
    it is live (one that is not is an obstacle that does not react and sees nothing)."""

    id: str
    domain: str
    q: Vec
    live: bool = True

    def __post_init__(self) -> None:
        dim = DOMAIN_DIM.get(self.domain)
        if dim is None:
            raise ValueError(f"proximity: vehicle {self.id!r}: unknown domain {self.domain!r}; "
                             f"choose one of {', '.join(DOMAIN_DIM)}")
        if len(self.q) != dim:
            raise ValueError(f"proximity: vehicle {self.id!r}: a {self.domain} position has {dim} "
                             f"coordinates, got {len(self.q)}")


def _as_3d(b: Body) -> Vec:
    return tuple(b.q) if len(b.q) == 3 else (b.q[0], b.q[1], SURFACE_Z)


def sense(bodies: Sequence[Body], sensing_range: float,
          cross_domain: bool = True) -> dict[str, tuple[Contact, ...]]:
    """For every vehicle, the contacts its proximity sensor reports (possibly none).

    Pairs are found through a horizontal grid of cells ``sensing_range`` wide, so the cost
    grows with the number of vehicles times their neighbours, not with its square.
    """
    if not (sensing_range > 0):
        raise ValueError(f"proximity: sensing range must be > 0 m, got {sensing_range!r}")
    ids = [b.id for b in bodies]
    if len(set(ids)) != len(ids):
        raise ValueError("proximity: vehicle ids must be unique")
    order = sorted(range(len(bodies)), key=lambda i: bodies[i].id)
    found: dict[str, list[tuple[str, Contact]]] = {b.id: [] for b in bodies}
    r2 = sensing_range * sensing_range
    for i, k in _candidate_pairs([bodies[j] for j in order], sensing_range):
        a, b = bodies[order[i]], bodies[order[k]]
        if not (a.live or b.live):
            continue
        if a.domain == b.domain:
            if sum((x - y) ** 2 for x, y in zip(a.q, b.q)) <= r2:
                share = 0.5 if a.live and b.live else 1.0
                found[a.id].append((b.id, Contact(tuple(b.q), b.id, share)))
                found[b.id].append((a.id, Contact(tuple(a.q), a.id, share)))
        elif cross_domain:
            uav, usv = (a, b) if a.domain == "uav" else (b, a)
            seen = _as_3d(usv)
            if sum((x - y) ** 2 for x, y in zip(uav.q, seen)) <= r2:
                found[uav.id].append((usv.id, Contact(seen, usv.id, 1.0)))
    live = {b.id for b in bodies if b.live}
    return {vid: tuple(c for _, c in sorted(lst, key=lambda t: t[0])) for vid, lst in found.items() if vid in live}


def _candidate_pairs(bodies: Sequence[Body], cell: float):
    """Index pairs (i < k) of bodies in the same or adjacent horizontal cells (all pairs
    when the range is infinite)."""
    n = len(bodies)
    if not math.isfinite(cell):
        for i in range(n):
            for k in range(i + 1, n):
                yield i, k
        return
    grid: dict[tuple[int, int], list[int]] = {}
    for i, b in enumerate(bodies):
        grid.setdefault((math.floor(b.q[0] / cell), math.floor(b.q[1] / cell)), []).append(i)
    for (cx, cy), members in grid.items():
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                other = grid.get((cx + dx, cy + dy))
                if other is None:
                    continue
                for i in members:
                    for k in other:
                        if i < k:
                            yield i, k


def sample_every(rate: float, control_rate: float) -> int:
    """Control ticks between two proximity samples: round(control_rate / rate), at least 1.

    A sensor faster than the control loop is sampled every tick (the controller could not
    use more). Sampled on ticks where ``tick % every == 0``; see :func:`is_sample_tick`.
    """
    if not (rate > 0 and math.isfinite(rate)):
        raise ValueError(f"proximity: sensing rate must be a finite number > 0 Hz, got {rate!r}")
    if not (control_rate > 0 and math.isfinite(control_rate)):
        raise ValueError(f"proximity: control rate must be a finite number > 0 Hz, got {control_rate!r}")
    return max(1, round(control_rate / rate))


def is_sample_tick(tick: int, every: int) -> bool:
    """Whether the sensor samples at control tick ``tick`` (tick 0 always)."""
    return tick % every == 0

"""How far is a point from an obstacle, and which way is out? The geometry of ``[[obstacle]]``.

Four shapes (docs/config.md, "[[obstacle]]"): on the water a ``circle`` and a convex ``polygon``
(islands, piers), in the air a vertical ``cylinder`` and an axis-aligned ``box`` (masts, no-fly
zones), each solid with a ``margin`` the vehicles keep from it. Boats see the water shapes (in
x, y), drones the air shapes (in x, y, z): an air shape is the solid between its floor and its
ceiling, so a drone above the ceiling by more than the margin is clear of it and may fly over;
the filter pushes a drone out along the nearest face, sideways or up (docs/safety.md).

:func:`clearance` gives the signed distance from a point to the shape (negative inside), the
outward unit normal (the distance's gradient: the direction from the nearest point of the
surface to the point; inside, the nearest face's normal) and the radius of curvature of the
surface at that nearest point (``bend``: the circle's radius, 0 at a polygon's vertex, inf on
a flat face; the dynamic filter's tangential term, cdus.core.safety). The barrier is
h(q) = distance - margin, continuous in q (a signed distance is 1-Lipschitz). Pure: tuples of
floats in and out, no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence, Union

Vec = tuple[float, ...]

#: the medium each shape is in: boats see "water" shapes, drones "air" shapes
WATER, AIR = "water", "air"
SHAPES = {"circle": WATER, "polygon": WATER, "cylinder": AIR, "box": AIR}
#: the vehicle kind that sees each medium
MEDIUM_OF_KIND = {"usv": WATER, "uav": AIR}
#: a point this close (m) to a circle's centre (or a cylinder's axis) has no radial direction:
#: it is pushed out along +x
AXIS = 1e-12


@dataclass(frozen=True, slots=True)
class Clearance:
    """``distance``: signed, to the shape's surface (m; negative inside); ``normal``: outward,
    unit; ``bend``: radius of curvature of the surface at the nearest point (m; inf: flat)."""

    distance: float
    normal: Vec
    bend: float


@dataclass(frozen=True)
class Circle:
    """A disc on the water: ``center`` (x, y), ``radius`` (m)."""

    center: Vec
    radius: float
    margin: float
    name: str = ""
    shape = "circle"
    medium = WATER


@dataclass(frozen=True)
class Polygon:
    """A convex polygon on the water, ``vertices`` counter-clockwise (:func:`convex_ccw`)."""

    vertices: tuple[Vec, ...]
    margin: float
    name: str = ""
    shape = "polygon"
    medium = WATER


@dataclass(frozen=True)
class Cylinder:
    """A vertical cylinder in the air: axis at ``center`` (x, y), ``radius``, from z = ``z[0]`` to ``z[1]``."""

    center: Vec
    radius: float
    z: tuple[float, float]
    margin: float
    name: str = ""
    shape = "cylinder"
    medium = AIR


@dataclass(frozen=True)
class Box:
    """An axis-aligned box in the air, corners ``lo`` = (x, y, z) min and ``hi`` max."""

    lo: Vec
    hi: Vec
    margin: float
    name: str = ""
    shape = "box"
    medium = AIR


Obstacle = Union[Circle, Polygon, Cylinder, Box]


def seen_by(kind: str, obstacles: Sequence[Obstacle]) -> tuple[Obstacle, ...]:
    """The obstacles a vehicle of ``kind`` avoids: a boat the water shapes, a drone the air shapes."""
    medium = MEDIUM_OF_KIND.get(kind)
    return tuple(o for o in obstacles if o.medium == medium)


def barrier(shape: Obstacle, q: Vec) -> float:
    """h(q) = signed distance - margin (m): ≥ 0 outside the margin, negative inside it."""
    return clearance(shape, q).distance - shape.margin


def clearance(shape: Obstacle, q: Vec) -> Clearance:
    """Signed distance, outward normal and surface bend from ``q`` to ``shape`` (2-D q for a
    water shape, 3-D for an air one; extra components are ignored by a water shape)."""
    if isinstance(shape, Circle):
        return _disc(q, shape.center, shape.radius)
    if isinstance(shape, Polygon):
        return _polygon(q, shape.vertices)
    if isinstance(shape, Cylinder):
        return _cylinder(q, shape)
    return _box(q, shape.lo, shape.hi)


def _disc(q: Vec, c: Vec, r: float) -> Clearance:
    dx, dy = q[0] - c[0], q[1] - c[1]
    rho = math.hypot(dx, dy)
    n = (dx / rho, dy / rho) if rho > AXIS else (1.0, 0.0)
    return Clearance(rho - r, n, r)


def _polygon(q: Vec, vs: tuple[Vec, ...]) -> Clearance:
    """Outside: the nearest point of the boundary (an edge's interior, or a vertex: bend 0);
    inside (every edge's line has q on its inner side): the nearest edge's line."""
    x, y = q[0], q[1]
    best = (math.inf, (1.0, 0.0), math.inf)
    deepest = (-math.inf, (1.0, 0.0))
    inside = True
    for i, (ax, ay) in enumerate(vs):
        bx, by = vs[(i + 1) % len(vs)]
        ex, ey = bx - ax, by - ay
        le = math.hypot(ex, ey)
        nx, ny = ey / le, -ex / le  # outward for counter-clockwise vertices
        side = (x - ax) * nx + (y - ay) * ny
        if side > 0.0:
            inside = False
        if side > deepest[0]:
            deepest = (side, (nx, ny))
        s = ((x - ax) * ex + (y - ay) * ey) / (le * le)
        if s <= 0.0:
            px, py, bend = ax, ay, 0.0
        elif s >= 1.0:
            px, py, bend = bx, by, 0.0
        else:
            px, py, bend = ax + s * ex, ay + s * ey, math.inf
        d = math.hypot(x - px, y - py)
        if d < best[0]:
            best = (d, _unit((x - px, y - py)) or (nx, ny), bend)
    if inside:
        return Clearance(deepest[0], deepest[1], math.inf)
    return Clearance(*best)


def _unit(v: Vec) -> Vec | None:
    """``v`` / |v|, of length 1 to rounding even where ``v``'s components are subnormal (v / hypot(v)
    gave (1, 1) for v = (5e-324, 5e-324): a vehicle that close to a vertex or a rim got a normal of
    length √2); None for the zero vector."""
    m = max(abs(x) for x in v)
    if m == 0.0:
        return None
    w = tuple(x / m for x in v)
    h = math.hypot(*w)
    return tuple(x / h for x in w)


def _cylinder(q: Vec, c: Cylinder) -> Clearance:
    """The solid's signed distance in (radial, vertical): beside it, the radial one (bend: its
    radius); above or below, the vertical one (flat); off the rim, the distance to the rim
    (taken as flat: the dynamic filter's tangential term is then left out, which asks more)."""
    disc = _disc(q, c.center, c.radius)
    dr = disc.distance
    lo, hi = c.z
    z = q[2] if len(q) > 2 else 0.5 * (lo + hi)
    dz, up = (z - hi, 1.0) if z - hi >= lo - z else (lo - z, -1.0)
    nz = (0.0, 0.0, up)
    nr = disc.normal + (0.0,)
    if dr > 0.0 and dz > 0.0:
        sr, sz = _unit((dr, dz))
        return Clearance(math.hypot(dr, dz), (nr[0] * sr, nr[1] * sr, up * sz), math.inf)
    if dr >= dz:
        return Clearance(dr, nr, c.radius)
    return Clearance(dz, nz, math.inf)


def _box(q: Vec, lo: Vec, hi: Vec) -> Clearance:
    """Per axis the distance outside the slab (positive) or inside it (negative); outside, the
    Euclidean norm of the positive parts; inside, the nearest face."""
    dim = len(lo)
    parts = []
    for j in range(dim):
        below, above = lo[j] - q[j], q[j] - hi[j]
        parts.append((below, -1.0) if below >= above else (above, 1.0))
    out = [max(d, 0.0) * s for d, s in parts]
    norm = math.sqrt(sum(x * x for x in out))
    if norm > 0.0:
        return Clearance(norm, tuple(x / norm for x in out), math.inf)
    j = max(range(dim), key=lambda k: parts[k][0])
    return Clearance(parts[j][0], tuple(parts[j][1] if k == j else 0.0 for k in range(dim)), math.inf)


def convex_ccw(vertices: Sequence[Sequence[float]]) -> tuple[tuple[Vec, ...], None] | tuple[None, tuple[int, str]]:
    """``vertices`` as a counter-clockwise convex polygon (either winding is accepted and
    turned counter-clockwise), or (None, (index, why)) naming the first vertex at fault: fewer
    than 3, a repeated vertex, one on the line of its neighbours (degenerate), a turn the other
    way (not convex), or a boundary that winds round more than once (a star)."""
    vs = [(float(v[0]), float(v[1])) for v in vertices]
    n = len(vs)
    if n < 3:
        return None, (n, f"a polygon needs at least 3 vertices, got {n}")
    area2 = sum(vs[i][0] * vs[(i + 1) % n][1] - vs[(i + 1) % n][0] * vs[i][1] for i in range(n))
    order = list(range(n)) if area2 >= 0.0 else list(range(n - 1, -1, -1))
    scale = max(max(abs(c) for v in vs for c in v), 1e-300)
    for i in range(1, n):
        for k in range(i):
            if math.dist(vs[i], vs[k]) <= 1e-12 * scale:
                return None, (i, f"repeats vertex {k} (every vertex must be a distinct corner)")
    turning = 0.0
    for j, i in enumerate(order):
        prev, nxt = vs[order[j - 1]], vs[order[(j + 1) % n]]
        e1 = (vs[i][0] - prev[0], vs[i][1] - prev[1])
        e2 = (nxt[0] - vs[i][0], nxt[1] - vs[i][1])
        cross = e1[0] * e2[1] - e1[1] * e2[0]
        tol = 1e-12 * math.hypot(*e1) * math.hypot(*e2)
        if abs(cross) <= tol:
            return None, (i, "lies on the line through its neighbours (a degenerate corner: remove it)")
        if cross < 0.0:
            return None, (i, "turns the other way from the rest: the polygon is not convex (split it into "
                             "convex [[obstacle]]s, or drop this vertex)")
        turning += math.atan2(cross, e1[0] * e2[0] + e1[1] * e2[1])
    if turning > 3.0 * math.pi:
        return None, (0, f"the boundary winds round {turning / (2 * math.pi):.0f} times (a star): list the "
                         f"vertices in order round the outline")
    return tuple(vs[i] for i in order), None

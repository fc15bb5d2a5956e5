"""What obstacles does a scenario file place? The ``[[obstacle]]`` tables, checked.

Each table is one shape of cdus.core.obstacles (docs/config.md, "[[obstacle]]"):

    [[obstacle]]                      # on the water: boats keep out
    shape = "circle"                  # or "polygon", vertices = [[x, y], ...] (convex, either winding)
    center = [0.0, 8.0]
    radius = 3.0
    margin = 1.0                      # optional; default: [safety] radius

    [[obstacle]]                      # in the air: drones keep out
    shape = "cylinder"                # or "box", min = [x, y, z], max = [x, y, z]
    center = [0.0, -8.0]
    radius = 2.0
    z = [0.0, 40.0]                   # floor and ceiling (m)

``name`` (optional) labels it in errors and in Rerun. A bad table is reported naming the
field and what would be valid (cdus.scenario.checks) and left out. A vehicle that would start
inside an obstacle of its medium is refused (:func:`starts_clear`): the filter would push it
out at γ times its depth, unbounded for a plant without a speed limit (a boat 1e5 m inside
left at km/s).
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping

from cdus.core import obstacles as obs
from cdus.core.paths import Path
from cdus.core.paths.geometry import PathError, for_dimension
from cdus.scenario.checks import Problems, quote
from cdus.wire.bounds import MAX_METRES, is_number

#: shape -> its keys besides shape, margin and name
SHAPE_KEYS = {"circle": ("center", "radius"), "polygon": ("vertices",), "cylinder": ("center", "radius", "z"),
              "box": ("min", "max")}
COMMON_KEYS = ("shape", "margin", "name")
#: a polygon's vertices at most (its convexity check is quadratic in them); an island outline needs tens
MAX_VERTICES = 256
#: obstacles at most: each adds a row to every vehicle's filter at every physics step
MAX_OBSTACLES = 100
#: polygon vertices at most over all the tables: each is an edge every vehicle's filter measures at every
#: step (100 polygons of 256 took 29-66 ms per velocity filter call at load 4-5; 4 of 256, 1.3 ms)
MAX_TOTAL_VERTICES = 1024
EXAMPLE = 'shape = "circle", center = [0.0, 8.0], radius = 3.0'


def obstacle_section(p: Problems, raw: Any, default_margin: float) -> tuple[obs.Obstacle, ...]:
    """The ``[[obstacle]]`` array; ``default_margin`` (m) where a table gives none ([safety] radius)."""
    if raw is None:
        return ()
    tables = p.tables(raw, "obstacle", "obstacle", f", e.g. [[obstacle]] {EXAMPLE}")
    if len(tables) > MAX_OBSTACLES:
        p.add("obstacle", f"at most {MAX_OBSTACLES} [[obstacle]] tables (each is a row of every vehicle's "
                          f"safety filter at every physics step), got {len(tables)}")
        return ()
    out = []
    named: dict[str, int] = {}  # label -> the first obstacle that has it
    for j, t in enumerate(tables):
        got = _one(p, t, f"obstacle[{j}]", default_margin)
        if got is None:
            continue
        if got.name in named:  # the metrics and Rerun tell obstacles apart by it
            p.add(f"obstacle[{j}].name", f"{quote(got.name)} names obstacle[{named[got.name]}] too: give each "
                                         f"obstacle its own name (the metrics and Rerun tell them apart by it)")
            continue
        named[got.name] = j
        out.append(got)
    total = sum(len(o.vertices) for o in out if isinstance(o, obs.Polygon))
    if total > MAX_TOTAL_VERTICES:
        p.add("obstacle", f"at most {MAX_TOTAL_VERTICES} polygon vertices over all the [[obstacle]] tables (each "
                          f"is an edge every vehicle's safety filter measures at every step), got {total}: "
                          f"outline the polygons with fewer corners")
        return ()
    return tuple(out)


def _one(p: Problems, t: dict, field: str, default_margin: float) -> obs.Obstacle | None:
    mark = len(p)
    shape = p.choice(t.get("shape"), f"{field}.shape", obs.SHAPES, "shape",
                     extra=" (circle and polygon on the water, seen by boats; cylinder and box in the air, seen "
                           "by drones)") if "shape" in t else p.missing(f"{field}.shape", f"give the shape, one of "
                                                                        f"{', '.join(obs.SHAPES)}")
    if shape is None:
        return None
    p.unknown_keys(t, COMMON_KEYS + SHAPE_KEYS[shape], field)
    name = p.string(t["name"], f"{field}.name", nonempty=True, one_line=True) if "name" in t else None
    margin = default_margin
    if "margin" in t:
        margin = p.number(t["margin"], f"{field}.margin", ge=0.0, le=MAX_METRES,
                          unit=" m (the distance vehicles keep from the obstacle)")
    for key in SHAPE_KEYS[shape]:
        if key not in t:
            p.missing(f"{field}.{key}", f"a {shape} needs {', '.join(SHAPE_KEYS[shape])}")
    if p.since(mark):
        return None
    label = name or field
    if shape == "circle":
        c = _point(p, t["center"], f"{field}.center", 2, "the circle's centre [x, y] in m")
        r = _radius(p, t["radius"], f"{field}.radius")
        return None if p.since(mark) else obs.Circle(c, r, margin, label)
    if shape == "cylinder":
        c = _point(p, t["center"], f"{field}.center", 2, "the cylinder's axis [x, y] in m")
        r = _radius(p, t["radius"], f"{field}.radius")
        z = _point(p, t["z"], f"{field}.z", 2, "its floor and ceiling [z_min, z_max] in m")
        if z is not None and not z[0] < z[1]:
            p.add(f"{field}.z", f"the floor must be below the ceiling, got [{z[0]:g}, {z[1]:g}]; write [z_min, z_max]")
        return None if p.since(mark) else obs.Cylinder(c, r, z, margin, label)
    if shape == "box":
        lo = _point(p, t["min"], f"{field}.min", 3, "the box's lowest corner [x, y, z] in m")
        hi = _point(p, t["max"], f"{field}.max", 3, "the box's highest corner [x, y, z] in m")
        if lo is not None and hi is not None:
            for axis, a, b in zip("xyz", lo, hi):
                if not a < b:
                    p.add(f"{field}.max", f"must be above {field}.min on every axis: {axis} max {b:g} is not above "
                                          f"min {a:g} (min is the lowest corner, max the highest)")
        return None if p.since(mark) else obs.Box(lo, hi, margin, label)
    return _polygon(p, t["vertices"], field, margin, label)


def _polygon(p: Problems, raw: Any, field: str, margin: float, label: str) -> obs.Polygon | None:
    if not isinstance(raw, list) or len(raw) > MAX_VERTICES:
        p.add(f"{field}.vertices", f"must be a list of 3 to {MAX_VERTICES} points [x, y] (a convex polygon's "
                                   f"corners in order round it), got "
                                   f"{f'{len(raw)} points' if isinstance(raw, list) else quote(type(raw).__name__)}")
        return None
    if raw and all(is_number(v) for v in raw):  # [x0, y0, x1, y1, ...]: one message, not one per number
        p.add(f"{field}.vertices", f"must be a list of corners, each a list [x, y], got a flat list of {len(raw)} "
                                   f"numbers; write e.g. vertices = [[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]]")
        return None
    mark = len(p)
    vs = [_point(p, v, f"{field}.vertices[{i}]", 2, "a corner [x, y] in m") for i, v in enumerate(raw)]
    if p.since(mark):
        return None
    ccw, fault = obs.convex_ccw(vs)
    if fault is not None:
        i, why = fault
        where = f"{field}.vertices" if i >= len(vs) else f"{field}.vertices[{i}]"
        p.add(where, why)
        return None
    return obs.Polygon(ccw, margin, label)


def _point(p: Problems, v: Any, field: str, n: int, what: str) -> tuple[float, ...] | None:
    return p.vector(v, field, n, what, key="path.center")


def _radius(p: Problems, v: Any, field: str) -> float | None:
    return p.number(v, field, "path.radius", unit=" m")


def starts_clear(p: Problems, specs: Iterable[Any], paths: Mapping[str, Path],
                 obstacles: tuple[obs.Obstacle, ...]) -> None:
    """Refuse a vehicle whose start (its ``start``, else its path at its phase, or at
    ``omega0``) is inside an obstacle it avoids (signed distance < 0; inside the margin only is
    allowed: the filter pushes it out at most γ × margin)."""
    for index, spec in enumerate(specs):
        seen = obs.seen_by(getattr(spec, "kind", None), obstacles)
        if spec is None or not seen or spec.id not in paths:
            continue
        if spec.start_position is not None:
            q0, key = tuple(float(x) for x in spec.start_position), "start"
        else:
            try:
                path = for_dimension(paths[spec.id], spec.dim)
            except PathError:
                continue  # reported by the vehicle's own checks
            q0 = path.eval(spec.phase if spec.omega0 is None else spec.omega0)[0]
            key = "phase"
        where = f"vehicle[{index}] (id {quote(spec.id)}).{key}"
        for k, o in enumerate(seen):
            d = obs.clearance(o, q0).distance
            if d < 0.0:
                p.add(where, f"vehicle {spec.id} would start {-d:.6g} m inside obstacle {o.name or k!r} at "
                             f"({', '.join(f'{x:g}' for x in q0)}): the safety filter would push it out at "
                             f"gamma x {-d:.6g} m/s; start it outside (start.position, phase or path) or move "
                             f"the [[obstacle]]")
                break

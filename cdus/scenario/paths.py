"""How does a path table of a scenario become a path? ``{family = "circle", center = [0, 0],
radius = 10}`` read against its family's declaration in the registry (cdus.core.paths.registry),
every number within its bound (cdus.wire.bounds), into the family's curve.

The core's families know nothing of tables; this module is the one door from a table (a
[[vehicle]]'s ``path``, a ``path`` event, ``cdus gs path``) to a :class:`~cdus.core.paths.Path`.
"""

from __future__ import annotations

from typing import Any, Mapping

from cdus.core.paths import (FAMILIES, REGISTRY, Family, Param, Path, PathError, Vec, for_dimension, not_finite_at,
                             turning_point)
from cdus.core.vocabulary import DIMENSIONS
from cdus.scenario.checks import show
from cdus.scenario.plugins import not_found_hint, path_problem, plugin_of
from cdus.wire.bounds import BOUNDS, MAX_METRES, MIN_RATE, finite, within

#: the keys every family takes besides its own
COMMON = frozenset({"family", "beta", "direction", "speed"})

#: what the numbers of a path are, in a refusal
_UNITS = {"radius": " m", "a": " m", "b": " m", "scale": " m", "height": " m", "d": " m", "speed": " m/s",
          "rotation": " rad", "beta": " (speed scaling f(βω))", "center": " m", "origin": " m", "waypoints": " m",
          "heading": " (a direction)", "amplitude": " m", "frequency": " (times βω)", "phase": " rad"}


#: the bound of a number of a plug-in family's own parameter (one cdus.wire.bounds does not name):
#: that of a position, ±MAX_METRES (docs/plugins.md)
PLUGIN_BOUND = within(MAX_METRES)


def bound(key: str):
    """The bound of the path parameter ``key``: BOUNDS["path.<key>"], or :data:`PLUGIN_BOUND`."""
    return BOUNDS.get(f"path.{key}", PLUGIN_BOUND)


def make_path(spec: Mapping[str, Any]) -> Path:
    """Build a path from a config table such as ``{family = "circle", center = [0, 0], radius = 10}``.

    Raises :class:`PathError` naming the offending key and what would be valid.
    """
    name = spec.get("family")
    if name is None:
        raise PathError("family", f"missing; choose one of {', '.join(FAMILIES)}")
    if not isinstance(name, str) or name not in REGISTRY:
        raise PathError("family", f"unknown path family {name!r}; choose one of {', '.join(FAMILIES)}")
    family = REGISTRY[name]
    unknown = sorted(set(spec) - family.keys - COMMON)
    if unknown:
        raise PathError(unknown[0], f"not a parameter of a {name} path; it takes {family.summary}")
    for p in family.params:
        if p.required and p.name not in spec:
            raise PathError(p.name, f"missing; a {name} path takes {family.summary}")
    beta = _number(spec, "beta", 1.0)
    if beta == 0:
        raise PathError("beta", "must be non-zero (speed scaling f(βω))")
    direction = _number(spec, "direction", -1.0, bounded=False)
    if direction not in (-1.0, 1.0):
        raise PathError("direction", f"must be -1 (the paper's choice) or +1, got {direction}")
    if "speed" in spec:
        if "beta" in spec:
            raise PathError("speed", "give either speed or beta, not both")
        if family.speed is None:
            speedy = [f.name for f in REGISTRY.values() if f.speed is not None]
            speedy = ", ".join(speedy[:-1]) + " and " + speedy[-1] if len(speedy) > 1 else "".join(speedy)
            raise PathError("speed", f"only {speedy} have a constant on-path speed; use beta for {name}")
        speed = _positive(spec, "speed")
        beta = speed / (1.0 if family.speed == "1" else _positive(spec, family.speed))
    if not abs(beta) >= MIN_RATE or not BOUNDS["path.beta"].holds(beta):
        by_size = "speed" in spec and family.speed not in (None, "1")
        what = f"speed / {family.speed}" if by_size else "speed" if "speed" in spec else "beta"
        raise PathError("speed" if "speed" in spec else "beta",
                        f"{what} (β, the speed scaling f(βω)) must be within ±{BOUNDS['path.beta'].hi:g} and at "
                        f"least {MIN_RATE:g} in size, got {beta:g}: a vehicle cannot follow such a path (its "
                        f"numbers overflow, or its lap 2π/β does)")
    return family.build(**_values(spec, family), beta=beta, direction=direction)


def _values(spec: Mapping[str, Any], family: Family) -> dict[str, Any]:
    """Each parameter of ``family`` read from ``spec`` (in the declared order), or its default."""
    out: dict[str, Any] = {}
    for p in family.params:
        if p.name not in spec:
            out[p.name] = p.default
            continue
        out[p.name] = v = _read(spec, p, out)
        if p.check is not None:
            p.check(v)
    return out


def _read(spec: Mapping[str, Any], p: Param, read: dict[str, Any]) -> Any:
    if p.kind == "vector":
        dims = (len(read[p.dims]),) if isinstance(p.dims, str) else p.dims
        return _vector(spec, p.name, dims)
    if p.kind == "number":
        return _number(spec, p.name)
    if p.kind == "positive":
        return _positive(spec, p.name)
    if p.kind == "points":
        return _points(spec, p.name)
    v = spec[p.name]  # flag
    if not isinstance(v, bool):
        raise PathError(p.name, f"must be true or false, got {v!r}")
    return v


def _number(spec: Mapping[str, Any], key: str, default: float | None = None, bounded: bool = True) -> float:
    """A finite number within its bound (cdus.wire.bounds.BOUNDS["path.<key>"])."""
    v = spec.get(key, default)
    if not finite(v):
        raise PathError(key, f"must be a finite number, got {v!r}")
    b = bound(key) if bounded else None
    if b is not None and not b.holds(v):
        raise PathError(key, f"{b.problem(v, _UNITS.get(key, ''))}: a vehicle cannot follow such a path (its "
                             f"numbers overflow)")
    return float(v)


def _positive(spec: Mapping[str, Any], key: str) -> float:
    v = spec.get(key)
    if finite(v) and v <= 0:
        raise PathError(key, f"must be > 0, got {float(v)}")
    return _number(spec, key)


def _vector(spec: Mapping[str, Any], key: str, dims: tuple[int, ...] = (2, 3)) -> Vec:
    return _coordinates(spec.get(key), key, key, dims)


def _coordinates(v: Any, key: str, field: str, dims: tuple[int, ...]) -> Vec:
    """``v`` as a tuple of ``dims`` finite numbers within BOUNDS["path.<key>"]; a refusal names ``field``."""
    if not isinstance(v, (list, tuple)) or len(v) not in dims:
        want = " or ".join(str(d) for d in dims)
        raise PathError(field, f"must be a list of {want} numbers, got {v!r}")
    out = []
    b = bound(key)
    for x in v:
        if not finite(x):
            raise PathError(field, f"must contain finite numbers, got {v!r}")
        if not b.holds(x):
            raise PathError(field, f"must contain numbers {b.text()}{_UNITS.get(key, '')}, got {x:g}: a vehicle cannot "
                                   f"follow such a path (its numbers overflow)")
        out.append(float(x))
    return tuple(out)


def check_path(table: Mapping[str, Any], dim: int | None) -> Path | None | tuple[str, str]:
    """The path a table gives a vehicle of ``dim`` axes (a [[vehicle]]'s, a path event's, a ground
    station's), or ``(key, message)``: the key at fault ("" for the table) and what is wrong.
    ``dim`` None (a vehicle of no valid kind): the table alone is checked, None if it holds.
    Never raises on any data."""
    try:  # every number within its bound (cdus.wire.bounds), checked by make_path
        built = make_path(table)
        if dim is None:
            return None
        followed = for_dimension(built, dim)
        if plugin_of(followed) is not None:  # a plug-in's curve: its shape, values and derivatives probed
            problem = path_problem(followed, dim)
            if problem is not None:
                return "", problem
        w = not_finite_at(followed)  # the numbers every vehicle will compute from it stay finite
        if w is not None:
            return "", not_finite_message(w)
        turn = turning_point(followed)
        if turn is not None:  # a retraced Lissajous, refused as the config refuses it
            return "phase", retrace_message(dict(table), turn, dim)
        return followed
    except PathError as e:
        if e.field == "family":
            return "family", (f"unknown path family {show(table.get('family'))}; choose one of {', '.join(FAMILIES)}"
                              f"{not_found_hint('paths')}"
                              if "family" in table else f"missing; choose one of {', '.join(FAMILIES)}")
        return ("" if e.field == "path" else e.field), e.message
    except (TypeError, ValueError, OverflowError, ZeroDivisionError) as e:
        return "", f"invalid path: {e}"


def not_finite_message(w: float) -> str:
    """Why a path whose values are not finite at ω = ``w`` is refused."""
    return f"its values are not finite numbers at ω = {w:g}: a vehicle cannot follow it"


#: a vehicle of each dimension in words (DIMENSIONS: usv 2-D, uav 3-D)
VEHICLE_WORDS = {DIMENSIONS["usv"]: "a boat", DIMENSIONS["uav"]: "a drone"}


def retrace_message(spec: dict, turn: float, dim: int | None) -> str:
    """Why a Lissajous path that runs back over itself is refused, and how to fix it."""
    axes = "its x, y (what a usv follows)" if dim == 2 and len(spec.get("center") or ()) == 3 else "the path"
    if all(a == 0 for a in (spec.get("amplitude") or ())[:dim or 3]) or \
            all(f == 0 for f in (spec.get("frequency") or ())[:dim or 3]):
        return f"{axes} does not move (every amplitude or frequency is 0): there is no path to follow"
    who = VEHICLE_WORDS.get(dim, "a vehicle")  # the kind from the dimension (DIMENSIONS: one kind per dimension)
    return (f"this Lissajous path runs back over itself: {axes} stops at ω = {turn:.4g} (no tangent: {who} "
            f"cannot follow it) and retraces its way (phase {list(spec.get('phase', [0] * len(spec.get('center') or ())))} "
            "turns every moving axis there at once; all phases 0 always do), so any two vehicles on it not at the "
            "same ω meet head-on twice a lap. Give phases that do not, e.g. phase = [0, 1.5708] for frequencies "
            "[1, 2], a figure-eight (docs/config.md, \"Paths\")")


#: the most waypoints a spline takes (a survey of a few km at one every metre)
MAX_WAYPOINTS = 10_000


def _points(spec: Mapping[str, Any], key: str) -> tuple[Vec, ...]:
    """A list of waypoints, each 2 or 3 finite numbers within BOUNDS["path.<key>"], all of one
    length; a refusal names the waypoint (``waypoints[3]``) and its value."""
    v = spec.get(key)
    if not isinstance(v, (list, tuple)) or not 0 < len(v) <= MAX_WAYPOINTS:
        raise PathError(key, f"must be a list of 1 to {MAX_WAYPOINTS} waypoints [x, y] or [x, y, z], got {v!r}")
    out: list[Vec] = []
    for i, p in enumerate(v):
        dims = (len(out[0]),) if out else (2, 3)
        if isinstance(p, (list, tuple)) and out and len(p) in (2, 3) and len(p) != len(out[0]):
            raise PathError(f"{key}[{i}]", f"has {len(p)} coordinates, waypoint 0 has {len(out[0])}: give every "
                                           f"waypoint {len(out[0])} (x, y{', z' if len(out[0]) == 3 else ''})")
        out.append(_coordinates(p, key, f"{key}[{i}]", dims))
    return tuple(out)

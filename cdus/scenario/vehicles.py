"""What is a vehicle in a scenario file? The [[vehicle]] tables and the [defaults] under them.

Each [[vehicle]] is merged over [defaults] (:func:`merge`), then checked part by part
(kind and plant, ε, regulator, phase, path, start, gains, limits, disturbance) into a
:class:`VehicleSpec`. A problem in a value that came from [defaults] is reported on the
vehicle and marked " (set in [defaults])". docs/config.md is the user reference.
"""

from __future__ import annotations

import copy
import math
import random
import re
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

from cdus.commands.gains import expand_k
from cdus.core.gain_bounds import gains_problem_for_rate, regulator_gains_problem
from cdus.core.limits import default_limits
from cdus.core.models import DEFAULT_PRESET, PLANTS as MODELS
from cdus.core.paths import FAMILIES, Path
from cdus.core.plants import USV_PRESETS
from cdus.core.vocabulary import DIMENSIONS, KINDS
from cdus.scenario.checks import IdList, Problems, describe, is_number, quote, show
from cdus.scenario.model import Edge, Rates, VehicleSpec
from cdus.scenario.paths import check_path
from cdus.scenario.plugins import not_found_hint
from cdus.scenario.robot import robot_table
from cdus.scenario.sections import DEFAULT_GAINS, gain_values
from cdus.wire.bounds import finite

class _Live(Mapping):
    """A view of the vehicle models' table (cdus.core.models.PLANTS) as it is now: a plug-in
    (cdus.scenario.plugins) registered after this module was imported is in it."""

    def __init__(self, view: Any):
        self._view = view

    def __getitem__(self, key: Any) -> Any:
        return self._view()[key]

    def __iter__(self):
        return iter(self._view())

    def __len__(self) -> int:
        return len(self._view())


#: plant -> kinds it models (the vehicle models' one table: cdus.core.models.PLANTS)
PLANTS: Mapping[str, tuple[str, ...]] = _Live(lambda: {name: m.kinds for name, m in MODELS.items()})
#: usv_3dof parameter presets ε1..ε7 (a CyberShip II-like 3-DOF model).
PRESETS: dict[str, tuple[float, ...]] = USV_PRESETS
#: plant -> regulator -> allowed regulator_gains keys; the first regulator is the default.
REGULATORS: Mapping[str, dict[str, tuple[str, ...]]] = _Live(lambda: {
    name: {r: rm.gain_keys for r, rm in m.regulators.items()} for name, m in MODELS.items() if m.regulators})
LIMIT_KEYS = ("speed", "accel", "tau_u", "tau_r", "yaw_rate")
VEHICLE_KEYS = ("id", "kind", "plant", "preset", "epsilon", "regulator", "regulator_gains", "phase",
                "path", "start", "omega0", "gains", "limits", "disturbance", "ros2")
TABLE_KEYS = ("path", "start", "gains", "regulator_gains", "limits", "disturbance")
START_KEYS = ("position", "heading", "region_min", "region_max")
DISTURBANCE_KEYS = ("constant", "gust", "gust_tau")
ID_PATTERN = re.compile(r"[A-Za-z0-9_-]{1,32}")
PATH_EXAMPLE = '{ family = "circle", center = [0, 0], radius = 10 }'
#: The largest fleet a scenario may hold. Each vehicle of `cdus launch` is an OS process of
#: 49-51 MB (README, "Measured"), so 1,024 vehicles need about 50 GB, beyond any one host;
#: realtime holds 48-64 vehicles at 50 Hz on a 2-core machine and `cdus sim` runs 600 at 1x
#: real time (~30 µs per vehicle step). The ω wire format itself carries sender indices up to
#: 65,535 (uint16 past 256), so it is not the bound. Raise it here if a host can take more.
MAX_VEHICLES = 1024


@dataclass
class Fleet:
    """The [[vehicle]] array checked: per table its id and spec (None where bad), and the paths."""

    ids: list[str | None] = field(default_factory=list)
    specs: list[VehicleSpec | None] = field(default_factory=list)
    paths: dict[str, Path] = field(default_factory=dict)

    @property
    def known(self) -> IdList:
        """The valid, unique ids (O(1) membership)."""
        return IdList(v for v in self.ids if v is not None)

    @property
    def complete(self) -> bool:
        """Every vehicle has a valid, unique id (so references to ids can be checked)."""
        return bool(self.ids) and None not in self.ids


# --------------------------------------------------------------------------- [defaults]


def defaults_section(p: Problems, defaults: Mapping[str, Any]) -> dict:
    """What can be checked in [defaults] without a vehicle: keys, table shapes, names.
    Returns the defaults that can be merged (known keys, tables where tables belong)."""
    if "id" in defaults:
        p.add("defaults.id", "an id cannot be a default; give every [[vehicle]] its own id")
    p.unknown_keys(defaults, [k for k in VEHICLE_KEYS if k != "id"], "defaults", skip=("id",))
    for key in TABLE_KEYS:
        if key in defaults:
            p.table(defaults[key], f"defaults.{key}", f"{key} = {{ ... }}")
    # names that are skipped for vehicles they do not apply to must at least exist somewhere
    if "preset" in defaults:
        p.choice(defaults["preset"], "defaults.preset", PRESETS, "preset")
    if "regulator" in defaults:
        p.choice(defaults["regulator"], "defaults.regulator", [r for regs in REGULATORS.values() for r in regs],
                 "regulator")
    if isinstance(defaults.get("regulator_gains"), dict):
        all_gains = sorted({g for regs in REGULATORS.values() for keys in regs.values() for g in keys})
        p.unknown_keys(defaults["regulator_gains"], all_gains, "defaults.regulator_gains")
    return {k: v for k, v in defaults.items()
            if k in VEHICLE_KEYS and k != "id" and (k not in TABLE_KEYS or isinstance(v, dict))}


def merge(defaults: Mapping, vehicle: Mapping) -> tuple[dict, set[tuple[str, ...]]]:
    """[defaults] under a vehicle: the vehicle wins; tables merge one level deep.

    Where the two give alternatives, the vehicle's choice replaces the default's: epsilon
    vs preset, start.position vs start.region_min/max, and a path of another family.
    Returns the merged table and the set of (key,) / (key, subkey) taken from [defaults].
    """
    merged: dict = copy.deepcopy(dict(defaults))
    origin: set[tuple[str, ...]] = {(key,) for key in defaults}
    origin |= {(key, sub) for key, dv in defaults.items() if isinstance(dv, dict) for sub in dv}
    alternatives = {"preset": "epsilon", "epsilon": "preset"}
    for key, vv in vehicle.items():
        other = alternatives.get(key)
        if other in merged and (other,) in origin:
            del merged[other]
            origin = {o for o in origin if o[0] != other}
        base = merged.get(key)
        if key in TABLE_KEYS and isinstance(vv, dict) and isinstance(base, dict):
            base = dict(base)
            if key == "start" and any(sub in vv for sub in ("position", "region_min", "region_max")):
                for sub in ("position", "region_min", "region_max"):
                    base.pop(sub, None)
            if key == "path" and "family" in vv and vv["family"] != base.get("family"):
                base = {}
            origin = {o for o in origin if not (o[0] == key and (len(o) == 1 or o[1] not in base or o[1] in vv))}
            base.update(vv)
            merged[key] = base
        else:
            merged[key] = vv
            origin = {o for o in origin if o[0] != key}
    return merged, origin


# --------------------------------------------------------------------------- [[vehicle]]


def vehicles_section(p: Problems, raw: Any, defaults: Mapping, fleet_gains: Mapping, seed: int) -> Fleet:
    """Every [[vehicle]], checked and resolved."""
    fleet = Fleet()
    if raw is None or raw == []:
        p.add("vehicle", "no vehicles; add at least one [[vehicle]] table with id, kind and path")
        return fleet
    tables = p.tables(raw, "vehicle", "vehicle", ", not [vehicle]")
    if len(tables) > MAX_VEHICLES:
        p.add("vehicle", f"{len(tables)} [[vehicle]] tables, more than the fleet-size limit of {MAX_VEHICLES}: every "
                         f"vehicle of cdus launch is a process of about 50 MB ({MAX_VEHICLES} take about 50 GB) and "
                         f"realtime holds about 48-64 vehicles at 50 Hz on this kind of machine; split the fleet or "
                         f"raise MAX_VEHICLES in cdus/scenario/vehicles.py on a host that can take it")
        return fleet
    first_index: dict[str, int] = {}
    for index, table in enumerate(tables):
        vid = vehicle_id(p, table, index, first_index)
        spec, path = vehicle(p, table, index, vid, defaults, fleet_gains, seed)
        fleet.ids.append(vid)
        fleet.specs.append(spec)
        if vid is not None and path is not None:
            fleet.paths[vid] = path
    return fleet


def vehicle_id(p: Problems, raw: Mapping, index: int, first_index: dict[str, int]) -> str | None:
    """The vehicle's id if valid and unique, else None (after reporting)."""
    where = f"vehicle[{index}].id"
    if "id" not in raw:
        p.missing(where, 'every vehicle needs a unique id, e.g. id = "usv1"')
        return None
    vid = raw["id"]
    if not isinstance(vid, str):
        p.add(where, f"must be a string of 1-32 letters, digits, _ or -, got {describe(vid)}")
        return None
    if not ID_PATTERN.fullmatch(vid):
        p.add(where, f"{show(vid)} is not a valid id: use 1-32 characters from A-Z a-z 0-9 _ - "
                     f"(it names the vehicle's process and keys)")
        return None
    if vid in first_index:
        p.add(where, f"duplicate id {quote(vid)} (also vehicle[{first_index[vid]}]); ids must be unique")
        return None
    first_index[vid] = index
    return vid


@dataclass
class _Merged:
    """One [[vehicle]] merged over [defaults]: its values and which of them came from [defaults]."""

    label: str  # vehicle[2] (id "uav1")
    v: dict
    origin: set[tuple[str, ...]]

    def field(self, *parts: Any) -> str:
        return self.label + "".join(f".{x}" for x in parts)

    def note(self, *key: str) -> str:
        return " (set in [defaults])" if key in self.origin else ""


def vehicle(p: Problems, raw: Mapping, index: int, vid: str | None, defaults: Mapping, fleet_gains: Mapping,
            seed: int) -> tuple[VehicleSpec | None, Path | None]:
    """One [[vehicle]] (merged with [defaults]): (spec or None, its path or None)."""
    label = f"vehicle[{index}]" + (f" (id {quote(vid)})" if vid is not None else "")
    mark = len(p)
    p.unknown_keys(raw, VEHICLE_KEYS, label)
    t = _Merged(label, *merge(defaults, raw))
    kind, plant = _kind_plant(p, t)
    dim = DIMENSIONS[kind] if kind is not None else None
    _skip_defaults(t, kind, plant)
    epsilon, preset = _epsilon(p, t, plant)
    regulator, regulator_gains = _regulator(p, t, plant)
    phase = _phase(p, t)
    path, path_pairs = _path(p, t, dim)
    start_position, start_heading = _start(p, t, kind, seed, vid)
    omega0 = _omega0(p, t)
    k, c = _gains(p, t, kind, fleet_gains)
    limits = _limits(p, t, plant, preset)
    disturbance = _disturbance(p, t, kind)
    robot = robot_table(p, t.v.get("ros2"), t.field("ros2"), plant, vid)
    if p.since(mark) or vid is None or kind is None or plant is None or dim is None:
        return None, path
    return VehicleSpec(
        id=vid, index=index, kind=kind, dim=dim, plant=plant, epsilon=epsilon, preset=preset,
        regulator=regulator, regulator_gains=regulator_gains, path=path_pairs, phase=phase,
        start_position=start_position, start_heading=start_heading, omega0=omega0, k=k, c=c,
        limits=limits, disturbance=disturbance, robot=robot,
    ), path


def _kind_plant(p: Problems, t: _Merged) -> tuple[str | None, str | None]:
    kind = None
    if "kind" not in t.v:
        p.missing(t.field("kind"), 'choose "usv" (boat, 2-D) or "uav" (drone, 3-D)')
    else:
        kind = p.choice(t.v["kind"], t.field("kind"), KINDS, "kind", note=t.note("kind"))
    plant = p.choice(t.v.get("plant", "ideal"), t.field("plant"), PLANTS, "plant", note=t.note("plant"),
                     extra=not_found_hint("plants"))
    if plant is not None and kind is not None and kind not in PLANTS[plant]:
        valid = " or ".join(quote(x) for x, kinds in PLANTS.items() if kind in kinds)
        p.add(t.field("plant"), f"plant {quote(plant)} models a {' or '.join(PLANTS[plant])}, not a {kind}"
                                f"{t.note('plant')}; a {kind} takes plant = {valid}")
        plant = None
    return kind, plant


def _skip_defaults(t: _Merged, kind: str | None, plant: str | None) -> None:
    """Drop the [defaults] values that do not apply to this vehicle's kind or plant."""
    if plant is not None:
        regs = REGULATORS.get(plant, {})
        for key in ("preset", "epsilon"):
            if plant != "usv_3dof" and (key,) in t.origin:
                t.v.pop(key, None)
        if ("regulator",) in t.origin and t.v.get("regulator") not in regs:
            t.v.pop("regulator", None)
        if ("regulator_gains",) in t.origin and not regs:
            t.v.pop("regulator_gains", None)
    if kind == "uav" and ("start", "heading") in t.origin:
        t.v["start"] = {k: x for k, x in t.v["start"].items() if k != "heading"}


def _epsilon(p: Problems, t: _Merged, plant: str | None) -> tuple[tuple[float, ...] | None, str | None]:
    """usv_3dof's ε1..ε7, from a preset or given: (epsilon, preset)."""
    if plant != "usv_3dof":
        for key in ("preset", "epsilon"):
            if plant is not None and key in t.v:
                p.add(t.field(key), f'only used by plant = "usv_3dof" (this vehicle\'s plant is {quote(plant)}); '
                                    f"remove it")
        return None, None
    if "preset" in t.v and "epsilon" in t.v:
        p.add(t.field("epsilon"), "give either preset or epsilon, not both")
        return None, None
    if "epsilon" in t.v:
        eps = p.vector(t.v["epsilon"], t.field("epsilon"), 7, "ε1..ε7", t.note("epsilon"), "vehicle.epsilon")
        if eps is not None and (eps[2] == 0 or eps[4] == 0):
            p.add(t.field("epsilon"), f"ε3 and ε5 must be non-zero (they scale the inputs τ_u and τ_r: "
                                      f"ε3 = 1/m11, ε5 = 1/m33), got {show(t.v['epsilon'])}{t.note('epsilon')}")
            return None, None
        return eps, None
    preset = p.choice(t.v.get("preset", DEFAULT_PRESET), t.field("preset"), PRESETS, "preset",
                      note=t.note("preset"), extra=" (or give epsilon = [ε1, ..., ε7])")
    return (PRESETS[preset], preset) if preset is not None else (None, None)


def _regulator(p: Problems, t: _Merged, plant: str | None) -> tuple[str | None, tuple[tuple[str, float], ...]]:
    """(regulator, regulator_gains) of a vehicle model; none for the ideal plant."""
    if plant is not None and plant not in REGULATORS:
        for key in ("regulator", "regulator_gains"):
            if key in t.v:
                p.add(t.field(key), f'the {plant} plant has no regulator; remove it, or choose plant = '
                                    '"usv_3dof" (usv) or "uav_double_integrator" (uav)')
        return None, ()
    if plant is None:
        return None, ()
    regs = REGULATORS[plant]
    regulator = _regulator_name(p, t, plant, regs)
    gains = p.table(t.v.get("regulator_gains", {}), t.field("regulator_gains"), "regulator_gains = { ... }",
                    t.note("regulator_gains")) or {}
    if regulator is None:
        return None, ()
    allowed = regs[regulator]
    # gains from [defaults] that belong to another regulator are skipped
    gains = {g: x for g, x in gains.items() if g in allowed or ("regulator_gains", g) not in t.origin}
    p.unknown_keys(gains, allowed, t.field("regulator_gains"), what="regulator gain",
                   valid=f"the {regulator} regulator takes")
    return regulator, _positive_pairs(p, t, gains, allowed, "regulator_gains")


def _regulator_name(p: Problems, t: _Merged, plant: str, regs: Mapping[str, Any]) -> str | None:
    name = t.v.get("regulator", next(iter(regs)))
    if name in regs:
        return name
    if name in {r for rs in REGULATORS.values() for r in rs}:
        p.add(t.field("regulator"), f"regulator {quote(name)} is not one for plant {quote(plant)}"
                                    f"{t.note('regulator')}; choose one of {', '.join(regs)}")
        return None
    return p.choice(name, t.field("regulator"), regs, "regulator", note=t.note("regulator"),
                    extra=f" (the regulators of plant {quote(plant)})")


def _positive_pairs(p: Problems, t: _Merged, table: Mapping[str, Any], allowed: tuple[str, ...],
                    name: str) -> tuple[tuple[str, float], ...]:
    # their bound: vehicle.regulator_gains, vehicle.limits (cdus.wire.bounds)
    """The allowed keys of ``table`` whose values are numbers > 0, as sorted (key, value) pairs."""
    pairs = []
    for key in sorted(k for k in table if k in allowed):
        x = p.number(table[key], t.field(name, key), f"vehicle.{name}", note=t.note(name, key))
        if x is not None:
            pairs.append((key, x))
    return tuple(pairs)


def _phase(p: Problems, t: _Merged) -> float:
    if "phase" not in t.v:
        return 0.0
    phase = p.number(t.v["phase"], t.field("phase"), "vehicle.phase", unit=" (θ_i, in ω units)", note=t.note("phase"))
    return 0.0 if phase is None else phase


def _path(p: Problems, t: _Merged, dim: int | None) -> tuple[Path | None, tuple]:
    """(the path for this vehicle's dimension or None, the path table as sorted pairs)."""
    if "path" not in t.v:
        p.missing(t.field("path"), f"e.g. path = {PATH_EXAMPLE}; families: {', '.join(FAMILIES)}")
        return None, ()
    spec = p.table(t.v["path"], t.field("path"), PATH_EXAMPLE, t.note("path"))
    if spec is None:
        return None, ()
    checked = check_path(spec, dim)
    if not isinstance(checked, tuple):
        return checked, _frozen(spec)
    key, message = checked
    sub = (key,) if key else ()
    # waypoints[1] was set where its list was: the note of "waypoints"
    where, note = t.field("path", *sub), t.note("path", *(k.split("[")[0] for k in sub))
    if key == "family" and "family" in spec:
        p.choice(spec["family"], where, FAMILIES, "path family", note=note, extra=not_found_hint("paths"))
    else:
        p.add(where, f"{message}{note}")
    return None, ()


def _frozen(v: Any) -> Any:
    """Lists -> tuples, tables -> sorted pairs, recursively (hashable)."""
    if isinstance(v, list):
        return tuple(_frozen(x) for x in v)
    if isinstance(v, dict):
        return tuple(sorted((k, _frozen(x)) for k, x in v.items()))
    return v


def _start(p: Problems, t: _Merged, kind: str | None, seed: int,
           vid: str | None) -> tuple[tuple[float, ...] | None, float | None]:
    """(start_position, start_heading): given, drawn in a box, or None (on the path)."""
    st = p.table(t.v.get("start", {}), t.field("start"), "start = { position = [0, 0] }", t.note("start")) or {}
    p.unknown_keys(st, START_KEYS, t.field("start"))
    heading: float | None = None
    if "heading" in st:
        if kind == "uav":
            p.add(t.field("start", "heading"), "a uav has no heading; remove it (headings are for usv starts)")
        else:
            heading = p.number(st["heading"], t.field("start", "heading"), "vehicle.start.heading", unit=" (rad)",
                               note=t.note("start", "heading"))
    if kind is None:
        return None, None
    has_region = "region_min" in st or "region_max" in st
    if "position" in st and has_region:
        p.add(t.field("start"), "give either position or region_min/region_max, not both")
        return None, None
    if "position" in st:
        dim = DIMENSIONS[kind]
        pos = p.vector(st["position"], t.field("start", "position"), dim,
                       f"a {kind} position {'[x, y]' if dim == 2 else '[x, y, z]'} in m", t.note("start", "position"),
                       "vehicle.start.position")
        return pos, (0.0 if kind == "usv" and heading is None else heading)
    if has_region:
        return _region_start(p, t, st, kind, heading, random.Random(f"{seed}/{vid}"))
    return None, heading


def _region_start(p: Problems, t: _Merged, st: Mapping, kind: str, heading: float | None,
                  rng: random.Random) -> tuple[tuple[float, ...] | None, float | None]:
    """A uniform random start in the box, and for a usv a random heading unless given."""
    dim = DIMENSIONS[kind]
    corners = []
    for key, other in (("region_min", "region_max"), ("region_max", "region_min")):
        if key not in st:
            p.missing(t.field("start", key), f"a random start box needs both region_min and region_max "
                                             f"(only {other} is given)")
            return None, None
        corners.append(p.vector(st[key], t.field("start", key), dim, f"a {kind} box corner in m",
                                t.note("start", key), "vehicle.start.region"))
    lo, hi = corners
    if lo is None or hi is None:
        return None, None
    bad = [j for j in range(dim) if not lo[j] < hi[j]]
    if bad:
        p.add(t.field("start", "region_min"),
              f"must be < region_max on every axis; not on {', '.join('xyz'[j] for j in bad)}: region_min = "
              f"{show(st['region_min'])}, region_max = {show(st['region_max'])}")
        return None, None
    pos = tuple(a + (b - a) * rng.random() for a, b in zip(lo, hi))
    if kind == "usv" and heading is None:
        heading = -math.pi + 2.0 * math.pi * rng.random()
    return pos, heading


def _omega0(p: Problems, t: _Merged) -> float | None:
    if "omega0" not in t.v or t.v["omega0"] == "nearest":
        return None
    return p.number(t.v["omega0"], t.field("omega0"), "vehicle.omega0", unit=' (or "nearest": the ω of the path point nearest '
                                                          'the start)', note=t.note("omega0"))


def _gains(p: Problems, t: _Merged, kind: str | None, fleet_gains: Mapping) -> tuple[tuple[float, ...], float]:
    """(k per axis, c): built-in < [gains] < [defaults].gains < the vehicle's gains."""
    vg = p.table(t.v.get("gains", {}), t.field("gains"), "gains = { k = 1.5, c = 2.0 }", t.note("gains")) or {}
    p.unknown_keys(vg, DEFAULT_GAINS, t.field("gains"))
    gain_values(p, vg, t.field("gains"), t.note("gains"))
    k_raw = vg["k"] if "k" in vg else fleet_gains.get("k", DEFAULT_GAINS["k"])
    c_raw = vg.get("c", fleet_gains.get("c", DEFAULT_GAINS["c"]))
    c = float(c_raw) if finite(c_raw) else DEFAULT_GAINS["c"]
    if kind is None:
        return (), c
    dim = DIMENSIONS[kind]
    if isinstance(k_raw, list) and len(k_raw) != dim:
        note = t.note("gains", "k") if "k" in vg else " (set in [gains])"
        p.add(t.field("gains", "k"), f"a list of per-axis gains needs {dim} values for a {kind} "
                                     f"({'x, y' if dim == 2 else 'x, y, z'}), got {len(k_raw)}: {show(k_raw)}{note}")
        return (), c
    if isinstance(k_raw, list) and all(finite(x) and x > 0 for x in k_raw):
        return expand_k(tuple(k_raw), dim), c
    if finite(k_raw) and k_raw > 0:
        return expand_k(k_raw, dim), c  # the one per-axis expansion (a run-time gains command's too)
    return (), c


def _limits(p: Problems, t: _Merged, plant: str | None, preset: str | None) -> tuple[tuple[str, float], ...]:
    """The limits given, over the plant preset's defaults (cdus.core.limits) with preset = true."""
    lt = p.table(t.v.get("limits", {}), t.field("limits"), "limits = { speed = 2.0 }", t.note("limits")) or {}
    p.unknown_keys(lt, (*LIMIT_KEYS, "preset"), t.field("limits"))
    given = _positive_pairs(p, t, lt, LIMIT_KEYS, "limits")
    if "preset" not in lt:
        return given
    use = p.boolean(lt["preset"], t.field("limits", "preset"), true=" (start from the plant preset's limits)",
                    false=" (only the limits given)", note=t.note("limits", "preset"))
    if not use or plant is None:
        return given
    try:
        base = default_limits(plant, preset)
    except ValueError:  # a plug-in's plant (docs/plugins.md) has no preset
        p.add(t.field("limits", "preset"), f"plant {quote(plant)} has no preset limits; give the limits themselves, "
                                           f"e.g. limits = {{ speed = 2.0 }}{t.note('limits', 'preset')}")
        return given
    pairs = {key: getattr(base, key) for key in LIMIT_KEYS if math.isfinite(getattr(base, key))}
    pairs.update(dict(given))
    return tuple(sorted(pairs.items()))


def _disturbance(p: Problems, t: _Merged, kind: str | None) -> tuple[tuple[str, Any], ...]:
    dt = p.table(t.v.get("disturbance", {}), t.field("disturbance"), "disturbance = { gust = 0.1 }",
                 t.note("disturbance")) or {}
    p.unknown_keys(dt, DISTURBANCE_KEYS, t.field("disturbance"))
    out: dict[str, Any] = {}
    if "constant" in dt and kind is not None:
        out["constant"] = p.vector(dt["constant"], t.field("disturbance", "constant"), DIMENSIONS[kind],
                                   f"a {kind} current/wind in m/s, one per axis", t.note("disturbance", "constant"),
                                   "disturbance.constant")
    if "gust" in dt:
        out["gust"] = p.number(dt["gust"], t.field("disturbance", "gust"), "disturbance.gust", unit=" m/s (std)",
                               note=t.note("disturbance", "gust"))
    if "gust_tau" in dt:
        out["gust_tau"] = p.number(dt["gust_tau"], t.field("disturbance", "gust_tau"), "disturbance.gust_tau", unit=" s",
                                   note=t.note("disturbance", "gust_tau"))
    return tuple(sorted((k, x) for k, x in out.items() if x is not None))


# --------------------------------------------------------------------------- gains against the rates


def gain_bounds(p: Problems, raw: Any, defaults: Mapping, fleet_gains: Mapping, specs: Sequence[VehicleSpec | None], rates: Rates,
                edges: Sequence[Edge]) -> None:
    """Each vehicle's k, c and regulator gains against what the discrete controller takes at
    the scenario's rates (cdus.core.gain_bounds: k·T < 2, c·Σa_ik·T < 1, b·h < 2). The field
    is the vehicle's, marked with the table the value came from."""
    weight_sums: dict[str, float] = {}
    for e in edges:
        weight_sums[e.i] = weight_sums.get(e.i, 0.0) + e.weight
    tables = raw if isinstance(raw, list) else []
    for spec in specs:
        if spec is None:
            continue
        label = f"vehicle[{spec.index}] (id {quote(spec.id)})"
        own = tables[spec.index].get("gains") if spec.index < len(tables) else None
        own = own if isinstance(own, dict) else {}
        dflt = defaults.get("gains") if isinstance(defaults.get("gains"), dict) else {}

        def origin(key: str) -> str:
            return ("" if key in own else " (set in [defaults])" if key in dflt
                    else " (set in [gains])" if key in fleet_gains else " (the default)")

        problem = gains_problem_for_rate(spec.k, None, rates.control, plant=spec.plant, physics_hz=rates.physics)
        if problem:
            p.add(f"{label}.gains.k", problem + origin("k"))
        problem = gains_problem_for_rate(None, spec.c, rates.control, weight_sum=weight_sums.get(spec.id, 0.0))
        if problem:
            p.add(f"{label}.gains.c", problem + origin("c"))
        problem = regulator_gains_problem(spec.regulator_gains, rates.physics)
        if problem:
            p.add(f"{label}.regulator_gains", problem)

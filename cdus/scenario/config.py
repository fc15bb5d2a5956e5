"""What is a scenario? The config schema: loading, defaults, validation, resolution.

The one source of truth for the scenario file (docs/config.md is its user reference).
``load_scenario`` reads a TOML file, applies ``--set`` overrides, merges ``[defaults]``
under every ``[[vehicle]]``, validates everything (collecting every problem, not just
the first), draws the seeded random starts and returns a frozen :class:`Scenario`.
A bad config raises :class:`ConfigError`, one line per problem, each naming the file,
the field and what would be valid. Nothing here starts anything; the only I/O is
reading the file.
"""

from __future__ import annotations

import copy
import json
import difflib
import math
import os
import random
import re
import tomllib
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

from cdus.core import graph as graphs
from cdus.scenario.errors import ConfigError
from cdus.scenario.link import validate_link
from cdus.scenario.show import quote as _q, show as _show
from cdus.scenario.events import validate_events
from cdus.core.paths import FAMILIES, PathError, for_dimension, make_path
from cdus.core.plants import USV_PRESETS

# --------------------------------------------------------------------------- schema

KINDS: dict[str, int] = {"usv": 2, "uav": 3}  # kind -> dimension
PLANTS: dict[str, tuple[str, ...]] = {  # plant -> kinds it models
    "ideal": ("usv", "uav"),
    "usv_3dof": ("usv",),
    "uav_double_integrator": ("uav",),
}
#: usv_3dof parameter presets ε1..ε7 (dgvf.md §3; a CyberShip II-like 3-DOF model).
PRESETS: dict[str, tuple[float, ...]] = USV_PRESETS
DEFAULT_PRESET = "cybership2"
#: plant -> regulator -> allowed regulator_gains keys; the first regulator is the default.
REGULATORS: dict[str, dict[str, tuple[str, ...]]] = {
    "usv_3dof": {"heading": ("b_u", "b_r", "k_psi"), "paper": ("b1", "b2", "b3")},
    "uav_double_integrator": {"pd": ("b", "k_v")},
}
TOPOLOGIES = graphs.TOPOLOGIES
LIMIT_KEYS = ("speed", "accel", "tau_u", "tau_r", "yaw_rate")

DEFAULT_DURATION = 60.0
DEFAULT_SEED = 0
DEFAULT_RATES = {"physics": 200.0, "control": 50.0, "broadcast": 50.0}
DEFAULT_METRICS = {"path_tol": 0.1, "coord_tol": 0.05}
DEFAULT_GAINS = {"k": 1.5, "c": 2.0}  # the paper's
DEFAULT_WEIGHT = 1.0

SECTIONS = ("scenario", "rates", "metrics", "gains", "defaults", "graph", "link", "event", "vehicle")
SCENARIO_KEYS = ("name", "description", "duration", "seed")
GRAPH_KEYS = ("topology", "directed", "weight", "hub", "edges", "edge")
EDGE_KEYS = ("i", "k", "weight", "delta")
VEHICLE_KEYS = ("id", "kind", "plant", "preset", "epsilon", "regulator", "regulator_gains", "phase",
                "path", "start", "omega0", "gains", "limits", "disturbance")
TABLE_KEYS = ("path", "start", "gains", "regulator_gains", "limits", "disturbance")
START_KEYS = ("position", "heading", "region_min", "region_max")
DISTURBANCE_KEYS = ("constant", "gust", "gust_tau")
ID_PATTERN = re.compile(r"[A-Za-z0-9_-]{1,32}")


# --------------------------------------------------------------------------- result


@dataclass(frozen=True)
class Rates:
    physics: float  # Hz
    control: float
    broadcast: float


@dataclass(frozen=True)
class Edge:
    """i listens to k with weight a_ik; the coordination error of this edge is |ω_i - ω_k - delta|."""

    i: str
    k: str
    weight: float
    delta: float


@dataclass(frozen=True)
class VehicleSpec:
    id: str
    index: int  # position in Scenario.vehicles
    kind: str  # usv | uav
    dim: int  # 2 | 3
    plant: str  # ideal | usv_3dof | uav_double_integrator
    epsilon: tuple[float, ...] | None  # ε1..ε7 for usv_3dof, else None
    preset: str | None  # the preset ε came from, None if given as epsilon or not usv_3dof
    regulator: str | None  # None for the ideal plant
    regulator_gains: tuple[tuple[str, float], ...]  # sorted; empty = the regulator's defaults
    path: tuple[tuple[str, Any], ...]  # sorted pairs, lists as tuples: make_path(dict(v.path))
    phase: float  # θ_i, ω units
    start_position: tuple[float, ...] | None  # None = start on the path
    start_heading: float | None  # None = along the path (always None for a UAV)
    omega0: float | None  # None = the ω of the path point nearest the start
    k: tuple[float, ...]  # per-axis path gain, length dim
    c: float  # coordination gain
    limits: tuple[tuple[str, float], ...]
    disturbance: tuple[tuple[str, Any], ...]


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    source: str
    duration: float
    seed: int
    rates: Rates
    path_tol: float
    coord_tol: float
    topology: str
    directed: bool
    vehicles: tuple[VehicleSpec, ...]
    edges: tuple[Edge, ...]  # every listening pair; undirected gives (i, k) and (k, i), Δ_ki = -Δ_ik
    link: dict
    events: tuple[dict, ...]
    raw: dict  # the overridden TOML data; parse_scenario(raw) rebuilds this scenario

    def vehicle(self, vid: str) -> VehicleSpec:
        for v in self.vehicles:
            if v.id == vid:
                return v
        raise KeyError(f"no vehicle {vid!r} in scenario {self.name!r}; ids are {', '.join(self.ids)}")

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(v.id for v in self.vehicles)

    def neighbours(self, vid: str) -> tuple[Edge, ...]:
        """The edges vehicle ``vid`` listens on (e.i == vid)."""
        return tuple(e for e in self.edges if e.i == vid)

    def metric_edges(self) -> tuple[Edge, ...]:
        """Edges to measure coordination on: undirected, each pair once as index(i) < index(k)."""
        if self.directed:
            return self.edges
        index = {v.id: v.index for v in self.vehicles}
        return tuple(e for e in self.edges if index[e.i] < index[e.k])


# --------------------------------------------------------------------------- entry points


def load_scenario(path: str | os.PathLike, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Read, override, validate and resolve a scenario file. Raises :class:`ConfigError`."""
    source = os.fspath(path)
    try:
        with open(source, "rb") as fh:
            if source.endswith(".json"):  # a resolved scenario (Scenario.raw) handed to a subprocess
                data = json.load(fh)
            else:
                data = tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(source, [("file", "not found; give the path of a scenario .toml file "
                                            "(see configs/ for examples)")]) from None
    except OSError as e:
        raise ConfigError(source, [("file", f"cannot be read: {e.strerror or e}")]) from None
    except UnicodeDecodeError:
        raise ConfigError(source, [("file", "is not UTF-8 text; a scenario is a TOML file")]) from None
    except json.JSONDecodeError as e:
        raise ConfigError(source, [(f"line {e.lineno}, column {e.colno}", f"JSON syntax error: {e.msg}")]) from None
    except tomllib.TOMLDecodeError as e:
        text = str(e)
        m = re.search(r"\(at line (\d+), column (\d+)\)", text)
        where = f"line {m.group(1)}, column {m.group(2)}" if m else "TOML"
        message = text[:m.start()].strip() if m else text
        raise ConfigError(source, [(where, f"TOML syntax error: {message}")]) from None
    return parse_scenario(data, source, overrides)


def parse_scenario(data: Mapping[str, Any], source: str = "<config>",
                   overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Validate and resolve already-parsed TOML data (``data`` is not modified)."""
    data = copy.deepcopy(dict(data))
    for key, value in (overrides or {}).items():
        try:
            apply_override(data, key, value)
        except ConfigError as e:
            raise ConfigError(source, e.problems) from None
    check = _Check()
    scenario = _resolve(data, source, check)
    if check.problems:
        raise ConfigError(source, check.problems)
    assert scenario is not None
    return scenario


def apply_override(data: dict, dotted_key: str, value: Any) -> None:
    """Set ``data[a][b]... = value`` for ``"a.b..."``, creating missing tables.

    ``vehicle.<id>.<key...>`` addresses the [[vehicle]] with that id. Raises
    :class:`ConfigError` for an unknown vehicle id or a path through a non-table.
    """
    parts = dotted_key.split(".") if isinstance(dotted_key, str) else [""]
    field = f"override {dotted_key}"

    def fail(message: str):
        raise ConfigError("--set", [(field, message)])

    if any(p == "" for p in parts):
        fail("not a dotted key; write e.g. scenario.seed, rates.control or vehicle.usv1.gains.k")
    node: Any = data
    if parts[0] == "vehicle":
        if len(parts) < 3:
            fail("address a vehicle's key as vehicle.<id>.<key>, e.g. vehicle.usv1.gains.k")
        vehicles = data.get("vehicle")
        vehicles = vehicles if isinstance(vehicles, list) else []
        ids = [v.get("id") for v in vehicles if isinstance(v, dict) and isinstance(v.get("id"), str)]
        match = [v for v in vehicles if isinstance(v, dict) and v.get("id") == parts[1]]
        if not match:
            fail(f"no vehicle with id {_q(parts[1])}{_did_you_mean(parts[1], ids)}; "
                 f"ids are {', '.join(ids) or '(none)'}")
        node, parts, done = match[0], parts[2:], ["vehicle", parts[1]]
    else:
        done = []
    for p in parts[:-1]:
        done.append(p)
        nxt = node.get(p)
        if nxt is None:
            nxt = node[p] = {}
        elif not isinstance(nxt, dict):
            fail(f"{'.'.join(done)} is {_describe(nxt)}, not a table, so it has no key {_q(parts[-1])}")
        node = nxt
    node[parts[-1]] = value


def parse_overrides(items: Iterable[str], source: str = "command line") -> dict[str, Any]:
    """``["rates.control=20", "link.loss=0.3"]`` (the ``--set`` flags) -> {dotted key: value}."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise ConfigError(source, [("--set", f"expected KEY=VALUE (e.g. rates.control=20), got {item!r}")])
        out[key.strip()] = parse_value(value.strip())
    return out


def parse_value(text: str) -> Any:
    """A ``--set key=value`` value: TOML scalar or inline value (int, float, bool, [1, 2],
    {a = 1}, "quoted"), else the text itself as a string."""
    stripped = text.strip()
    if stripped in ("True", "False"):
        return stripped == "True"
    try:
        value = tomllib.loads(f"v = {stripped}")["v"]
    except tomllib.TOMLDecodeError:
        return text
    if isinstance(value, (int, float, bool, str, list, dict)):
        return value
    return text  # TOML dates and times: keep the text


# --------------------------------------------------------------------------- problems


class _Check:
    """Collects (field, message) problems, each once."""

    def __init__(self) -> None:
        self.problems: list[tuple[str, str]] = []

    def add(self, field: str, message: str) -> None:
        if (field, message) not in self.problems:
            self.problems.append((field, message))


def _describe(v: Any) -> str:
    if isinstance(v, bool):
        return f"the boolean {_show(v)}"
    if isinstance(v, str):
        return f"the string {_show(v)}"
    if isinstance(v, (int, float)):
        return f"the number {_show(v)}"
    if isinstance(v, list):
        return f"the list {_show(v)}"
    if isinstance(v, dict):
        return f"the table {_show(v)}"
    return repr(v)


def _num(x: float) -> str:
    return f"{x:g}"


def _did_you_mean(word: str, options: Iterable[str]) -> str:
    close = difflib.get_close_matches(str(word), list(options), n=1, cutoff=0.6)
    return f' (did you mean {_q(close[0])}?)' if close else ""


def _choose(value: Any, options: Iterable[str]) -> str:
    options = list(options)
    return f"{_did_you_mean(value, options)}; choose one of {', '.join(options)}"


def _unknown_keys(check: _Check, table: Mapping, allowed: Iterable[str], prefix: str,
                  what: str = "key", valid: str | None = None, skip: Iterable[str] = ()) -> None:
    allowed = list(allowed)
    for key in table:
        if key not in allowed and key not in skip:
            close = difflib.get_close_matches(str(key), allowed, n=1, cutoff=0.6)
            hint = f'did you mean {_q(close[0])}? ' if close else ""
            check.add(_join(prefix, key), f"unknown {what}; {hint}{valid or f'valid {what}s here'}: "
                                          f"{', '.join(allowed)}")


def _join(prefix: str, key: Any) -> str:
    return f"{prefix}.{key}" if prefix else str(key)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _number(check: _Check, v: Any, field: str, *, gt: float | None = None, ge: float | None = None,
            unit: str = "", note: str = "") -> float | None:
    """A finite number with an optional bound, or None after reporting the problem."""
    bound = f" > {_num(gt)}" if gt is not None else f" >= {_num(ge)}" if ge is not None else ""
    if not _is_number(v):
        check.add(field, f"must be a number{bound}{unit}, got {_describe(v)}{note}")
        return None
    if not math.isfinite(v):
        check.add(field, f"must be a finite number{bound}{unit}, got {_show(v)}{note}")
        return None
    if (gt is not None and not v > gt) or (ge is not None and not v >= ge):
        check.add(field, f"must be{bound}{unit}, got {_show(v)}{note}")
        return None
    return float(v)


def _vector(check: _Check, v: Any, field: str, dim: int, what: str, note: str = "") -> tuple[float, ...] | None:
    if not isinstance(v, list) or len(v) != dim or not all(_is_number(x) and math.isfinite(x) for x in v):
        if isinstance(v, list) and all(_is_number(x) for x in v):
            got = f"{len(v)} numbers {_show(v)}"
        else:
            got = _describe(v)
        check.add(field, f"must be a list of {dim} numbers ({what}), got {got}{note}")
        return None
    return tuple(float(x) for x in v)


def _table(check: _Check, data: Mapping, key: str, field: str, note: str = "") -> dict:
    v = data.get(key, {})
    if not isinstance(v, dict):
        check.add(field, f"must be a table (e.g. {key} = {{ ... }} or a [{key}] section), got {_describe(v)}{note}")
        return {}
    return v


def _frozen(v: Any) -> Any:
    """Lists -> tuples, tables -> sorted pairs, recursively (hashable)."""
    if isinstance(v, list):
        return tuple(_frozen(x) for x in v)
    if isinstance(v, dict):
        return tuple(sorted((k, _frozen(x)) for k, x in v.items()))
    return v


def _pi_text(x: float) -> str | None:
    """x as a simple multiple of π ("2π", "-2π/3"), or None."""
    r = x / math.pi
    for q in (1, 2, 3, 4, 6, 8, 12):
        p = round(r * q)
        if p != 0 and abs(r * q - p) < 1e-6:
            g = math.gcd(p, q)
            p, q = p // g, q // g
            num = {1: "", -1: "-"}.get(p, str(p))
            return f"{num}π{'' if q == 1 else f'/{q}'}"
    return None


def _angle(x: float) -> str:
    """A number, followed by its value as a multiple of π when it is a simple one."""
    pi = _pi_text(x)
    return f"{x:.6g}" + (f" ({pi})" if pi else "")


# --------------------------------------------------------------------------- resolution


def _resolve(data: dict, source: str, check: _Check) -> Scenario | None:
    _unknown_keys(check, data, SECTIONS, "", what="section")

    # [scenario]
    sc = _table(check, data, "scenario", "scenario")
    _unknown_keys(check, sc, SCENARIO_KEYS, "scenario")
    name = sc.get("name")
    if "name" not in sc:
        check.add("scenario.name", 'missing; every scenario needs a name, e.g. [scenario] name = "lake_circle"')
    elif not isinstance(name, str) or not name.strip():
        check.add("scenario.name", f"must be a non-empty string, got {_describe(name)}")
    description = sc.get("description", "")
    if not isinstance(description, str):
        check.add("scenario.description", f"must be a string, got {_describe(description)}")
        description = ""
    duration = DEFAULT_DURATION
    if "duration" in sc:
        duration = _number(check, sc["duration"], "scenario.duration", gt=0, unit=" s") or DEFAULT_DURATION
    seed = sc.get("seed", DEFAULT_SEED)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        check.add("scenario.seed", f"must be an integer >= 0, got {_describe(seed)}")
        seed = DEFAULT_SEED

    # [rates]
    rt = _table(check, data, "rates", "rates")
    _unknown_keys(check, rt, tuple(DEFAULT_RATES), "rates")
    rates = dict(DEFAULT_RATES)
    ok = True
    for key in DEFAULT_RATES:
        if key in rt:
            v = _number(check, rt[key], f"rates.{key}", gt=0, unit=" Hz")
            ok = ok and v is not None
            rates[key] = v if v is not None else rates[key]
    # unset rates follow the control rate: broadcast once per control step, physics at least that often
    if "broadcast" not in rt:
        rates["broadcast"] = rates["control"]
    if "physics" not in rt:
        rates["physics"] = max(rates["physics"], rates["control"])
    if ok:
        if rates["physics"] < rates["control"]:
            check.add("rates.physics", f"must be >= rates.control ({_num(rates['control'])} Hz): the plant steps "
                                       f"at least once per control period; got {_num(rates['physics'])}")
        if rates["broadcast"] > rates["control"]:
            check.add("rates.broadcast", f"must be <= rates.control ({_num(rates['control'])} Hz): a vehicle has "
                                         f"a new ω at most once per control step; got {_num(rates['broadcast'])}")

    # [metrics]
    mt = _table(check, data, "metrics", "metrics")
    _unknown_keys(check, mt, tuple(DEFAULT_METRICS), "metrics")
    metrics = dict(DEFAULT_METRICS)
    for key, unit in (("path_tol", " m"), ("coord_tol", " rad")):
        if key in mt:
            metrics[key] = _number(check, mt[key], f"metrics.{key}", gt=0, unit=unit) or metrics[key]

    # [gains]: checked here, per-axis length checked per vehicle
    fleet_gains = _table(check, data, "gains", "gains")
    _unknown_keys(check, fleet_gains, tuple(DEFAULT_GAINS), "gains")
    _check_gain_values(check, fleet_gains, "gains")

    # [defaults]
    defaults = _table(check, data, "defaults", "defaults")
    _check_defaults(check, defaults)
    defaults = {k: v for k, v in defaults.items()
                if k in VEHICLE_KEYS and k != "id" and (k not in TABLE_KEYS or isinstance(v, dict))}

    # [link], [[event]]: checked below, once the vehicle ids are known
    link = _table(check, data, "link", "link")
    events_raw = data.get("event", [])
    events: tuple[dict, ...] = ()
    if not isinstance(events_raw, list) or not all(isinstance(e, dict) for e in events_raw):
        check.add("event", f"must be an array of tables ([[event]] sections), got {_describe(events_raw)}")
    else:
        events = tuple(events_raw)

    # [[vehicle]]
    vehicles_raw = data.get("vehicle")
    vehicles: list[VehicleSpec | None] = []
    paths: dict[str, Any] = {}
    ids: list[str | None] = []
    if vehicles_raw is None or vehicles_raw == []:
        check.add("vehicle", 'no vehicles; add at least one [[vehicle]] table with id, kind and path')
    elif not isinstance(vehicles_raw, list) or not all(isinstance(v, dict) for v in vehicles_raw):
        check.add("vehicle", f"must be an array of tables ([[vehicle]] sections, not [vehicle]), "
                             f"got {_describe(vehicles_raw)}")
    else:
        first_index: dict[str, int] = {}
        for index, raw_vehicle in enumerate(vehicles_raw):
            vid = _vehicle_id(check, raw_vehicle, index, first_index)
            ids.append(vid)
            spec, path = _vehicle(check, raw_vehicle, index, vid, defaults, fleet_gains, seed)
            vehicles.append(spec)
            if vid is not None and path is not None:
                paths[vid] = path

    # [graph]
    gr = _table(check, data, "graph", "graph")
    topology, directed, edges = _graph(check, gr, ids, vehicles, paths)

    # [link] (the fault model) and [[event]] (scheduled vehicle faults) need the ids
    if link is not None and all(isinstance(i, str) for i in ids) and ids:
        try:
            validate_link(link, ids, source)
        except ConfigError as e:
            for field_, message in e.problems:
                check.add(field_, message)
        _, event_problems = validate_events(events, [i for i in ids if i])
        for field_, message in event_problems:
            check.add(field_, message)

    if check.problems:
        return None
    return Scenario(
        name=name, description=description, source=source, duration=duration, seed=seed,
        rates=Rates(**rates), path_tol=metrics["path_tol"], coord_tol=metrics["coord_tol"],
        topology=topology, directed=directed, vehicles=tuple(vehicles), edges=edges,
        link=copy.deepcopy(link), events=copy.deepcopy(events), raw=data,
    )


def _check_gain_values(check: _Check, gains: Mapping, prefix: str, note: str = "") -> None:
    if "k" in gains:
        k = gains["k"]
        if isinstance(k, list):
            if not k:
                check.add(f"{prefix}.k", f"must be a number > 0 or a list of per-axis numbers > 0, got []{note}")
            for j, x in enumerate(k):
                _number(check, x, f"{prefix}.k[{j}]", gt=0, note=note)
        else:
            _number(check, k, f"{prefix}.k", gt=0, note=note + " (or a list of per-axis values)"
                    if not _is_number(k) else note)
    if "c" in gains:
        _number(check, gains["c"], f"{prefix}.c", gt=0, note=note)


def _check_defaults(check: _Check, defaults: Mapping) -> None:
    """What can be checked in [defaults] without a vehicle: keys, table shapes, names."""
    if "id" in defaults:
        check.add("defaults.id", "an id cannot be a default; give every [[vehicle]] its own id")
    _unknown_keys(check, defaults, [k for k in VEHICLE_KEYS if k != "id"], "defaults", skip=("id",))
    for key in TABLE_KEYS:
        if key in defaults and not isinstance(defaults[key], dict):
            check.add(f"defaults.{key}", f"must be a table, e.g. {key} = {{ ... }}, got {_describe(defaults[key])}")
    # names that are skipped for vehicles they do not apply to must at least exist somewhere
    if "preset" in defaults and defaults["preset"] not in PRESETS:
        preset = defaults["preset"]
        check.add("defaults.preset", f"unknown preset {_show(preset)}{_choose(preset, PRESETS)}")
    all_regulators = {r: p for p, regs in REGULATORS.items() for r in regs}
    if "regulator" in defaults and defaults["regulator"] not in all_regulators:
        check.add("defaults.regulator", f"unknown regulator {_show(defaults['regulator'])}"
                                        f"{_choose(defaults['regulator'], all_regulators)}")
    if isinstance(defaults.get("regulator_gains"), dict):
        all_gains = sorted({g for regs in REGULATORS.values() for keys in regs.values() for g in keys})
        _unknown_keys(check, defaults["regulator_gains"], all_gains, "defaults.regulator_gains")


def _vehicle_label(index: int, vid: str | None) -> str:
    return f"vehicle[{index}]" + (f" (id {_q(vid)})" if vid is not None else "")


def _vehicle_id(check: _Check, raw: Mapping, index: int, first_index: dict[str, int]) -> str | None:
    """The vehicle's id if valid and unique, else None (after reporting)."""
    label = f"vehicle[{index}]"
    if "id" not in raw:
        check.add(f"{label}.id", 'missing; every vehicle needs a unique id, e.g. id = "usv1"')
        return None
    vid = raw["id"]
    if not isinstance(vid, str):
        check.add(f"{label}.id", f"must be a string of 1-32 letters, digits, _ or -, got {_describe(vid)}")
        return None
    if not ID_PATTERN.fullmatch(vid):
        check.add(f"{label}.id", f"{_show(vid)} is not a valid id: use 1-32 characters from A-Z a-z 0-9 _ - "
                                 f"(it names the vehicle's process and keys)")
        return None
    if vid in first_index:
        check.add(f"{label}.id", f"duplicate id {_q(vid)} (also vehicle[{first_index[vid]}]); ids must be unique")
        return None
    first_index[vid] = index
    return vid


def _merge(defaults: Mapping, vehicle: Mapping) -> tuple[dict, set[tuple[str, ...]]]:
    """[defaults] under a vehicle: the vehicle wins; tables merge one level deep.

    Where the two give alternatives, the vehicle's choice replaces the default's: epsilon
    vs preset, start.position vs start.region_min/max, and a path of another family.
    Returns the merged table and the set of (key,) / (key, subkey) taken from [defaults].
    """
    merged: dict = {}
    origin: set[tuple[str, ...]] = set()
    for key, dv in defaults.items():
        merged[key] = copy.deepcopy(dv)
        origin.add((key,))
        if isinstance(dv, dict):
            origin |= {(key, sub) for sub in dv}
    alternatives = {"preset": "epsilon", "epsilon": "preset"}
    for key, vv in vehicle.items():
        if key in alternatives and alternatives[key] in merged and (alternatives[key],) in origin:
            del merged[alternatives[key]]
            origin = {o for o in origin if o[0] != alternatives[key]}
        base = merged.get(key)
        if key in TABLE_KEYS and isinstance(vv, dict) and isinstance(base, dict):
            base = dict(base)
            if key == "start" and ("position" in vv or "region_min" in vv or "region_max" in vv):
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


def _vehicle(check: _Check, raw: Mapping, index: int, vid: str | None, defaults: Mapping,
             fleet_gains: Mapping, seed: int) -> tuple[VehicleSpec | None, Any]:
    """Validate one [[vehicle]] (merged with [defaults]); returns (spec or None, path or None)."""
    label = _vehicle_label(index, vid)
    problems_before = len(check.problems)
    _unknown_keys(check, raw, VEHICLE_KEYS, label)
    v, origin = _merge(defaults, raw)

    def note(*key: str) -> str:
        return " (set in [defaults])" if key in origin else ""

    def field(*parts: Any) -> str:
        return label + "".join(f".{p}" for p in parts)

    # kind, plant
    kind = v.get("kind")
    dim: int | None = None
    if "kind" not in v:
        check.add(field("kind"), 'missing; choose "usv" (boat, 2-D) or "uav" (drone, 3-D)')
    elif kind not in KINDS:
        check.add(field("kind"), f"unknown kind {_show(kind)}{note('kind')}{_choose(kind, KINDS)}")
        kind = None
    else:
        dim = KINDS[kind]
    plant = v.get("plant", "ideal")
    if plant not in PLANTS:
        check.add(field("plant"), f"unknown plant {_show(plant)}{note('plant')}{_choose(plant, PLANTS)}")
        plant = None
    elif kind is not None and kind not in PLANTS[plant]:
        valid = [p for p, kinds in PLANTS.items() if kind in kinds]
        check.add(field("plant"), f"plant {_q(plant)} models a {' or '.join(PLANTS[plant])}, not a {kind}"
                                  f"{note('plant')}; a {kind} takes plant = {' or '.join(map(_q, valid))}")
        plant = None

    # a [defaults] key that does not apply to this vehicle's plant is skipped
    if plant is not None:
        regs = REGULATORS.get(plant, {})
        for key in ("preset", "epsilon"):
            if plant != "usv_3dof" and (key,) in origin:
                v.pop(key, None)
        if ("regulator",) in origin and v.get("regulator") not in regs:
            v.pop("regulator", None)
        if ("regulator_gains",) in origin and not regs:
            v.pop("regulator_gains", None)
    if kind == "uav" and ("start", "heading") in origin:
        v["start"] = {k: x for k, x in v["start"].items() if k != "heading"}

    # ε: preset or epsilon
    epsilon: tuple[float, ...] | None = None
    preset: str | None = None
    if plant == "usv_3dof":
        if "preset" in v and "epsilon" in v:
            check.add(field("epsilon"), "give either preset or epsilon, not both")
        elif "epsilon" in v:
            eps = v["epsilon"]
            if not isinstance(eps, list) or len(eps) != 7 or not all(_is_number(x) and math.isfinite(x) for x in eps):
                check.add(field("epsilon"), f"must be a list of 7 numbers ε1..ε7, "
                                            f"got {_describe(eps)}{note('epsilon')}")
            elif eps[2] == 0 or eps[4] == 0:
                check.add(field("epsilon"), f"ε3 and ε5 must be non-zero (they scale the inputs τ_u and τ_r: "
                                            f"ε3 = 1/m11, ε5 = 1/m33), got {_show(eps)}{note('epsilon')}")
            else:
                epsilon = tuple(float(x) for x in eps)
        else:
            preset = v.get("preset", DEFAULT_PRESET)
            if preset not in PRESETS:
                check.add(field("preset"), f"unknown preset {_show(preset)}{note('preset')}{_choose(preset, PRESETS)}"
                                           f" (or give epsilon = [ε1, ..., ε7])")
                preset = None
            else:
                epsilon = PRESETS[preset]
    elif plant is not None:
        for key in ("preset", "epsilon"):
            if key in v:
                check.add(field(key), f'only used by plant = "usv_3dof" (this vehicle\'s plant is {_q(plant)}); '
                                      f"remove it")

    # regulator
    regulator: str | None = None
    regulator_gains: tuple[tuple[str, float], ...] = ()
    if plant == "ideal":
        for key in ("regulator", "regulator_gains"):
            if key in v:
                check.add(field(key), 'the ideal plant has no regulator; remove it, or choose plant = '
                                      '"usv_3dof" (usv) or "uav_double_integrator" (uav)')
    elif plant is not None:
        regs = REGULATORS[plant]
        regulator = v.get("regulator", next(iter(regs)))
        if regulator not in regs:
            all_regs = {r for rs in REGULATORS.values() for r in rs}
            if regulator in all_regs:
                msg = f"regulator {_q(regulator)} is not one for plant {_q(plant)}"
            else:
                msg = f"unknown regulator {_show(regulator)}{_did_you_mean(regulator, regs)}"
            check.add(field("regulator"), f"{msg}{note('regulator')}; plant {_q(plant)} takes regulator = "
                                          f"{' or '.join(map(_q, regs))}")
            regulator = None
        rg = _table(check, v, "regulator_gains", field("regulator_gains"), note("regulator_gains"))
        if regulator is not None:
            allowed = regs[regulator]
            if ("regulator_gains",) in origin or any(("regulator_gains", g) in origin for g in rg):
                rg = {g: x for g, x in rg.items() if g in allowed or ("regulator_gains", g) not in origin}
            _unknown_keys(check, rg, allowed, field("regulator_gains"), what="regulator gain",
                          valid=f"the {regulator} regulator takes")
            regulator_gains = _positive_pairs(check, rg, allowed, "regulator_gains", field, note)

    # phase
    phase = 0.0
    if "phase" in v:
        phase = _number(check, v["phase"], field("phase"), unit=" (θ_i, in ω units)", note=note("phase"))
        phase = 0.0 if phase is None else phase

    # path
    path_obj = None
    path_pairs: tuple = ()
    if "path" not in v:
        check.add(field("path"), f'missing; e.g. path = {{ family = "circle", center = [0, 0], radius = 10 }}; '
                                 f"families: {', '.join(FAMILIES)}")
    elif not isinstance(v["path"], dict):
        check.add(field("path"), f'must be a table, e.g. {{ family = "circle", center = [0, 0], radius = 10 }}, '
                                 f"got {_describe(v['path'])}")
    else:
        spec = v["path"]
        try:
            built = make_path(spec)
            path_obj = for_dimension(built, dim) if dim is not None else None
            path_pairs = _frozen(spec)
        except PathError as e:
            sub = () if e.field == "path" else (e.field,)
            where = field("path", *sub)
            src = note("path", *sub) if sub else note("path")
            if e.field == "family" and "family" in spec:
                fam = spec["family"]
                check.add(where, f"unknown path family {_show(fam)}{src}{_choose(fam, FAMILIES)}")
            else:
                check.add(where, f"{e.message}{src}")
        except (TypeError, ValueError) as e:  # a malformed value the path module did not anticipate
            check.add(field("path"), f"invalid path: {e}{note('path')}")

    # start, omega0
    start_position, start_heading = _start(check, v, kind, dim, field, note, seed, vid)
    omega0: float | None = None
    if "omega0" in v and v["omega0"] != "nearest":
        omega0 = _number(check, v["omega0"], field("omega0"), note=note("omega0") +
                         ' (or "nearest": the ω of the path point nearest the start)')

    # gains: built-in < [gains] < [defaults].gains < vehicle gains
    vg = _table(check, v, "gains", field("gains"), note("gains"))
    _unknown_keys(check, vg, tuple(DEFAULT_GAINS), field("gains"))
    _check_gain_values(check, vg, field("gains"), note("gains"))
    k_raw, k_where = (vg["k"], ("gains", "k")) if "k" in vg else (fleet_gains.get("k", DEFAULT_GAINS["k"]), None)
    c_raw = vg.get("c", fleet_gains.get("c", DEFAULT_GAINS["c"]))
    k: tuple[float, ...] = ()
    if isinstance(k_raw, list) and dim is not None and len(k_raw) != dim:
        src = note(*k_where) if k_where else " (set in [gains])"
        check.add(field("gains", "k"), f"a list of per-axis gains needs {dim} values for a {kind} "
                                       f"({'x, y' if dim == 2 else 'x, y, z'}), got {len(k_raw)}: {_show(k_raw)}{src}")
    elif dim is not None:
        if isinstance(k_raw, list) and all(_is_number(x) and x > 0 for x in k_raw):
            k = tuple(float(x) for x in k_raw)
        elif _is_number(k_raw) and k_raw > 0:
            k = (float(k_raw),) * dim
    c = float(c_raw) if _is_number(c_raw) else DEFAULT_GAINS["c"]

    # limits
    lt = _table(check, v, "limits", field("limits"), note("limits"))
    _unknown_keys(check, lt, LIMIT_KEYS, field("limits"))
    limits = _positive_pairs(check, lt, LIMIT_KEYS, "limits", field, note)

    # disturbance
    dt = _table(check, v, "disturbance", field("disturbance"), note("disturbance"))
    _unknown_keys(check, dt, DISTURBANCE_KEYS, field("disturbance"))
    disturbance = {}
    if "constant" in dt and dim is not None:
        const = _vector(check, dt["constant"], field("disturbance", "constant"), dim,
                        f"a {kind} current/wind in m/s, one per axis", note("disturbance", "constant"))
        if const is not None:
            disturbance["constant"] = const
    if "gust" in dt:
        x = _number(check, dt["gust"], field("disturbance", "gust"), ge=0, unit=" m/s (std)",
                    note=note("disturbance", "gust"))
        if x is not None:
            disturbance["gust"] = x
    if "gust_tau" in dt:
        x = _number(check, dt["gust_tau"], field("disturbance", "gust_tau"), gt=0, unit=" s",
                    note=note("disturbance", "gust_tau"))
        if x is not None:
            disturbance["gust_tau"] = x

    if len(check.problems) > problems_before or vid is None or kind is None or plant is None:
        return None, path_obj
    return VehicleSpec(
        id=vid, index=index, kind=kind, dim=dim, plant=plant, epsilon=epsilon, preset=preset,
        regulator=regulator, regulator_gains=regulator_gains, path=path_pairs, phase=phase,
        start_position=start_position, start_heading=start_heading, omega0=omega0, k=k, c=c,
        limits=tuple(limits), disturbance=tuple(sorted(disturbance.items())),
    ), path_obj


def _start(check: _Check, v: Mapping, kind: str | None, dim: int | None, field, note, seed: int,
           vid: str | None) -> tuple[tuple[float, ...] | None, float | None]:
    """(start_position, start_heading), drawing a region start with Random(f"{seed}/{id}")."""
    st = _table(check, v, "start", field("start"), note("start"))
    _unknown_keys(check, st, START_KEYS, field("start"))
    heading: float | None = None
    if "heading" in st:
        if kind == "uav":
            check.add(field("start", "heading"), "a uav has no heading; remove it (headings are for usv starts)")
        else:
            heading = _number(check, st["heading"], field("start", "heading"), unit=" (rad)",
                              note=note("start", "heading"))
    if dim is None:
        return None, None
    has_region = "region_min" in st or "region_max" in st
    if "position" in st and has_region:
        check.add(field("start"), "give either position or region_min/region_max, not both")
        return None, None
    if "position" in st:
        pos = _vector(check, st["position"], field("start", "position"), dim,
                      f"a {kind} position {'[x, y]' if dim == 2 else '[x, y, z]'} in m", note("start", "position"))
        if kind == "usv" and heading is None:
            heading = 0.0
        return pos, heading
    if has_region:
        lo_hi = []
        for key in ("region_min", "region_max"):
            if key not in st:
                other = "region_max" if key == "region_min" else "region_min"
                check.add(field("start", key), f"missing; a random start box needs both region_min and region_max "
                                               f"(only {other} is given)")
                return None, None
            lo_hi.append(_vector(check, st[key], field("start", key), dim, f"a {kind} box corner in m",
                                 note("start", key)))
        lo, hi = lo_hi
        if lo is None or hi is None:
            return None, None
        bad = [j for j in range(dim) if not lo[j] < hi[j]]
        if bad:
            axes = ", ".join("xyz"[j] for j in bad)
            check.add(field("start", "region_min"),
                      f"must be < region_max on every axis; not on {axes}: region_min = "
                      f"{_show(st['region_min'])}, region_max = {_show(st['region_max'])}")
            return None, None
        rng = random.Random(f"{seed}/{vid}")
        pos = tuple(a + (b - a) * rng.random() for a, b in zip(lo, hi))
        if kind == "usv" and heading is None:
            heading = -math.pi + 2.0 * math.pi * rng.random()
        return pos, heading
    return None, heading


# --------------------------------------------------------------------------- graph


def _graph(check: _Check, gr: Mapping, ids: list[str | None], vehicles: list[VehicleSpec | None],
           paths: Mapping[str, Any]) -> tuple[str, bool, tuple[Edge, ...]]:
    """Validate [graph] and build the edges: (topology, directed, edges)."""
    _unknown_keys(check, gr, GRAPH_KEYS, "graph")
    before = len(check.problems)
    topology = gr.get("topology", "ring")
    if topology not in TOPOLOGIES:
        check.add("graph.topology", f"unknown topology {_show(topology)}{_choose(topology, TOPOLOGIES)}")
        topology = "ring"
    directed = gr.get("directed", False)
    if not isinstance(directed, bool):
        check.add("graph.directed", f"must be true or false, got {_describe(directed)}")
        directed = False
    weight = DEFAULT_WEIGHT
    if "weight" in gr:
        weight = _number(check, gr["weight"], "graph.weight", gt=0, unit=" (a_ik)") or DEFAULT_WEIGHT

    known = [v for v in ids if v is not None]
    graph_ok = bool(ids) and len(known) == len(ids)  # every vehicle has a valid, unique id

    def vehicle_ref(value: Any, where: str) -> str | None:
        if not isinstance(value, str):
            check.add(where, f"must be a vehicle id (a string), got {_describe(value)}")
            return None
        if graph_ok and value not in known:
            check.add(where, f"{_q(value)} is not a vehicle{_did_you_mean(value, known)}; ids are {', '.join(known)}")
            return None
        return value

    hub = None
    if "hub" in gr:
        if topology != "star":
            check.add("graph.hub", f'only used with topology = "star" (topology is {_q(topology)}); remove it')
        elif not isinstance(gr["hub"], str):
            check.add("graph.hub", f"must be a vehicle id (a string), got {_describe(gr['hub'])}")
        elif graph_ok and gr["hub"] not in known:
            check.add("graph.hub", f"hub {_q(gr['hub'])} is not a vehicle{_did_you_mean(gr['hub'], known)}; "
                                   f"ids are {', '.join(known)}")
        else:
            hub = gr["hub"]

    explicit: list[tuple[str, str]] = []
    if "edges" in gr:
        edges_raw = gr["edges"]
        if topology != "explicit":
            check.add("graph.edges", f'only used with topology = "explicit" (topology is {_q(topology)}); set '
                                     f'topology = "explicit" to list the pairs yourself, or remove graph.edges '
                                     f"(use [[graph.edge]] tables to set the weight or delta of the "
                                     f"{topology}'s pairs)")
        elif not isinstance(edges_raw, list):
            check.add("graph.edges", f'must be a list of [i, k] pairs, e.g. [["usv1", "usv2"]], '
                                     f"got {_describe(edges_raw)}")
        else:
            for j, pair in enumerate(edges_raw):
                where = f"graph.edges[{j}]"
                if not isinstance(pair, list) or len(pair) != 2:
                    check.add(where, f'must be a pair [i, k] of vehicle ids (i listens to k), got {_describe(pair)}')
                    continue
                i, k = vehicle_ref(pair[0], where), vehicle_ref(pair[1], where)
                if i is not None and k is not None:
                    if i == k:
                        check.add(where, f"self-loop [{_q(i)}, {_q(k)}]: a vehicle cannot listen to itself")
                    else:
                        explicit.append((i, k))

    refinements: list[tuple[int, str, str, float | None, float | None]] = []
    edge_tables = gr.get("edge", [])
    if not isinstance(edge_tables, list) or not all(isinstance(e, dict) for e in edge_tables):
        check.add("graph.edge", f"must be an array of tables ([[graph.edge]] sections with i, k, weight, delta), "
                                f"got {_describe(edge_tables)}")
        edge_tables = []
    for j, et in enumerate(edge_tables):
        where = f"graph.edge[{j}]"
        _unknown_keys(check, et, EDGE_KEYS, where)
        missing = [key for key in ("i", "k") if key not in et]
        for key in missing:
            check.add(f"{where}.{key}", f"missing; a [[graph.edge]] names the pair with i (the listener) and k "
                                        f"(the vehicle it listens to)")
        if missing:
            continue
        i, k = vehicle_ref(et["i"], f"{where}.i"), vehicle_ref(et["k"], f"{where}.k")
        w = _number(check, et["weight"], f"{where}.weight", gt=0, unit=" (a_ik)") if "weight" in et else None
        d = _number(check, et["delta"], f"{where}.delta", unit=" (Δ_ik, the target of ω_i - ω_k)") \
            if "delta" in et else None
        if i is None or k is None:
            continue
        if i == k:
            check.add(where, f"self-loop i = k = {_q(i)}: a vehicle cannot listen to itself")
            continue
        refinements.append((j, i, k, w, d))
        if topology == "explicit":
            explicit.append((i, k))

    if not graph_ok or len(check.problems) > before:
        return topology, directed, ()

    # listening pairs
    if topology == "ring" and len(known) < 2:
        if "topology" in gr:
            check.add("graph.topology", f'a ring needs at least 2 vehicles, got {len(known)}; leave topology '
                                        f'unset or use "complete" for a single vehicle')
            return topology, directed, ()
        pairs: list[tuple[str, str]] = []
    else:
        pairs = graphs.build_pairs(topology, known, directed, hub=hub, explicit=explicit)
    pair_set = set(pairs)

    # per-pair weight and Δ (default θ_i - θ_k), refined by [[graph.edge]]
    phase = {v.id: v.phase for v in vehicles if v is not None}
    weights = {p: weight for p in pairs}
    deltas = {p: phase.get(p[0], 0.0) - phase.get(p[1], 0.0) for p in pairs}
    set_by: dict[tuple[str, str], int] = {}
    kind_text = f"{'directed' if directed else 'undirected'} {topology}"
    for j, i, k, w, d in refinements:
        where = f"graph.edge[{j}]"
        if (i, k) not in pair_set:
            listens = [b for a, b in pairs if a == i]
            check.add(where, f"{i} does not listen to {k} in this {kind_text} ({i} listens to "
                             f"{', '.join(listens) or 'nobody'}); a [[graph.edge]] can only refine an existing pair "
                             f'unless topology = "explicit"')
            continue
        key = (i, k) if directed else tuple(sorted((i, k), key=known.index))
        if key in set_by:
            both = "" if directed else " (the graph is undirected: one table sets both directions)"
            check.add(where, f"the pair {i} - {k} is already set by graph.edge[{set_by[key]}]{both}")
            continue
        set_by[key] = j
        if w is not None:
            weights[(i, k)] = w
            if not directed:
                weights[(k, i)] = w
        if d is not None:
            deltas[(i, k)] = d
            if not directed:
                deltas[(k, i)] = -d
    if len(check.problems) > before:
        return topology, directed, ()

    # a directed spanning tree (the paper's Assumption 1)
    missing = graphs.unreachable(known, pairs)
    if missing:
        check.add("graph", _spanning_message(known, pairs, missing, directed, topology))

    # consistent offsets: Δ_ik = θ_i - θ_k for some θ
    edges = tuple(Edge(i, k, weights[(i, k)], deltas[(i, k)]) for i, k in pairs)
    found = graphs.inconsistent_cycle(known, edges)
    if found is not None:
        check.add("graph.edge", _cycle_message(known, edges, found, paths))
    return topology, directed, edges


def _spanning_message(ids: list[str], pairs: list[tuple[str, str]], missing: list[str], directed: bool,
                      topology: str) -> str:
    root = graphs.spanning_root(ids, pairs)
    reached = [v for v in ids if v not in missing]
    where = "graph.edges" if topology == "explicit" else 'graph.edges (with topology = "explicit")'
    if not directed:
        return (f"the graph is not connected: {', '.join(missing)} cannot exchange ω with "
                f"{', '.join(reached)}; add an edge such as [{_q(missing[0])}, {_q(root)}] to {where}")
    msg = (f"no directed spanning tree: {', '.join(missing)} never hear{'s' if len(missing) == 1 else ''} "
           f"(even indirectly) from {root}, the vehicle "
           f"that reaches the most others, and no other vehicle reaches everyone (a pair [i, k] means i listens to "
           f"k, so information flows from k to i); add a pair such as [{_q(missing[0])}, {_q(root)}] "
           f"({missing[0]} listens to {root}) to {where}")
    reversed_pairs = [(k, i) for i, k in pairs]
    if not graphs.unreachable(ids, reversed_pairs):
        leader = graphs.spanning_root(ids, reversed_pairs)
        msg += (f"; or reverse the pairs: written the other way round they form a tree led by {leader} "
                f"(write each pair as [follower, leader])")
    msg += ", or set directed = false"
    return msg


def _common_period(periods: list[float | None]) -> float | None:
    """The smallest period shared by all (closed) paths on the cycle, if there is one."""
    if not periods or any(p is None for p in periods):
        return None
    longest = max(periods)
    for p in periods:
        ratio = longest / p
        if abs(ratio - round(ratio)) > 1e-6:
            return None
    return longest


def _cycle_message(ids: list[str], edges: tuple[Edge, ...], found: tuple[list[str], float],
                   paths: Mapping[str, Any]) -> str:
    cycle, total = found
    msg = (f"inconsistent formation offsets: around the cycle {' -> '.join(cycle)} the deltas sum to "
           f"{_angle(total)}, not 0, so ω_i - ω_k -> Δ_ik cannot hold on every edge (Δs must come from "
           f"per-vehicle phases, Δ_ik = θ_i - θ_k)")
    members = cycle[:-1]
    period = _common_period([getattr(paths.get(v), "period", None) if v in paths else None for v in members])
    phases = graphs.suggest_phases(ids, edges)
    if period is not None:
        laps = total / period
        n = round(laps)
        if n != 0 and abs(total - n * period) <= 1e-6:
            lap_text = "one lap" if abs(n) == 1 else f"{abs(n)} laps"
            msg += (f"; the sum is {n} × {_pi_text(period) or f'{period:.6g}'}, {lap_text} of the path: "
                    f"the formation cannot close")
            wrapped = {}
            for v, t in phases.items():
                t = t % period
                wrapped[v] = 0.0 if abs(t - period) < 1e-9 * period else t
            return msg + ("; you probably meant per-vehicle phases (each Δ then holds modulo one lap): remove the "
                          "deltas and set " + _phase_lines(wrapped))
    return msg + "; to keep the offsets of a spanning tree, remove the deltas and set " + _phase_lines(phases)


def _phase_lines(phases: Mapping[str, float]) -> str:
    return ", ".join(f"vehicle {_q(v)} phase = {round(t, 6)!r}" for v, t in phases.items())


def _positive_pairs(check: "_Check", table: Mapping[str, Any], allowed: Iterable[str], name: str,
                    field: Any, note: Any) -> tuple[tuple[str, float], ...]:
    """The allowed keys of ``table`` whose values are numbers > 0, as sorted (key, value) pairs."""
    pairs = []
    for key in sorted(table):
        if key in allowed:
            x = _number(check, table[key], field(name, key), gt=0, note=note(name, key))
            if x is not None:
                pairs.append((key, x))
    return tuple(pairs)

"""How is a scenario file read? Loading, overrides, and the sections put together.

The entry points of the scenario layer (docs/config.md is the user reference):
``load_scenario`` reads a TOML file, applies ``--set`` overrides, checks every section
(collecting every problem, not just the first), draws the seeded random starts and
returns a frozen :class:`Scenario`. A bad config raises :class:`ConfigError`, one line
per problem, each naming the file, the field and what would be valid. Nothing here
starts anything; the only I/O is reading the file.

One module per part of the file: :mod:`.sections` ([scenario], [rates], [metrics],
[gains], [supervision]), :mod:`.vehicles` ([defaults], [[vehicle]]), :mod:`.graph`,
:mod:`.link`, :mod:`.radio`, :mod:`.events`, :mod:`.safety` ([safety], [disturbance], [observer]);
all word their problems with :mod:`.checks`; the result
is the dataclasses of :mod:`.model`.
"""

from __future__ import annotations

import copy
import json
import os
import re
import select
import stat
import tomllib
from typing import Any, Iterable, Mapping

from dataclasses import replace

from cdus.scenario.checks import Problems, describe, quote
from cdus.scenario.errors import ConfigError
from cdus.core.formation import base_phases
from cdus.scenario.events import change_section, event_section, radio_event_section
from cdus.scenario.graph import graph_section
from cdus.scenario.link import link_section
from cdus.scenario.model import Edge, Rates, Safety, Scenario, Supervision, VehicleSpec
from cdus.scenario.plugins import plugins_section, probe_plants
from cdus.scenario.obstacles import obstacle_section, starts_clear
from cdus.scenario.radio import radio_section
from cdus.scenario.safety import apply_fleet, disturbance_section, observer_section, safety_section
from cdus.scenario.sections import (
    default_path_tol, gains_section, guidance_section, metrics_section, rates_section, scenario_section, section,
    supervision_section,
)
from cdus.scenario.robot import topic_clashes
from cdus.scenario.ros2 import ros2_section
from cdus.scenario.vehicles import defaults_section, gain_bounds, vehicles_section

# The entry points, and for their callers the error and the result types (defined in errors.py, model.py).
__all__ = [
    "ConfigError", "Edge", "Rates", "Safety", "Scenario", "Supervision", "VehicleSpec", "apply_override", "load_scenario",
    "parse_overrides", "parse_scenario", "parse_text", "parse_value",
]

SECTIONS = ("plugins", "scenario", "rates", "metrics", "gains", "guidance", "defaults", "supervision", "safety",
            "disturbance", "observer", "graph", "link", "radio", "ros2", "event", "vehicle", "obstacle")


# --------------------------------------------------------------------------- entry points


#: The largest scenario file read (bytes), checked before parsing. A fleet at the size limit
#: (cdus.scenario.vehicles.MAX_VEHICLES) with every per-vehicle key spelled out takes well
#: under 1 MB; the shipped configs take 1-4 kB. Parsing costs about 2 s and 13 MB of memory
#: per MB of TOML (a 53 MB file took 115 s and 700 MB), so 4 MB bounds it to seconds.
MAX_FILE_BYTES = 4 * 1024 * 1024
#: The deepest nesting of tables and lists accepted. A scenario nests 4 levels at most
#: ([[vehicle]] > start > region_min > number); past this the file is not a scenario, and
#: deep nesting would exhaust Python's recursion (50,000 brackets gave a RecursionError).
MAX_NESTING = 32


def load_scenario(path: str | os.PathLike, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Read, override, validate and resolve a scenario file. Raises :class:`ConfigError`."""
    source = os.fspath(path)
    try:
        # O_NONBLOCK: a FIFO opens at once instead of waiting for a writer for ever
        fd = os.open(source, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        mode = os.fstat(fd).st_mode
        if stat.S_ISFIFO(mode):  # a pipe: `cdus sim <(...)`, /dev/stdin; one nobody writes into is refused
            raw = _read_pipe(fd, source)
        elif not stat.S_ISREG(mode):
            os.close(fd)
            what = "a directory" if stat.S_ISDIR(mode) else "a device or socket"
            raise ConfigError(source, [("file", f"is {what}, not a regular file; give the path of a scenario "
                                                f".toml file (see configs/ for examples)")])
        else:
            with open(fd, "rb") as fh:
                raw = fh.read(MAX_FILE_BYTES + 1)
    except FileNotFoundError:
        raise ConfigError(source, [("file", "not found; give the path of a scenario .toml file "
                                            "(see configs/ for examples)")]) from None
    except OSError as e:
        raise ConfigError(source, [("file", f"cannot be read: {e.strerror or e}")]) from None
    if len(raw) > MAX_FILE_BYTES:
        raise ConfigError(source, [("file", f"larger than {MAX_FILE_BYTES // (1024 * 1024)} MB, the size limit of a "
                                            f"scenario file (a fleet of the largest size allowed, every key spelled "
                                            f"out, takes under 1 MB); give a scenario .toml file, not a data file")])
    data = parse_text(raw, source, json_format=source.endswith(".json"))
    return parse_scenario(data, source, overrides)


PIPE_WAIT_S = 5.0  # how long a config that is a pipe may stay silent before it is refused


def _read_pipe(fd: int, source: str) -> bytes:
    """The whole of a pipe given as the config (up to the size limit, + 1 byte), or a
    ConfigError when nothing comes for PIPE_WAIT_S (a named pipe nobody writes into hung
    `cdus sim` for ever). Closes ``fd``."""
    chunks, size = [], 0
    try:
        while size <= MAX_FILE_BYTES:
            if not select.select([fd], [], [], PIPE_WAIT_S)[0]:
                raise ConfigError(source, [("file", f"is a named pipe (FIFO) nothing was written into within "
                                                    f"{PIPE_WAIT_S:g} s; give the path of a scenario .toml file "
                                                    f"(see configs/ for examples)")])
            try:
                chunk = os.read(fd, 1 << 16)
            except BlockingIOError:
                continue
            if not chunk:  # the writer closed it: the whole file
                break
            chunks.append(chunk)
            size += len(chunk)
    finally:
        os.close(fd)
    return b"".join(chunks)


def parse_text(raw: bytes, source: str, json_format: bool = False) -> dict:
    """The bytes of a scenario file as TOML (or JSON: a resolved scenario, Scenario.raw,
    handed to a subprocess) data. A UTF-8 byte order mark and CRLF or CR line ends are
    accepted (a copy saved by a Windows editor); nesting deeper than :data:`MAX_NESTING`
    is a :class:`ConfigError`, never a RecursionError."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(source, [("file", "is not UTF-8 text; a scenario is a TOML file")]) from None
    text = text.removeprefix("\ufeff").replace("\r\n", "\n").replace("\r", "\n")
    deep = _too_deep_text(text)
    if deep is not None:
        raise ConfigError(source, [(deep, _nesting_message())])
    try:
        data = json.loads(text) if json_format else tomllib.loads(text)
    except RecursionError:  # not expected after _too_deep_text; never a traceback
        raise ConfigError(source, [("file", _nesting_message())]) from None
    except json.JSONDecodeError as e:
        raise ConfigError(source, [(f"line {e.lineno}, column {e.colno}", f"JSON syntax error: {e.msg}")]) from None
    except tomllib.TOMLDecodeError as e:
        text = str(e)
        m = re.search(r"\(at line (\d+), column (\d+)\)", text)
        where = f"line {m.group(1)}, column {m.group(2)}" if m else "TOML"
        message = text[:m.start()].strip() if m else text
        raise ConfigError(source, [(where, f"TOML syntax error: {message}")]) from None
    except ValueError as e:  # an integer of more than 4,300 digits (Python's int-from-text limit)
        raise ConfigError(source, [("file", f"holds a number cdus cannot read ({str(e)[:80]}): no "
                                            f"scenario number needs more than a few digits")]) from None
    if not isinstance(data, dict):
        raise ConfigError(source, [("file", f"must hold a table of sections, got {describe(data)}")])
    return data


def _nesting_message() -> str:
    return (f"lists and tables nested deeper than {MAX_NESTING} levels; a scenario nests 4 at most "
            f"(e.g. [[vehicle]] > start > region_min > a number): this is not a scenario file")


def _too_deep_text(text: str) -> str | None:
    """``line L, column C`` of the first bracket or brace nested deeper than
    :data:`MAX_NESTING` outside strings and comments, else None. A linear scan: a
    conservative bound on the depth the parser will reach (TOML nests through inline
    brackets and braces; table headers ``[a.b]`` nest by dotted keys, bounded by the data
    check in :func:`parse_scenario`)."""
    depth = 0
    line, col = 1, 0
    quote: str | None = None
    comment = False
    triple = False
    escape = False
    j, n = 0, len(text)
    while j < n:
        ch = text[j]
        col += 1
        if ch == "\n":
            line, col, comment = line + 1, 0, False
            if quote is not None and not triple:
                quote = None  # an unterminated string: the parser reports it
            j += 1
            continue
        if comment:
            j += 1
            continue
        if quote is not None:
            if escape:
                escape = False
            elif ch == "\\" and quote == '"':
                escape = True
            elif ch == quote and (not triple or text.startswith(quote * 3, j)):
                if triple:
                    j += 2
                    col += 2
                quote, triple = None, False
            j += 1
            continue
        if ch in "\"'":
            triple = text.startswith(ch * 3, j)
            quote = ch
            if triple:
                j += 2
                col += 2
        elif ch == "#":
            comment = True
        elif ch in "[{":
            depth += 1
            if depth > MAX_NESTING:
                return f"line {line}, column {col}"
        elif ch in "]}":
            depth = max(0, depth - 1)
        j += 1
    return None


def nesting_problem(data: Any, limit: int = MAX_NESTING) -> bool:
    """Is ``data`` (parsed TOML/JSON, or an override value) nested deeper than ``limit``?
    Iterative, so it cannot itself run out of recursion."""
    stack = [(data, 0)]
    while stack:
        v, d = stack.pop()
        if isinstance(v, (dict, list, tuple)) and d > limit:
            return True
        if isinstance(v, dict):
            stack.extend((x, d + 1) for x in v.values())
        elif isinstance(v, (list, tuple)):
            stack.extend((x, d + 1) for x in v)
    return False


def parse_scenario(data: Mapping[str, Any], source: str = "<config>",
                   overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Validate and resolve already-parsed TOML data (``data`` is not modified)."""
    if nesting_problem(data):
        raise ConfigError(source, [("file", _nesting_message())])
    for key, value in (overrides or {}).items():
        if nesting_problem(value, MAX_NESTING - 1):
            raise ConfigError(source, [(f"override {key}", _nesting_message())])
    data = copy.deepcopy(dict(data))
    for key, value in (overrides or {}).items():
        try:
            apply_override(data, key, value)
        except ConfigError as e:
            raise ConfigError(source, e.problems) from None
    p = Problems()
    scenario = _resolve(p, data, source)
    if scenario is None:
        raise ConfigError(source, p.items)
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

    if any(part == "" for part in parts):
        fail("not a dotted key; write e.g. scenario.seed, rates.control or vehicle.usv1.gains.k")
    node: Any = data
    if parts[0] == "vehicle":
        if len(parts) < 3:
            fail("address a vehicle's key as vehicle.<id>.<key>, e.g. vehicle.usv1.gains.k")
        vehicles = data.get("vehicle")
        vehicles = [v for v in vehicles if isinstance(v, dict)] if isinstance(vehicles, list) else []
        problems = Problems()
        problems.vehicle(parts[1], field, [v["id"] for v in vehicles if isinstance(v.get("id"), str)])
        if problems:
            fail(problems.items[0][1])
        node, parts, done = next(v for v in vehicles if v.get("id") == parts[1]), parts[2:], ["vehicle", parts[1]]
    else:
        done = []
    for part in parts[:-1]:
        done.append(part)
        nxt = node.get(part)
        if nxt is None:
            nxt = node[part] = {}
        elif not isinstance(nxt, dict):
            fail(f"{'.'.join(done)} is {describe(nxt)}, not a table, so it has no key {quote(parts[-1])}")
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
    if _too_deep_text(stripped) is not None:
        return text  # kept as a string; never a RecursionError
    try:
        value = tomllib.loads(f"v = {stripped}")["v"]
    except (ValueError, RecursionError):  # a TOML syntax error, or an int of over 4,300 digits
        return text
    if isinstance(value, (int, float, bool, str, list, dict)):
        return value
    return text  # TOML dates and times: keep the text


# --------------------------------------------------------------------------- the sections together


def sensor_timing(p: Problems, safety: Any, duration: float) -> None:
    """With the filter on, a sensor whose latency or sample period is the whole run would
    leave the filter without contacts, or steering by where the vehicles were at t = 0."""
    if not safety.enabled:
        return
    if safety.latency >= duration:
        p.add("safety.latency", f"must be below scenario.duration ({duration:g} s): contacts that old never "
                                f"reach the filter, which would never act; got {safety.latency:g} s")
    if 1.0 / safety.rate >= duration:
        p.add("safety.rate", f"must be above 1 / scenario.duration ({1.0 / duration:g} Hz): the sensor would "
                             f"sample once, at t = 0, and the filter steer by those positions for the whole "
                             f"run; got {safety.rate:g} Hz")


def _resolve(p: Problems, data: Mapping[str, Any], source: str) -> Scenario | None:
    """Every section, checked in file order where one needs another (vehicles before the
    graph, the ids before [link] and [[event]]); None if anything is wrong."""
    p.unknown_keys(data, SECTIONS, "", what="section")
    mark = len(p)
    plugins_section(p, data.get("plugins"))  # first: the vehicles and events may name what they add
    if p.since(mark):  # not also "unknown path family" for each vehicle on a plug-in that failed
        return None
    header = scenario_section(p, section(p, data, "scenario"))
    rates = rates_section(p, section(p, data, "rates"))
    metrics = section(p, data, "metrics")
    path_tol, coord_tol = metrics_section(p, metrics)
    fleet_gains = gains_section(p, section(p, data, "gains"))
    scale_omega = guidance_section(p, section(p, data, "guidance"))
    defaults = defaults_section(p, section(p, data, "defaults"))
    supervision = supervision_section(p, section(p, data, "supervision"))
    safety = safety_section(p, section(p, data, "safety"))
    sensor_timing(p, safety, header.duration)
    obstacles = obstacle_section(p, data.get("obstacle"), safety.radius)
    disturbance = disturbance_section(p, section(p, data, "disturbance"))
    observer = observer_section(p, section(p, data, "observer"))
    fleet = vehicles_section(p, data.get("vehicle"), defaults, fleet_gains, header.seed)
    fleet.specs = apply_fleet(fleet.specs, data.get("vehicle"), defaults, disturbance, observer)
    probe_plants(p, fleet.specs, fleet.paths, rates.physics, rates.control, safety.enabled)
    starts_clear(p, fleet.specs, fleet.paths, obstacles)
    if scale_omega:
        fleet.specs = [None if s is None else replace(s, scale_omega=True) for s in fleet.specs]
    if "path_tol" not in metrics:  # a fleet with usv_3dof boats: theirs (sections.USV_PATH_TOL)
        path_tol = default_path_tol(fleet.specs)
    topology, directed, edges = graph_section(p, section(p, data, "graph"), fleet)
    gain_bounds(p, data.get("vehicle"), defaults, fleet_gains, fleet.specs, rates, edges)
    ids = fleet.known if fleet.complete else None
    link = link_section(p, data.get("link", {}), ids)
    radio = radio_section(p, data["radio"], ids) if "radio" in data else None
    events = event_section(p, data.get("event", []), ids)
    specs = [v for v in fleet.specs if v is not None]
    base = base_phases(ids, {v.id: v.phase for v in specs}, edges) if ids is not None and not p else None
    changes = change_section(p, data.get("event", []), ids, {v.id: v.dim for v in specs}, edges, directed, base)
    radio_events = radio_event_section(p, data.get("event", []), "radio" in data,
                                       adhoc=radio is not None and radio.topology == "adhoc")
    ros2 = ros2_section(p, section(p, data, "ros2"), ids)
    topic_clashes(p, fleet.specs, ros2)
    if p or link is None:
        return None
    return Scenario(
        name=header.name, description=header.description, source=source, duration=header.duration,
        seed=header.seed, rates=rates, path_tol=path_tol, coord_tol=coord_tol, topology=topology,
        directed=directed, vehicles=tuple(v for v in fleet.specs if v is not None), edges=edges, link=link,
        events=events, supervision=supervision, raw=dict(data), safety=safety, radio=radio,
        changes=changes, radio_events=radio_events, ros2=ros2, obstacles=obstacles,
    )

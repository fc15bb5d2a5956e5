"""Are the scheduled events valid? The scenario's ``[[event]]`` tables.

    [[event]]
    at = 60.0            # simulated seconds
    action = "kill"      # kill | pause | resume | restart | formation | path
    vehicle = "usv2"
    duration = 10.0      # optional, pause only: resume after this many seconds

    [[event]]            # a new formation: phases of some vehicles (the others keep theirs) ...
    at = 80.0
    action = "formation"
    phases = { usv2 = 2.0944, uav1 = 4.1888 }
    # ... or offsets on edges: offsets = [{ i = "usv2", k = "usv1", delta = 2.0944 }]

    [[event]]            # a new path for one vehicle
    at = 90.0
    action = "path"
    vehicle = "uav1"
    path = { family = "circle", center = [0, 0, 20], radius = 15, speed = 1.5 }

    [[event]]
    at = 60.0
    action = "radio"     # with [radio]: a scheduled radio change, for messages sent from `at` on
    tx_power = 5.0       # dBm, and/or
    station = [0.0, -80.0]

:func:`event_section` checks them against the vehicle ids into the
:class:`cdus.core.events.Event` tuple that ``Scenario.events`` carries (what each action
does is described there); :func:`change_section` checks the formation and path changes
into ``Scenario.changes`` (cdus.core.formation). docs/config.md is the user reference.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

from cdus.commands.base import Rejected
from cdus.commands.radio import Radio
from cdus.commands.vehicle import BY_EVENT as FAULT_BY_EVENT
from cdus.core.events import Event
from cdus.core.formation import MAX_PHASE, FormationChange, PathChange, phases_from_offsets
from cdus.scenario.paths import check_path  # noqa: F401 (also the world's and the agents' door to a new path)
from cdus.scenario.checks import IdList, Problems, describe, is_number, quote, show
from cdus.core.radiolink import RadioEvent
from cdus.core.vocabulary import CHANGE_ACTIONS, FAULT_ACTIONS, KILL, PATH, PAUSE, RESTART, RESUME, ROSTER_STATES
from cdus.wire.bounds import BOUNDS

EVENT_KEYS = ("at", "action", "vehicle", "duration", "phases", "offsets", "path")
REQUIRED = ("at", "action", "vehicle")
#: the actions a vehicle-fault or change event takes (cdus.core.vocabulary; a radio event is radio_event_section's)
ALL_ACTIONS = FAULT_ACTIONS + CHANGE_ACTIONS
OFFSET_KEYS = ("i", "k", "delta")
PATH_EXAMPLE = '{ family = "circle", center = [0, 0], radius = 10 }'
#: ω units: how far a formation's given offsets may be from the ones its phases give (float64
#: sums along the graph's tree round; a lap is 2π/β, ~30 ω units at β = 0.2)
OFFSET_TOL = 1e-6


def event_section(p: Problems, raw: Any, ids: Sequence[str] | None) -> tuple[Event, ...]:
    """The events sorted by time (a pause with ``duration`` adds its resume), checked in
    sequence per vehicle (:func:`_check_sequence`)."""
    fielded: list[tuple[Event, str]] = []
    for j, e in enumerate(p.tables(raw, "event", "event")):
        if e.get("action") in CHANGE_ACTIONS:
            continue  # change_section's
        if e.get("action") == "radio":
            continue  # radio_event_section's
        evs = _event(p, e, f"event[{j}]", ids)
        # a pause's duration brings a resume, named after the duration
        fielded += [(ev, f"event[{j}]" + (".duration" if k else "")) for k, ev in enumerate(evs)]
    fielded.sort(key=lambda x: x[0].at)  # stable: events at the same time keep the file's order
    return tuple(_check_sequence(p, fielded))


# what each action needs the vehicle to be, and what it leaves it
_NEEDS = {KILL: ("live", "paused"), PAUSE: ("live",), RESUME: ("paused",), RESTART: ROSTER_STATES}
_LEAVES = {KILL: "gone", PAUSE: "paused", RESUME: "live", RESTART: "live"}
_FIX = {KILL: "it is already gone (killed before): remove one of the kills",
        PAUSE: "it is {state} then: pause a live vehicle (a killed one needs a restart first)",
        RESUME: "it is {state} then, not paused: remove it, or pause the vehicle first "
                "(a killed vehicle comes back with a restart)"}


def _check_sequence(p: Problems, fielded: list[tuple[Event, str]]) -> list[Event]:
    """Every event must find its vehicle in a state it can act on: no resume of a vehicle
    nobody paused, no second kill, no pause of a killed vehicle. (A lapsed pause, gone in
    the roster after the lease, still counts as paused here: a resume brings it back.) The
    resume a pause's ``duration`` implies is dropped if a kill or restart came first.
    Returns the events to carry out."""
    state: dict[str, str] = {}
    out: list[Event] = []
    for ev, field in fielded:
        now = state.get(ev.vehicle, "live")
        if field.endswith(".duration") and now != "paused":
            continue  # the pause ended otherwise (killed or restarted meanwhile)
        if now not in _NEEDS[ev.action]:
            p.add(f"{field}.action", f"{ev.action} of {ev.vehicle} at {ev.at:g} s: "
                                     + _FIX[ev.action].format(state="killed" if now == "gone" else now))
            continue
        state[ev.vehicle] = _LEAVES[ev.action]
        out.append(ev)
    return out


def _event(p: Problems, e: dict, field: str, ids: Sequence[str] | None) -> list[Event]:
    """One [[event]]: its event, and the resume that ends a pause with a duration."""
    mark = len(p)
    p.unknown_keys(e, EVENT_KEYS, field)
    for key in ("phases", "offsets", "path"):
        if key in e:
            p.add(f"{field}.{key}", f'only a "formation" event takes phases or offsets, and a "path" event a path '
                                    f"(this event is a {quote(e.get('action'))}); remove it")
    missing = [key for key in REQUIRED if key not in e]
    for key in missing:
        p.missing(f"{field}.{key}", 'an event needs at, action and vehicle, e.g. at = 60.0, action = "kill", '
                                    'vehicle = "usv2"')
    if missing:
        return []
    at = p.number(e["at"], f"{field}.at", "event.at", unit=" (s of simulated time)")
    action = p.choice(e["action"], f"{field}.action", ALL_ACTIONS, "action")
    vehicle = p.vehicle(e["vehicle"], f"{field}.vehicle", ids)
    duration = None
    if "duration" in e:
        if action is not None and action != PAUSE:
            p.add(f"{field}.duration", f"only a pause takes a duration (this event is a {quote(action)}); remove it")
        else:
            duration = p.number(e["duration"], f"{field}.duration", "event.duration",
                                unit=" s (then the vehicle resumes)")
    if p.since(mark) or at is None or action is None or vehicle is None:
        return []
    fault = FAULT_BY_EVENT[action].parse({"vehicle": vehicle})  # the run-time command's own parse
    if isinstance(fault, Rejected):
        p.add(f"{field}.{fault.field or 'vehicle'}", fault.reason)
        return []
    events = [Event(at, fault.NAMES.event, fault.vehicle)]
    if duration is not None:
        events.append(Event(at + duration, RESUME, vehicle))
    return events


# --------------------------------------------------------------------------- formation and path changes


def change_section(p: Problems, raw: Any, ids: Sequence[str] | None, dims: Mapping[str, int],
                   edges: Sequence[Any], directed: bool, base: Sequence[float] | None
                   ) -> tuple[FormationChange | PathChange, ...]:
    """The ``formation`` and ``path`` events, sorted by time (the file's order at the same time),
    each checked: a formation's phases name vehicles, are finite and within ±MAX_PHASE; its
    offsets name listening pairs and, with the Δs in force on every other edge, close around
    every cycle (resolved into phases against the scheduled formation before it: ``base`` is
    the phases in force at the start); a path is a path table for the vehicle's dimension.
    ``edges``: the graph's edges (.i, .k); ``ids``/``base`` None: not checkable (other problems)."""
    if not isinstance(raw, list) or not all(isinstance(t, dict) for t in raw):
        return ()  # event_section reported it
    pending: list[tuple[float, int, str, dict]] = []
    for j, e in enumerate(raw):
        if e.get("action") not in CHANGE_ACTIONS:
            continue
        field = f"event[{j}]"
        p.unknown_keys(e, EVENT_KEYS, field)
        if "at" not in e:
            p.missing(f"{field}.at", f'a {e["action"]} event needs at (s of simulated time), e.g. at = 60.0')
            continue
        at = p.number(e["at"], f"{field}.at", "event.at", unit=" (s of simulated time)")
        if "duration" in e:
            p.add(f"{field}.duration", f"only a pause takes a duration (this event is a {quote(e['action'])}); remove it")
        if at is not None:
            pending.append((at, j, field, e))
    pending.sort(key=lambda x: (x[0], x[1]))
    current = list(base) if base is not None else None
    out: list[FormationChange | PathChange] = []
    for at, _, field, e in pending:
        if e["action"] == PATH:
            change = _path_change(p, e, field, at, ids, dims)
        else:
            change = _formation_change(p, e, field, at, ids, edges, directed, current)
            if change is not None and current is not None:
                for vid, theta in change.phases:
                    current[ids.index(vid)] = theta
        if change is not None:
            out.append(change)
    return tuple(out)


def _path_change(p: Problems, e: dict, field: str, at: float, ids: Sequence[str] | None,
                 dims: Mapping[str, int]) -> PathChange | None:
    for key in ("phases", "offsets"):
        if key in e:
            p.add(f"{field}.{key}", f'only a "formation" event takes {key}; a "path" event takes vehicle and path')
    for key in ("vehicle", "path"):
        if key not in e:
            p.missing(f"{field}.{key}", f'a path event needs vehicle and path, e.g. vehicle = "uav1", '
                                        f"path = {PATH_EXAMPLE}")
    if "vehicle" not in e or "path" not in e:
        return None
    vid = p.vehicle(e["vehicle"], f"{field}.vehicle", ids)
    table = p.table(e["path"], f"{field}.path", PATH_EXAMPLE)
    if vid is None or table is None or vid not in dims:
        return None
    checked = check_path(table, dims[vid])
    if isinstance(checked, tuple) and isinstance(checked[0], str):
        sub, message = checked
        p.add(f"{field}.path" + (f".{sub}" if sub else ""), f"{message} (vehicle {vid} is {dims[vid]}-D)")
        return None
    return PathChange(at, vid, frozen(table))


def frozen(v: Any) -> Any:
    """Lists -> tuples, tables -> sorted pairs, recursively (hashable; ``dict()`` of it is the table)."""
    if isinstance(v, list):
        return tuple(frozen(x) for x in v)
    if isinstance(v, dict):
        return tuple(sorted((k, frozen(x)) for k, x in v.items()))
    return v


def _formation_change(p: Problems, e: dict, field: str, at: float, ids: Sequence[str] | None,
                      edges: Sequence[Any], directed: bool, current: list[float] | None) -> FormationChange | None:
    for key in ("vehicle", "path"):
        if key in e:
            p.add(f"{field}.{key}", 'a "formation" event changes the whole fleet\'s offsets: it takes phases '
                                    '(or offsets), not vehicle or path; remove it')
    given = [key for key in ("phases", "offsets") if key in e]
    if len(given) != 1:
        p.add(f"{field}.phases", "a formation event takes either phases = { id = θ, ... } (θ in ω units) or "
                                 'offsets = [{ i = "usv2", k = "usv1", delta = ... }], ' +
                                 ("not both" if given else "and has neither"))
        return None
    if ids is None or current is None:
        return None
    if given[0] == "phases":
        phases = check_phases(e["phases"], ids)
        if isinstance(phases, tuple):
            p.add(f"{field}.phases" + (f".{phases[0]}" if phases[0] else ""), phases[1])
            return None
    else:
        offsets = check_offsets(e["offsets"], ids, edges, directed)
        if isinstance(offsets, tuple):
            p.add(f"{field}.offsets" + phases_suffix(offsets[0]), offsets[1])
            return None
        phases = offsets_to_phases(ids, current, edges, offsets, directed)
        if isinstance(phases, str):
            p.add(f"{field}.offsets", phases)
            return None
    order = {v: j for j, v in enumerate(ids)}
    return FormationChange(at, tuple(sorted(phases.items(), key=lambda x: order[x[0]])))


def phases_suffix(sub: str) -> str:
    return sub if sub.startswith("[") or not sub else f".{sub}"


def check_phases(table: Any, ids: Sequence[str]) -> dict[str, float] | tuple[str, str]:
    """``{id: θ}`` from a phases table, or ``(key, message)``: a table of known ids, each a
    finite number within ±MAX_PHASE (ω units; a lap is 2π/β)."""
    if not isinstance(table, dict) or not table:
        return "", (f"must be a non-empty table of vehicle = phase (θ in ω units), e.g. {{ usv2 = 2.0944 }}, "
                    f"got {describe(table)}")
    known = ids if isinstance(ids, IdList) else IdList(ids)
    out = {}
    for vid, theta in table.items():
        if not isinstance(vid, str) or vid not in known:
            return "", f"{show(vid)} is not a vehicle; ids are {', '.join(list(ids)[:10])}"
        if not BOUNDS["vehicle.phase"].holds(theta):
            got = show(theta) if is_number(theta) else describe(theta)
            return vid, f"must be a finite number of ω units within ±{MAX_PHASE:g} (θ; a lap is 2π/β), got {got}"
        out[vid] = float(theta)
    return out


def check_offsets(raw: Any, ids: Sequence[str], edges: Sequence[Any], directed: bool
                  ) -> dict[tuple[str, str], float] | tuple[str, str]:
    """``{(i, k): Δ_ik}`` from a list of ``{i, k, delta}`` tables naming listening pairs (in an
    undirected graph a pair once, either way round), or ``(where, message)``."""
    if not isinstance(raw, list) or not raw or not all(isinstance(t, dict) for t in raw):
        return "", (f'must be a non-empty list of {{ i = "usv2", k = "usv1", delta = ... }} tables (i listens to k, '
                    f"Δ_ik the target of ω_i - ω_k), got {describe(raw)}")
    known = ids if isinstance(ids, IdList) else IdList(ids)
    pairs = {(e.i, e.k) for e in edges}
    out: dict[tuple[str, str], float] = {}
    for j, t in enumerate(raw):
        where = f"[{j}]"
        extra = sorted(str(x) for x in set(t) - set(OFFSET_KEYS))
        if extra:
            return f"{where}.{extra[0]}", "unknown key; valid keys here: i, k, delta"
        for key in OFFSET_KEYS:
            if key not in t:
                return f"{where}.{key}", 'missing; an offset is { i = "usv2", k = "usv1", delta = ... }'
        i, k, d = t["i"], t["k"], t["delta"]
        for key, v in (("i", i), ("k", k)):
            if not isinstance(v, str) or v not in known:
                return f"{where}.{key}", f"{show(v)} is not a vehicle; ids are {', '.join(list(ids)[:10])}"
        if not BOUNDS["graph.edge.delta"].holds(d):
            got = show(d) if is_number(d) else describe(d)
            return f"{where}.delta", f"must be a finite number of ω units within ±{MAX_PHASE:g}, got {got}"
        if (i, k) not in pairs:
            return where, (f"{i} does not listen to {k} in this graph: an offset can only be set on an edge of "
                           f"[graph] (i listens to k)")
        key = (i, k) if directed or ids.index(i) < ids.index(k) else (k, i)
        if key in out:
            return where, f"the pair {i} - {k} is given twice" + ("" if directed else
                                                                   " (the graph is undirected: one entry sets both "
                                                                   "directions)")
        out[key] = float(d) if key == (i, k) else -float(d)
    return out


#: a cycle of more vehicles than this is shown by its ends in a refusal
MAX_CYCLE_SHOWN = 8


def offsets_to_phases(ids: Sequence[str], current: Sequence[float], edges: Sequence[Any],
                      offsets: Mapping[tuple[str, str], float], directed: bool) -> dict[str, float] | str:
    """The phase updates for ``offsets`` (cdus.core.formation.phases_from_offsets), or why the
    offsets cannot hold: the cycle around which they do not sum to 0, and the fix."""
    found = phases_from_offsets(ids, current, [(e.i, e.k) for e in edges], offsets, directed)
    if isinstance(found, tuple):
        cycle, total = found
        hops = " -> ".join(cycle) if len(cycle) <= MAX_CYCLE_SHOWN else (
            f"{' -> '.join(cycle[:3])} -> ... ({len(cycle) - 5} more) -> {' -> '.join(cycle[-2:])}")
        rounded = " (rounded numbers? give them to full precision)" if abs(total) < 1e-3 else ""
        # the fix before the cycle: a ground station's reply (cut at 300 characters) keeps it
        return (f"inconsistent formation offsets: with those in force on the other edges they sum to {total:.6g}, "
                f"not 0{rounded}, around a cycle; give per-vehicle phases instead (Δ_ik = θ_i - θ_k always "
                f"closes) or offsets on every edge of the cycle that sum to 0; the cycle: {hops}")
    # the cycle check's tolerance is relative (1e-9 of the largest value): offsets near ±1e9 that
    # miss closing by up to ~1 ω unit passed it, and the phases solved along the tree then gave
    # one edge a Δ other than the one asked. Every given Δ must come out as asked.
    theta = dict(zip(ids, current)) | found
    tol = OFFSET_TOL + 1e-15 * len(ids) * max([1.0, *(abs(x) for x in theta.values())])
    for (i, k), d in offsets.items():
        miss = (theta[i] - theta[k]) - d
        if not abs(miss) <= tol:
            return (f"inconsistent formation offsets: they miss closing around a cycle through {i} - {k} by "
                    f"{-miss:.6g} ω units (the deltas given and the ones in force on the other edges must sum "
                    f"to 0 within {tol:.2g}); give per-vehicle phases instead (phases = {{ id = θ, ... }})")
    far = [vid for vid, theta in found.items() if not abs(theta) <= MAX_PHASE]
    if far:  # every process takes phases within ±MAX_PHASE only
        return (f"these offsets put the phase of {far[0]} at {found[far[0]]:.6g}, beyond ±{MAX_PHASE:g} ω units; "
                f"give smaller offsets")
    return found


RADIO_EVENT_KEYS = ("at", "action", "tx_power", "station")


def radio_event_section(p: Problems, raw: Any, has_radio: bool, adhoc: bool = False) -> tuple[RadioEvent, ...]:
    """The ``action = "radio"`` events, sorted by time (a stable sort: the file's order at one
    time, the later one wins): ``at`` and ``tx_power`` and/or ``station``, as a ground station's
    ``radio`` command takes them (cdus.scenario.radio.validate_radio_update); only with [radio],
    and no ``station`` with an ``adhoc`` one (it has no station: the ground station's command is
    refused alike)."""
    out: list[RadioEvent] = []
    if not isinstance(raw, list):
        return ()  # event_section reports it
    for j, e in enumerate(raw):
        if not isinstance(e, dict) or e.get("action") != "radio":
            continue
        field = f"event[{j}]"
        mark = len(p)
        p.unknown_keys(e, RADIO_EVENT_KEYS, field)
        if not has_radio:
            p.add(f"{field}.action", "a radio event needs a [radio] table (docs/radio.md); add one or remove the event")
        if "at" not in e:
            p.missing(f"{field}.at", 'a radio event needs at, and tx_power and/or station, e.g. at = 60.0, '
                                     'action = "radio", tx_power = 5.0')
        at = (p.number(e["at"], f"{field}.at", "event.at", unit=" (s of simulated time)")
              if "at" in e else None)
        change = Radio.parse({"radio": {k: v for k, v in e.items() if k in Radio.CHANGE_KEYS}})  # a command's parse
        if isinstance(change, Rejected):
            p.add(f"{field}.{change.field}" if change.field not in (None, "radio") else field, change.reason)
            continue
        tx, station = change.tx_power, change.station
        if adhoc and station is not None:
            p.add(f"{field}.station", 'the [radio] table\'s topology is "adhoc": no station relays the messages, '
                                      'so moving one changes nothing; remove station (keep tx_power) or set '
                                      'radio.topology = "station"')
        if not p.since(mark) and at is not None:
            out.append(RadioEvent(at, tx, station))
    out.sort(key=lambda ev: ev.at)
    return tuple(out)

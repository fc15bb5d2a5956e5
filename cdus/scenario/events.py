"""Are the scheduled vehicle faults valid? The scenario's ``[[event]]`` tables.

    [[event]]
    at = 60.0            # simulated seconds
    action = "kill"      # kill | pause | resume | restart
    vehicle = "usv2"
    duration = 10.0      # optional, pause only: resume after this many seconds

    [[event]]
    at = 60.0
    action = "radio"     # with [radio]: a scheduled radio change, for messages sent from `at` on
    tx_power = 5.0       # dBm, and/or
    station = [0.0, -80.0]

:func:`event_section` checks them against the vehicle ids into the
:class:`cdus.core.events.Event` tuple that ``Scenario.events`` carries (what each action
does is described there; docs/config.md is the user reference).
"""

from __future__ import annotations

from typing import Any, Sequence

from cdus.core.events import ACTIONS, Event
from cdus.core.radiolink import RadioEvent
from cdus.scenario.checks import Problems, quote
from cdus.scenario.errors import ConfigError
from cdus.scenario.radio import validate_radio_update

EVENT_KEYS = ("at", "action", "vehicle", "duration")
REQUIRED = ("at", "action", "vehicle")


def event_section(p: Problems, raw: Any, ids: Sequence[str] | None) -> tuple[Event, ...]:
    """The events sorted by time (a pause with ``duration`` adds its resume), checked in
    sequence per vehicle (:func:`_check_sequence`)."""
    fielded: list[tuple[Event, str]] = []
    for j, e in enumerate(p.tables(raw, "event", "event")):
        if e.get("action") == "radio":
            continue  # radio_event_section's
        evs = _event(p, e, f"event[{j}]", ids)
        # a pause's duration brings a resume, named after the duration
        fielded += [(ev, f"event[{j}]" + (".duration" if k else "")) for k, ev in enumerate(evs)]
    fielded.sort(key=lambda x: x[0].at)  # stable: events at the same time keep the file's order
    return tuple(_check_sequence(p, fielded))


# what each action needs the vehicle to be, and what it leaves it
_NEEDS = {"kill": ("live", "paused"), "pause": ("live",), "resume": ("paused",), "restart": ("live", "paused", "gone")}
_LEAVES = {"kill": "gone", "pause": "paused", "resume": "live", "restart": "live"}
_FIX = {"kill": "it is already gone (killed before): remove one of the kills",
        "pause": "it is {state} then: pause a live vehicle (a killed one needs a restart first)",
        "resume": "it is {state} then, not paused: remove it, or pause the vehicle first "
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
    missing = [key for key in REQUIRED if key not in e]
    for key in missing:
        p.missing(f"{field}.{key}", 'an event needs at, action and vehicle, e.g. at = 60.0, action = "kill", '
                                    'vehicle = "usv2"')
    if missing:
        return []
    at = p.number(e["at"], f"{field}.at", ge=0, unit=" (s of simulated time)")
    action = p.choice(e["action"], f"{field}.action", ACTIONS, "action")
    vehicle = p.vehicle(e["vehicle"], f"{field}.vehicle", ids)
    duration = None
    if "duration" in e:
        if action is not None and action != "pause":
            p.add(f"{field}.duration", f"only a pause takes a duration (this event is a {quote(action)}); remove it")
        else:
            duration = p.number(e["duration"], f"{field}.duration", gt=0, unit=" s (then the vehicle resumes)")
    if p.since(mark) or at is None or action is None or vehicle is None:
        return []
    events = [Event(at, action, vehicle)]
    if duration is not None:
        events.append(Event(at + duration, "resume", vehicle))
    return events


RADIO_EVENT_KEYS = ("at", "action", "tx_power", "station")


def radio_event_section(p: Problems, raw: Any, has_radio: bool) -> tuple[RadioEvent, ...]:
    """The ``action = "radio"`` events, sorted by time (a stable sort: the file's order at one
    time, the later one wins): ``at`` and ``tx_power`` and/or ``station``, as a ground station's
    ``radio`` command takes them (cdus.scenario.radio.validate_radio_update); only with [radio]."""
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
        at = p.number(e["at"], f"{field}.at", ge=0, unit=" (s of simulated time)") if "at" in e else None
        try:
            tx, station = validate_radio_update({k: v for k, v in e.items() if k in ("tx_power", "station")},
                                                f"{field}")
        except ConfigError as err:
            for name, message in err.problems:
                p.add(f"{field}.{name.removeprefix('radio.')}" if name != "radio" else field, message)
            continue
        if not p.since(mark) and at is not None:
            out.append(RadioEvent(at, tx, station))
    out.sort(key=lambda ev: ev.at)
    return tuple(out)

"""Scheduled vehicle faults: the scenario's ``[[event]]`` tables.

    [[event]]
    at = 60.0            # simulated seconds
    action = "kill"      # kill | pause | resume | restart
    vehicle = "usv2"
    duration = 10.0      # optional, pause only: resume after this many seconds

- kill: the vehicle's process dies (SIGKILL); its neighbours drop it from their sums
  when its liveliness token goes; the world reports whether the graph still has a
  spanning tree.
- pause: the process is frozen (SIGSTOP): it neither steps nor sends, but it is not
  gone until the liveliness lease runs out (1 s under the launcher).
- resume: SIGCONT.
- restart: a new process for the vehicle, which rejoins where the world last saw it,
  with ω at the nearest point of its path (continuing its old ω, not a lap away).

The launcher carries them out against the world's simulated time; the in-process fleet
emulates the same effects, so a sweep can use them too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

ACTIONS = ("kill", "pause", "resume", "restart")
EVENT_KEYS = ("at", "action", "vehicle", "duration")


@dataclass(frozen=True)
class Event:
    at: float
    action: str
    vehicle: str


def validate_events(raw: Iterable[dict], ids: Sequence[str]) -> tuple[tuple[Event, ...], list[tuple[str, str]]]:
    """The events sorted by time (a pause with ``duration`` adds its resume), and the problems."""
    events: list[Event] = []
    problems: list[tuple[str, str]] = []
    for j, e in enumerate(raw):
        f = f"event[{j}]"
        unknown = sorted(set(e) - set(EVENT_KEYS))
        if unknown:
            problems.append((f"{f}.{unknown[0]}", f"not an event key; an event takes {', '.join(EVENT_KEYS)}"))
        at, action, vid = e.get("at"), e.get("action"), e.get("vehicle")
        ok = True
        if isinstance(at, bool) or not isinstance(at, (int, float)) or not math.isfinite(at) or at < 0:
            problems.append((f"{f}.at", f"must be a time in simulated seconds >= 0, got {at!r}"))
            ok = False
        if action not in ACTIONS:
            problems.append((f"{f}.action", f"must be one of {', '.join(ACTIONS)}, got {action!r}"))
            ok = False
        if vid not in ids:
            problems.append((f"{f}.vehicle", f"no vehicle {vid!r}; ids are {', '.join(ids)}"))
            ok = False
        dur = e.get("duration")
        if dur is not None and (action != "pause" or isinstance(dur, bool) or not isinstance(dur, (int, float))
                                or not dur > 0):
            problems.append((f"{f}.duration", "only a pause takes a duration, a number of seconds > 0"))
            ok = False
        if ok:
            events.append(Event(float(at), action, vid))
            if dur is not None:
                events.append(Event(float(at) + float(dur), "resume", vid))
    events.sort(key=lambda ev: ev.at)
    return tuple(events), problems


def parse_events(raw: Iterable[dict], ids: Sequence[str]) -> tuple[Event, ...]:
    events, problems = validate_events(raw, ids)
    if problems:
        raise ValueError("; ".join(f"{f}: {m}" for f, m in problems))
    return events

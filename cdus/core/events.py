"""Who is live when, given the scheduled vehicle faults? The roster a fleet's runners agree on.

A scenario's ``[[event]]`` tables (validated in :mod:`cdus.scenario.events`) are
:class:`Event`\\ s. Their effect on the fleet is a *roster*: for each vehicle, the ticks
from which it is ``live``, ``paused`` (frozen: silent, its last ω still held by its
neighbours) or ``gone`` (out of every sum; nothing it sent is used any more). Every
runner derives the same roster from the same events with :func:`plan_roster`, so a
fault lands on the same tick in the in-process fleet and in a lockstep fleet of
processes, whatever the operating system does (docs/faults.md):

- kill at t: gone from the first tick at or after t;
- pause at t: paused from that tick; gone once the liveliness lease has run out (the
  process is frozen, so its token lapses), unless it is resumed before;
- resume at t: live again from that tick, continuing where it was;
- restart at t: gone and live again at that tick, as a new process that rejoins where
  the world last saw it (``fresh``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Sequence

from cdus.core.vocabulary import KILL, PAUSE, RESTART, RESUME, ROSTER_STATES

LEASE_S = 1.0  # the liveliness lease the launcher sets: a frozen process is gone after this


@dataclass(frozen=True)
class Event:
    at: float  # simulated seconds
    action: str  # one of cdus.core.vocabulary.FAULT_ACTIONS: kill | pause | resume | restart
    vehicle: str


@dataclass(frozen=True, order=True)
class RosterChange:
    """From tick ``tick`` on, vehicle ``vehicle`` (an index) is ``state``; ``fresh``: it comes
    back as a new process (a restart), not from a pause."""

    tick: int
    vehicle: int
    state: str
    fresh: bool = False


def event_tick(at: float, period: float) -> int:
    """The first control tick at or after simulated time ``at``."""
    return max(0, math.ceil(at / period - 1e-9))


def plan_roster(events: Iterable[Event], ids: Sequence[str], period: float,
                lease: float = LEASE_S) -> tuple[RosterChange, ...]:
    """The roster changes the scheduled ``events`` make, sorted by tick (then vehicle)."""
    index = {vid: j for j, vid in enumerate(ids)}
    lease_ticks = max(1, math.ceil(lease / period - 1e-9))
    changes: list[RosterChange] = []
    state = {j: "live" for j in range(len(ids))}
    paused_at: dict[int, int] = {}

    def lapse(j: int, before: int) -> None:
        """A paused vehicle whose lease runs out before tick ``before`` is gone from then."""
        p = paused_at.pop(j, None)
        if p is not None and p + lease_ticks < before:
            changes.append(RosterChange(p + lease_ticks, j, "gone"))
            state[j] = "gone"

    for ev in sorted(events, key=lambda e: e.at):
        j, n = index[ev.vehicle], event_tick(ev.at, period)
        if ev.action == KILL and state[j] != "gone":
            lapse(j, n)
            if state[j] != "gone":
                changes.append(RosterChange(n, j, "gone"))
                state[j] = "gone"
        elif ev.action == PAUSE and state[j] == "live":
            changes.append(RosterChange(n, j, "paused"))
            state[j], paused_at[j] = "paused", n
        elif ev.action == RESUME and state[j] == "paused":
            lapse(j, n)
            changes.append(RosterChange(n, j, "live"))
            state[j] = "live"
            paused_at.pop(j, None)
        elif ev.action == RESTART:
            paused_at.pop(j, None)
            changes.append(RosterChange(n, j, "gone"))
            changes.append(RosterChange(n, j, "live", fresh=True))
            state[j] = "live"
    for j in list(paused_at):
        lapse(j, math.inf)
    changes.sort(key=lambda c: (c.tick, c.vehicle, ROSTER_STATES.index(c.state) if c.state != "live" else 9))
    return tuple(changes)

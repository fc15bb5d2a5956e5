"""From which tick does a run-time command apply? One rule for both clocks.

A command changes every vehicle from the same control tick, so that tick must be one no vehicle
has stepped yet when the change reaches it. What a clock knows is one tick, ``known``:

- lockstep: the highest tick the world has granted (a vehicle may have stepped it already,
  never one past it); the change can apply from the next: ``lead = 1``;
- realtime: the wall clock's tick now; the change must travel to every vehicle before the
  tick it names, so it applies :data:`LEAD_S` (0.5 s) of simulated time ahead:
  ``lead = lead_ticks(period)`` (at least 1).

The rule is then ``effect_tick(known, lead) = max(0, known + lead)`` for every command that names a
tick (gains, formation, path), and the first time a change named in simulated time (link,
radio) can take is that tick's start, ``effect_time``: a time asked that has passed, or none
asked, becomes it. A tick past the run's last is refused (:func:`never_applies`): it would be
answered "applied" and never apply. docs/ground_station.md ("When a change applies") is the
user's copy. The fleet's pause, resume and stop, and a vehicle's faults, are the clocks' own
(cdus.sim.lockstep, the world): they take no tick from here.
"""

from __future__ import annotations

import math

from cdus.wire.rejected import Rejected

#: s of simulated time a realtime change is sent ahead of the tick it applies from
LEAD_S = 0.5


def lead_ticks(period: float, lead_s: float = LEAD_S) -> int:
    """Control ticks (of ``period`` s) in ``lead_s`` s, at least 1: a realtime clock's lead."""
    return max(1, math.ceil(lead_s / period - 1e-9))


def effect_tick(known: int, lead: int) -> int:
    """The first tick a command can change on every vehicle alike, given the tick the clock
    knows (``known``: lockstep's granted, -1 before the first grant; realtime's now, negative
    before the clock starts) and its ``lead`` (>= 1); never before tick 0."""
    return max(0, known + max(1, lead))


def tick_of(at: float, period: float) -> int:
    """The first control tick at or after simulated time ``at`` (cdus.core.events.event_tick)."""
    return max(0, math.ceil(at / period - 1e-9))


def effect_time(asked: float | None, known: int, lead: int, period: float) -> tuple[float, str]:
    """The simulated time a change named in time (link, radio) applies from: ``asked`` if it is
    not before :func:`effect_tick`'s start, else that start (None asked: that start). With the
    note for the asker when an asked time had passed ("" otherwise)."""
    earliest = effect_tick(known, lead) * period
    if asked is None:
        return earliest, ""
    if asked < earliest:
        return earliest, f"t = {asked:g} s asked had passed: from the first time every vehicle can take it"
    return asked, ""


def never_applies(tick: int, last_tick: int, period: float) -> Rejected | None:
    """Why a change from ``tick`` would never apply (past the run's last tick), else None."""
    if tick <= last_tick:
        return None
    return Rejected(f"the run's last tick is {last_tick} (t = {last_tick * period:.2f} s) and the first this "
                    f"change could apply from is {tick}: it would never apply (the run is ending)")

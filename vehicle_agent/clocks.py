"""Which clock does this agent run on, and what has the world said about time?

The clock is picked once, here, where the agent starts (:func:`pick`): a lockstep or a
realtime strategy object (vehicle_agent.lockstep, vehicle_agent.realtime) that holds
everything the two clocks do differently: the run loop, the tick horizon an ω may carry, the
subscriptions, the per-sender rate limit, what a resume means, the telemetry batch. Nothing
else in vehicle_agent compares the clock's name.
"""

from __future__ import annotations

from dataclasses import dataclass

from cdus.core.schedule import CLOCKS
from vehicle_agent.lockstep import Lockstep
from vehicle_agent.realtime import Realtime

#: each clock's strategy by its name (cdus.core.schedule.CLOCKS)
STRATEGIES: dict[str, type[Lockstep] | type[Realtime]] = {"lockstep": Lockstep, "realtime": Realtime}
assert tuple(STRATEGIES) == CLOCKS


@dataclass
class Clock:
    """What the world has said about time: grants (lockstep) or t0 (realtime)."""

    begun: bool = False  # lockstep: the run started (at tick 0) or we were told where to join
    join: int = 0
    granted: int = -1
    t0: float | None = None
    paused: bool = False
    stop: bool = False


def pick(name: str, rate: float) -> Lockstep | Realtime:
    """The strategy of clock ``name`` (one of cdus.core.schedule.CLOCKS); ``rate``: the broadcast
    rate, ω per s, a neighbour sends (realtime's rate limit)."""
    if name not in STRATEGIES:
        raise ValueError(f"clock must be one of {CLOCKS}, got {name!r}")
    return STRATEGIES[name](rate)

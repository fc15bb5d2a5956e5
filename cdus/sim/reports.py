"""The fleet events every runner reports alike (docs/faults.md, "What gets reported").

`cdus sim`'s in-process fleet, the lockstep decisions and the world build their events
here, so one scenario gives the same kinds and texts whichever runs it.
"""

from __future__ import annotations

from typing import Iterable, Sequence

from cdus.core import graph as graphs
from cdus.wire.schemas import FleetEvent

Pair = tuple[str, str]


def scheduled_fault(tick: int, period: float, action: str, vid: str) -> FleetEvent:
    """A scheduled kill | pause | resume | restart, carried out at ``tick``."""
    t = tick * period
    return FleetEvent.of(t, "fault", f"scheduled {action} of {vid} (t = {t:g} s)", vehicle=vid)


def commanded_fault(tick: int, period: float, action: str, vid: str, by: str) -> FleetEvent:
    """A ground station's kill | pause | resume | restart, carried out at ``tick`` (lockstep)."""
    t = tick * period
    return FleetEvent.of(t, "fault", f"{action} of {vid} by {by} (t = {t:g} s)", vehicle=vid)


def vehicle_lost(t: float, vid: str) -> FleetEvent:
    return FleetEvent.of(t, "vehicle_lost", f"vehicle {vid} lost", vehicle=vid)


def vehicle_back(t: float, vid: str, joins_at: int | None = None) -> FleetEvent:
    text = f"vehicle {vid} back" + ("" if joins_at is None else f" (joins at tick {joins_at})")
    return FleetEvent.of(t, "vehicle_back", text, vehicle=vid)


def graph_event(t: float, ids: Sequence[str], pairs: Iterable[Pair], alive: Iterable[str]) -> FleetEvent:
    """Whether the graph of the live vehicles still has a spanning tree (a warning if not)."""
    live = set(alive)
    members = [v for v in ids if v in live]
    edges = [(i, k) for i, k in pairs if i in live and k in live]
    if not members:
        return FleetEvent.of(t, "graph", "no vehicle is live", severity="warn")
    cut = graphs.unreachable(members, edges)
    if cut:
        return FleetEvent.of(t, "graph", f"the live graph has no spanning tree: {', '.join(cut)} cut off",
                             severity="warn")
    return FleetEvent.of(t, "graph", f"the live graph ({len(members)} vehicles) still has a spanning tree")

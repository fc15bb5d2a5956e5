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


class ConsoleQuota:
    """What to print of a stream of events: every event, but only the first ``per_link``
    ``link_burst`` events of each link (a lossy link makes thousands), then one line saying
    the rest are in metrics.json. Returns the lines to print for ``event`` (maybe none)."""

    def __init__(self, per_link: int = 3):
        self.per_link = per_link
        self.seen: dict[str | None, int] = {}

    def lines(self, event: FleetEvent) -> list[str]:
        if event.kind != "link_burst":
            return [event.line()]
        n = self.seen[event.link] = self.seen.get(event.link, 0) + 1
        if n <= self.per_link:
            return [event.line()]
        if n == self.per_link + 1:
            return [f"(further drop bursts on {event.link or 'this link'} are not printed; the metrics' events "
                    "have them all)"]
        return []


def formation_changed(tick: int, period: float, phases: Iterable[tuple[str, float]], by: str | None = None
                      ) -> FleetEvent:
    """A formation change applied from ``tick``: the new phases (θ, ω units); ``by``: the ground
    station that asked, None for a scheduled one."""
    t = tick * period
    text = ", ".join(f"{vid} = {theta:.6g}" for vid, theta in phases)
    who = f" by {by}" if by else " (scheduled)"
    return FleetEvent.of(t, "formation_changed", f"formation phases {text} from tick {tick} (t = {t:g} s){who}")


def path_changed(tick: int, period: float, vid: str, table: Iterable[tuple[str, object]], by: str | None = None
                 ) -> FleetEvent:
    """Vehicle ``vid`` follows a new path (its table as sorted pairs) from ``tick``."""
    t = tick * period
    spec = dict(table)
    text = ", ".join(f"{k} = {list(v) if isinstance(v, tuple) else v}" for k, v in sorted(spec.items()))
    who = f" by {by}" if by else " (scheduled)"
    return FleetEvent.of(t, "path_changed", f"path of {vid}: {text} from tick {tick} (t = {t:g} s){who}",
                         vehicle=vid)

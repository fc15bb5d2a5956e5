"""Which fleet events does every runner report, and how are they worded? Alike in every runner
(docs/faults.md, "What gets reported").

`cdus sim`'s in-process fleet, the lockstep decisions and the world build their events
here, so one scenario gives the same kinds and texts whichever runs it.
"""

from __future__ import annotations

import re
from typing import Iterable, Sequence

from cdus.core import graph as graphs
from cdus.core.events import event_tick
from cdus.core.formation import FormationChange
from cdus.core.linkspec import LinkFaults
from cdus.core.obstacles import MEDIUM_OF_KIND, clearance, seen_by
from cdus.scenario.model import Scenario
from cdus.sim.build import start_point
from cdus.wire.bounds import is_number
from cdus.wire.schemas import FleetEvent
from cdus.wire.text import printable

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


def link_state_event(t: float, link: str, state: str) -> FleetEvent:
    """A directed link ``src->dst`` became up | lossy | down at ``t`` (its first message that saw it)."""
    return FleetEvent.of(t, "link_state", f"link {link} {state} (from t = {t:.2f} s)",
                         severity="warn" if state == "down" else "info", link=link)


_LINK_STATE = re.compile(r"link (\S+) (up|lossy|down) \(from t = ([0-9.]+) s\)")
NEWEST_LOOK_BACK = 512  # events newest_events looks back for the rest of a link change
LINK_GROUP_S = 1.0  # s: link_state events of one state this close together are one change (a command's)


def group_link_states(events: list[FleetEvent]) -> list[FleetEvent]:
    """``events`` with each run of ``link_state`` events into one state within LINK_GROUP_S of
    the run's first said once, where the first was: a ground station's ``link loss=0.1`` makes
    one event per directed link (12 on lake_circle), which filled the 8 lines of the status table
    and made 12 lines of the launcher's. The others are kept as they are, in order."""
    out: list[FleetEvent] = []
    groups: dict[str, tuple[int, float, list[str]]] = {}  # state -> (index in out, first t, links)
    for e in events:
        m = _LINK_STATE.fullmatch(e.text) if e.kind == "link_state" and e.link else None
        if m is None:
            out.append(e)
            continue
        state = m[2]
        g = groups.get(state)
        if g is None or not 0.0 <= e.t - g[1] <= LINK_GROUP_S or e.link in g[2]:
            groups[state] = (len(out), e.t, [e.link])
            out.append(e)
            continue
        g[2].append(e.link)
        names = ", ".join(g[2][:4]) + (f" and {len(g[2]) - 4} more" if len(g[2]) > 4 else "")
        out[g[0]] = FleetEvent.of(g[1], "link_state", f"{len(g[2])} links {state} (from t = {g[1]:.2f} s): {names}",
                                  severity=out[g[0]].severity)
    return out


def newest_events(events: Sequence[FleetEvent], n: int = 10) -> list[FleetEvent]:
    """The newest ``n`` of ``events`` with each link change whole (:func:`group_link_states`), in
    time order, for a status: a window of the newest 10 raw events cut a change of 12 links to
    "6 links lossy ... and 2 more". The window is widened back over the ``link_state`` events
    within LINK_GROUP_S of one in it (they arrive with each agent's counters, in no order of
    time), and until it holds ``n`` once grouped; at most NEWEST_LOOK_BACK events back."""
    end = len(events)
    start = max(0, end - n)
    while True:
        states = [e.t for e in events[start:] if e.kind == "link_state"]
        if states:
            first = min(states)
            for i in range(start - 1, max(0, end - NEWEST_LOOK_BACK) - 1, -1):
                e = events[i]
                if e.kind == "link_state" and e.t >= first - LINK_GROUP_S:
                    start, first = i, min(first, e.t)
        grouped = group_link_states(sorted(events[start:], key=lambda e: e.t))
        if len(grouped) >= n or start <= max(0, end - NEWEST_LOOK_BACK):
            return grouped[-n:]
        start = max(0, start - (n - len(grouped)))


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


#: link_state events before this simulated time that put a link in the state its [link] table
#: gives it (lossy: it delays, drops or duplicates) are the design, not news: one line says them
DESIGN_BEFORE_S = 1.0


def describe_faults(f: LinkFaults) -> str:
    """A link's random faults in a few words: "loss 0.1, delay 0.05 s (uniform jitter 0.01 s)"."""
    parts = []
    if f.loss > 0.0:
        parts.append(f"loss {f.loss:g}")
    if f.burst is not None and f.burst.active:
        parts.append(f"burst loss (p {f.burst.p:g}, r {f.burst.r:g}, about {f.burst.stationary_loss:.2g} of "
                     "messages)")
    if f.delay.active:
        parts.append(f"delay {f.delay.base:g} s" + (f" ({f.delay.distribution} jitter {f.delay.jitter:g} s)"
                                                    if f.delay.jitter > 0.0 else ""))
    if f.duplicate > 0.0:
        parts.append(f"duplicate {f.duplicate:g}")
    return ", ".join(parts)


def design_lines(scenario: Scenario) -> tuple[str, dict[str, str]]:
    """The links lossy by design (the scenario's [link] table and overrides): one summary line,
    "link faults from t = 0: loss 0.1 on 12 links (all)", groups of links with the same faults
    separated by "; " (the links named when a group has at most 4), and each lossy link's
    ``src->dst`` with its description. ("", {}) when no link is lossy by design."""
    links = sorted({(e.k, e.i) for e in scenario.edges}, key=lambda sd: (scenario.ids.index(sd[0]),
                                                                        scenario.ids.index(sd[1])))
    groups: dict[str, list[str]] = {}
    lossy: dict[str, str] = {}
    for src, dst in links:
        f = scenario.link.for_link(src, dst)
        if f.active:
            what = describe_faults(f)
            groups.setdefault(what, []).append(f"{src}->{dst}")
            lossy[f"{src}->{dst}"] = what
    if not groups:
        return "", {}
    total = len(links)
    parts = []
    for what, names in groups.items():
        n = len(names)
        where = (f"{n} links (all)" if n == total else f"{n} of {total} links"
                 + (f" ({', '.join(names)})" if n <= 4 else ""))
        parts.append(f"{what} on {where}")
    return "link faults from t = 0: " + "; ".join(parts), lossy


#: how many events past the end are named one by one (then one line counts the rest)
LATE_NAMED = 10


def _event_words(e: dict) -> str:
    """An [[event]] (validated) in a few words: ``kill usv2 at 300 s``, ``formation at 60 s``."""
    action, at = e.get("action"), e.get("at")
    if action in ("formation", "radio"):
        return f"{action} at {at:g} s"
    if action == "path":
        return f"path of {e.get('vehicle')} at {at:g} s"
    return f"{action} {e.get('vehicle')} at {at:g} s"


def late_event_lines(scenario: Scenario, duration: float | None = None) -> list[str]:
    """A note per ``[[event]]`` the run ends before (``at`` past ``duration``, by default the
    scenario's, e.g. shortened by --duration): accepted (a shorter run of a longer scenario is
    a legitimate use) but said once where the run starts, by ``cdus sim`` and ``cdus launch``
    alike. A pause whose ``duration`` ends past the run's end is named too (its resume will
    not apply). Every action counts: faults, formation and path changes, radio changes."""
    end = scenario.duration if duration is None else duration
    raw = scenario.raw.get("event", [])
    if not isinstance(raw, list):
        return []
    lines = []
    for j, e in enumerate(raw):
        at = e.get("at") if isinstance(e, dict) else None
        if not is_number(at):
            continue
        words = printable(_event_words(e), 200)
        if at > end:
            lines.append(f"note: event[{j}] ({words}) is past the run's end ({end:g} s): it will not apply")
        elif isinstance(e.get("duration"), (int, float)) and at + e["duration"] > end:
            lines.append(f"note: event[{j}] ({words} for {e['duration']:g} s) ends past the run's end ({end:g} s): "
                         f"its resume at {at + e['duration']:g} s will not apply")
    if len(lines) > LATE_NAMED:
        lines = lines[:LATE_NAMED] + [f"note: and {len(lines) - LATE_NAMED} more events past the run's end "
                                      f"({end:g} s): they will not apply"]
    return lines


def obstacle_lines(scenario: Scenario) -> list[str]:
    """Notes on the [[obstacle]]s a run is about to meet, said once where it starts (``cdus sim``
    and ``cdus launch``): the filter is off (they are only measured), an obstacle no vehicle of
    the fleet sees (a shape in the air with no drone, on the water with no boat), a vehicle that
    starts within an obstacle's margin (inside the solid is refused when the scenario is read:
    cdus.scenario.obstacles). Accepted all (a measured run without the filter is a legitimate
    use), never silent."""
    obstacles = scenario.obstacles
    if not obstacles:
        return []
    lines = []
    if not scenario.safety.enabled:
        lines.append(f"note: [safety] is off: the vehicles do not avoid the {len(obstacles)} [[obstacle]] "
                     f"table(s), their clearance is only measured (the metrics' obstacles block); "
                     f"set [safety] enabled = true (or --set safety.enabled=true) to keep them out")
    media = {MEDIUM_OF_KIND.get(v.kind) for v in scenario.vehicles}
    for o in obstacles:
        if o.medium not in media:
            who, other = (("drone", "a circle or a polygon for boats") if o.medium == "air"
                          else ("boat", "a cylinder or a box for drones"))
            lines.append(f"note: obstacle {printable(o.name, 64)} ({o.shape}) is seen by {who}s only and the "
                         f"fleet has no {who}: nothing avoids or measures it (use {other})")
    inside = []
    for v in scenario.vehicles:
        q0 = start_point(v)[0]
        for o in seen_by(v.kind, obstacles):
            d = clearance(o, q0).distance
            if d < o.margin:
                inside.append(f"note: {v.id} starts {d:.3g} m from it, within its margin {o.margin:g} m "
                              f"(obstacle {printable(o.name, 64)})"
                              + (": the filter pushes it out first" if scenario.safety.enabled else ""))
    if len(inside) > LATE_NAMED:
        inside = inside[:LATE_NAMED] + [f"note: and {len(inside) - LATE_NAMED} more vehicles start within an "
                                        f"obstacle's margin"]
    return lines + inside


#: the plants whose presets have limits (cdus.core.limits.default_limits): on them, no limit at
#: all leaves thrust, acceleration and speed unbounded
LIMITED_PLANTS = ("usv_3dof", "uav_double_integrator")


def limit_lines(scenario: Scenario) -> list[str]:
    """A note, said once where a run starts, naming the vehicles on a plant with preset limits
    (``usv_3dof``, ``uav_double_integrator``) that were given no limit at all: their actuators
    are then unbounded (a usv_3dof boat switched on with ``--set`` and no limits was driven to
    870 m/s), which is accepted (the dynamics alone are a legitimate study) but never silent."""
    bare: dict[str, list[str]] = {}
    for v in scenario.vehicles:
        if v.plant in LIMITED_PLANTS and not v.limits:
            bare.setdefault(v.plant, []).append(v.id)
    lines = []
    for plant, ids in bare.items():
        more = len(ids) - LATE_NAMED
        who = ", ".join(printable(i, 64) for i in ids[:LATE_NAMED]) + (f" and {more} more" if more > 0 else "")
        one = len(ids) == 1  # the fix as a --set too: the plant was often switched on with one
        fix = f"vehicle.{ids[0]}.limits.preset=true" if one else "defaults.limits.preset=true"
        lines.append(f"note: {who} ({plant}) {'has' if one else 'have'} no limits: thrust, acceleration and speed are "
                     f"unbounded; for the preset's, add limits = {{ preset = true }} to {'its [[vehicle]]' if one else 'their [[vehicle]]s'} "
                     f"or to [defaults] (or --set {fix}), or limits = {{ speed = ... }} "
                     f"(docs/config.md, 'Limits per preset')")
    return lines


class EventHold:
    """Events heard out of time order (link changes come with the agents' counters, up to a
    second late), each held HOLD_S of the hearer's clock, then given back in time order: what
    the launcher, ``cdus sim`` (:class:`ConsoleQuota`) and the console's log print from."""

    HOLD_S = 1.5  # s an event is held before due() gives it (the agents report once a second)

    def __init__(self) -> None:
        self._held: list[tuple[float, FleetEvent]] = []  # (when heard, event)

    def hold(self, event: FleetEvent, now: float) -> None:
        """``event`` heard at ``now`` (the hearer's clock, seconds)."""
        self._held.append((now, event))

    def due(self, now: float) -> list[FleetEvent]:
        """The events held HOLD_S or longer at ``now``, and with them every one held stamped no
        later than the newest of those (heard later, it would otherwise come after an event it
        preceded, and a link change heard over two batches be said in two), in time order."""
        ready = [e.t for at, e in self._held if now - at >= self.HOLD_S]
        if not ready:
            return []
        upto = max(ready)
        out = sorted((e for at, e in self._held if now - at >= self.HOLD_S or e.t <= upto), key=lambda e: e.t)
        self._held = [(at, e) for at, e in self._held if not (now - at >= self.HOLD_S or e.t <= upto)]
        return out

    def flush(self) -> list[FleetEvent]:
        """Every event held (the run is over), in time order."""
        ready, self._held = [e for _, e in self._held], []
        return sorted(ready, key=lambda e: e.t)


class ConsoleQuota:
    """What to print of a stream of events, the launcher's and ``cdus sim``'s alike
    (:meth:`printed`): every event, but

    - only the first ``per_link`` ``link_burst`` events of each link (a lossy link makes
      thousands), then one line saying the rest are in metrics.json;
    - with the ``scenario``: not a ``lossy`` line per link lossy by design as its first
      messages go out (before DESIGN_BEFORE_S), but one line for them all, at the first
      (:func:`design_lines`). A link's later changes (a down window, a ground station's
      command) are printed as they come.

    :meth:`lines` returns the lines to print for ``event`` (maybe none)."""

    HOLD_S = EventHold.HOLD_S  # s an event is held by hold() before due() prints it

    def __init__(self, per_link: int = 3, scenario: Scenario | None = None):
        self.per_link = per_link
        self.seen: dict[str | None, int] = {}
        self.design, self._lossy = design_lines(scenario) if scenario is not None else ("", {})
        self._design_said = False
        self._held = EventHold()  # see hold()

    def opening(self) -> list[str]:
        """The design line, once, as :meth:`printed` would give it at t = 0, for a printer that
        hears link states late (the launcher: with the agents' stats, a wall second into the run,
        after events stamped later); the lossy lines it stands for are then left out. Not
        thread-safe: a printer calling it and :meth:`printed` from two threads holds a lock."""
        if not self.design or self._design_said:
            return []
        self._design_said = True
        return [f"  event: {printable(FleetEvent.of(0.0, 'link_state', self.design).line())}"]

    def lines(self, event: FleetEvent) -> list[str]:
        if event.kind == "link_state" and event.link in self._lossy and event.t < DESIGN_BEFORE_S \
                and event.text == link_state_event(event.t, event.link, "lossy").text:
            del self._lossy[event.link]  # its first lossy line only: the design
            if self._design_said:
                return []
            self._design_said = True
            return [FleetEvent.of(event.t, "link_state", self.design).line()]
        if event.kind != "link_burst":
            return [event.line()]
        n = self.seen[event.link] = self.seen.get(event.link, 0) + 1
        if n <= self.per_link:
            return [event.line()]
        if n == self.per_link + 1:
            return [f"(further drop bursts on {event.link or 'this link'} are not printed; the metrics' events "
                    "have them all)"]
        return []

    def printed(self, event: FleetEvent) -> list[str]:
        """The console lines of ``event`` as the launcher and ``cdus sim`` print them."""
        return [f"  event: {printable(line)}" for line in self.lines(event)]

    # A printer that hears events out of time order (the launcher: link changes come with the
    # agents' counters, up to a second late) holds each for HOLD_S of its own clock, then prints
    # what is due in time order, a link change of many links as one line (group_link_states).

    def hold(self, event: FleetEvent, now: float) -> None:
        """``event`` heard at ``now`` (the printer's clock, seconds)."""
        self._held.hold(event, now)

    def due(self, now: float) -> list[str]:
        """The lines of the events held HOLD_S or longer at ``now``, in time order."""
        return self._in_order(self._held.due(now))

    def flush(self) -> list[str]:
        """The lines of every event held (the run is over)."""
        return self._in_order(self._held.flush())

    def _in_order(self, events: list[FleetEvent]) -> list[str]:
        items: list[FleetEvent] = []
        for e in events:
            lines = self.lines(e) if e.kind == "link_state" else None
            if lines is not None and (not lines or lines[0] != e.line()):  # the design line, or nothing
                items += [FleetEvent.of(e.t, "link_state", self.design)] if lines else []
                continue
            items.append(e)
        return [line for e in group_link_states(items) for line in self.printed(e)]


def formation_changed(tick: int, period: float, phases: Iterable[tuple[str, float]], by: str | None = None
                      ) -> FleetEvent:
    """A formation change applied from ``tick``: the new phases (θ, ω units); ``by``: the ground
    station that asked, None for a scheduled one."""
    t = tick * period
    text = ", ".join(f"{vid} = {theta:.6g}" for vid, theta in phases)
    who = f" by {by}" if by else " (scheduled)"
    what = f"formation phases {text}" if text else "formation unchanged (the offsets given were in force)"
    return FleetEvent.of(t, "formation_changed", f"{what} from tick {tick} (t = {t:g} s){who}")


def path_changed(tick: int, period: float, vid: str, table: Iterable[tuple[str, object]], by: str | None = None
                 ) -> FleetEvent:
    """Vehicle ``vid`` follows a new path (its table as sorted pairs) from ``tick``."""
    t = tick * period
    spec = dict(table)
    text = ", ".join(f"{k} = {list(v) if isinstance(v, tuple) else v}" for k, v in sorted(spec.items()))
    who = f" by {by}" if by else " (scheduled)"
    return FleetEvent.of(t, "path_changed", f"path of {vid}: {text} from tick {tick} (t = {t:g} s){who}",
                         vehicle=vid)


def radio_scheduled(tick: int, period: float, tx_power: float | None, station: Sequence[float] | None
                    ) -> FleetEvent:
    """A scheduled radio change (``[[event]] action = "radio"``) in force from ``tick`` (the first
    tick at or after its ``at``): the new transmit power and/or station, as every runner reports it."""
    t = tick * period
    parts = ([] if tx_power is None else [f"tx_power = {tx_power:g} dBm"]) + \
        ([] if station is None else [f"station = [{', '.join(f'{x:g}' for x in station)}] m"])
    return FleetEvent.of(t, "radio_changed", f"radio: {', '.join(parts)} from tick {tick} (t = {t:g} s) (scheduled)")


def scheduled_change_events(scenario: Scenario, period: float) -> dict[int, list[FleetEvent]]:
    """The events of the scenario's scheduled formation, path and radio changes, by the tick they
    apply from (the in-process fleet and the world report each when its tick is recorded)."""
    out: dict[int, list[FleetEvent]] = {}
    for change in scenario.changes:
        tick = event_tick(change.at, period)
        out.setdefault(tick, []).append(
            formation_changed(tick, period, change.phases) if isinstance(change, FormationChange)
            else path_changed(tick, period, change.vehicle, change.path))
    for rev in scenario.radio_events:
        tick = event_tick(rev.at, period)
        out.setdefault(tick, []).append(radio_scheduled(tick, period, rev.tx_power, rev.station))
    return out

"""Which alarms does the live console raise and clear? From the world's status alone (pure: no I/O,
no clock).

:class:`Alarms` takes each decoded status (a :class:`cdus.wire.status.WorldStatus`) in turn and
says which alarms it raises and which it clears, each stamped with the status's simulated
time. An alarm is raised once, stays active while its condition holds, and is cleared
once when it ends:

- ``vehicle_lost``: a vehicle the world's roster says is gone (killed, crashed, paused past
  its lease), or, from a world whose status has no roster states, one not alive;
- ``no_spanning_tree``: the coordination graph among the live vehicles has no directed
  spanning tree (some vehicle cannot be reached: its ω no longer agrees with the others');
- ``error_growing``: a live vehicle's path error |Φ| or a coordination edge's error (both
  ends live) has grown at every status for at least ``grow_s`` simulated seconds, to at
  least ``grow_factor`` times what it was and by at least ``grow_min``;
- ``separation``: the closest pair of live vehicles of one kind is nearer than the
  scenario's [safety] radius. A status without the radius cannot say: :attr:`Alarms.notes`
  says so, and no separation alarm is raised.

Statuses whose time does not advance (a paused fleet) or whose value is the same as the
last (the same status read again at a later time) change no growth; a time going back
(another run) starts the growth over.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

from cdus.core import graph as graphs
from cdus.wire.status import WorldStatus

KINDS = ("vehicle_lost", "no_spanning_tree", "error_growing", "separation")
GROW_S = 3.0  # s of simulated time an error must grow for
GROW_FACTOR = 1.5  # ... to at least this times its value when it started growing
GROW_MIN = 0.1  # ... and by at least this much (m or rad): a settled formation wobbles by less
NO_RADIUS = "separation: the world's status does not carry the [safety] radius, so no separation alarm"


@dataclass(frozen=True)
class Alarm:
    kind: str  # one of KINDS
    subject: str  # the vehicle, edge ("a-b"), path error ("|Φ| a") or "" for the fleet
    text: str  # what a person reads
    t: float  # simulated time it was raised

    @property
    def key(self) -> tuple[str, str]:
        return self.kind, self.subject


@dataclass(frozen=True)
class AlarmChange:
    raised: bool  # True: raised, False: cleared
    alarm: Alarm
    t: float  # simulated time of the change

    def line(self) -> str:
        verb = "ALARM" if self.raised else "cleared"
        return f"t = {self.t:.2f} s {verb}: {self.alarm.text}"


@dataclass
class _Growth:
    t0: float  # when it started growing
    x0: float  # its value then
    t: float  # the last sample
    x: float


@dataclass
class Alarms:
    grow_s: float = GROW_S
    grow_factor: float = GROW_FACTOR
    grow_min: float = GROW_MIN
    active: dict[tuple[str, str], Alarm] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    _growth: dict[str, _Growth] = field(default_factory=dict)
    _t: float | None = None

    def update(self, status: WorldStatus, last_heard: Mapping[str, float] | None = None) -> list[AlarmChange]:
        """The alarms this status raises and clears (cleared ones first), stamped with its time
        ``t``; a lost vehicle with the time it was last heard of, when ``last_heard`` (vehicle ->
        the time of its newest telemetry) has an earlier one. The status is decode_status's (every
        field checked there: one state per id, edges and the closest pair between its ids)."""
        t, ids = status.t, status.ids
        if status.states is not None:
            state = dict(zip(ids, status.states))
        else:
            alive = set(status.alive)
            state = {v: "live" if v in alive else "gone" for v in ids}
        live = [v for v in ids if state[v] == "live"]
        want: dict[tuple[str, str], str] = {}
        since: dict[tuple[str, str], float] = {}  # an alarm's time when known better than the status's
        heard = last_heard or {}
        for v in ids:
            if state[v] == "gone":
                want[("vehicle_lost", v)] = f"vehicle {v} lost"
                last = heard.get(v)
                if last is not None and last < t:  # its newest telemetry: when it was last heard of alive
                    since[("vehicle_lost", v)] = last
        edges = status.edges or []
        if edges and live:
            pairs = [(a, b) for a, b, _ in edges]
            if not status.directed:
                pairs += [(b, a) for a, b in pairs]
            live_set = set(live)
            cut = graphs.unreachable(live, [(a, b) for a, b in pairs if a in live_set and b in live_set])
            if cut:
                want[("no_spanning_tree", "")] = f"the live graph has no spanning tree: {', '.join(cut)} cut off"
        series = self._series(ids, state, edges, status.path_errors)
        for k in [k for k in self._growth if k not in series]:  # not measured now: its growth starts over
            del self._growth[k]
        for name, (x, unit) in series.items():
            g = self._grow(name, t, x)
            if g is not None and g.t - g.t0 >= self.grow_s - 1e-9 and g.x >= self.grow_factor * g.x0 \
                    and g.x - g.x0 >= self.grow_min:
                want[("error_growing", name)] = (f"{name} growing for {g.t - g.t0:.0f} s: "
                                                 f"{g.x0:.3g} -> {g.x:.3g} {unit}")
        radius = status.safety_radius
        self.notes = [] if radius is not None else [NO_RADIUS]
        if radius is not None and status.closest is not None:
            a, b, d = status.closest
            if d < radius and state[a] == "live" and state[b] == "live":
                want[("separation", "")] = f"{a} and {b} {d:.2f} m apart, below the safety radius {radius:g} m"
        self._t = t
        changes = [AlarmChange(False, a, t) for k, a in self.active.items() if k not in want]
        for k in [k for k in self.active if k not in want]:
            del self.active[k]
        for k, text in want.items():
            if k not in self.active:
                when = since.get(k, t)
                self.active[k] = Alarm(k[0], k[1], text, when)
                changes.append(AlarmChange(True, self.active[k], when))
        return changes

    @staticmethod
    def _series(ids: list[str], state: dict[str, str], edges: list, path_errors: list[float | None] | None) -> dict:
        """name -> (value, unit) of every error that is measured now (live ends only)."""
        out = {}
        for a, b, e in edges:
            if e is not None and state[a] == "live" and state[b] == "live":
                out[f"edge {a}-{b}"] = (e, "rad")
        for v, x in zip(ids, path_errors or []):
            if x is not None and state[v] == "live":
                out[f"|Φ| {v}"] = (x, "m")
        return out

    def _grow(self, name: str, t: float, x: float) -> _Growth | None:
        """The run of growth of series ``name`` ending at (t, x), or None if it is not growing."""
        g = self._growth.get(name)
        if g is None or t < g.t:  # new, or time went back
            self._growth[name] = _Growth(t, x, t, x)
            return None
        if t == g.t or x == g.x:  # no news (the same status again, read at a later time)
            return g if g.t > g.t0 else None
        if x > g.x:
            g.t, g.x = t, x
            return g
        self._growth[name] = _Growth(t, x, t, x)
        return None

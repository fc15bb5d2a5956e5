"""What do both runners do with the radio geometry? Samples, the communication graph, utilisation,
run-time changes.

The world process and the in-process fleet do the same with each radio geometry sample
(docs/radio.md, "Integration"): build it from the positions of the vehicles that stepped the
sample tick (:func:`geometry_sample`), put it through the wire codec once, hand it to the
vehicles (the world: on ``to/<set>/radio``; the fleet: to the shared RadioLink), and watch it
(:class:`RadioWatch`): the channel utilisation over time, each link's delivery probability
(for Rerun), and whether the communication graph (the scenario's edges whose delivery
probability is at least :data:`SPLIT_P`) still has a spanning tree among the live vehicles:
``radio_split`` when it stops having one, ``radio_joined`` when it has one again. Both
runners therefore report the same events at the same simulated times.

Run-time changes (``cdus gs radio tx_power=20 station=[x,y,z]``, a scheduled ``radio`` event):
:func:`radio_change_problem` checks one, :func:`apply_radio_change` applies it to a channel
for messages sent from ``at`` on.
"""

from __future__ import annotations

import math
from typing import Any, Iterable, Mapping, Sequence

from cdus.core import graph as graphs
from cdus.core.radio import Geometry
from cdus.core.radiolink import RadioCounters, as_point
from cdus.scenario.errors import ConfigError
from cdus.scenario.radio import validate_radio_update
from cdus.sim.runmetrics import RadioMetrics, Utilisation
from cdus.wire.messages import MAX_COORDINATE, GeometryMsg
from cdus.wire.schemas import FleetEvent

#: a link whose delivery probability is below this is out of the communication graph
SPLIT_P = 0.5
#: s a split (or a rejoin) must last before it is reported (stamped at its first sample): a link
#: at the edge of the range flickers with the shadowing, and one event per crossing is the news
SPLIT_HOLD = 2.0


def geometry_sample(tick: int, positions: Mapping[int, Sequence[float]], n: int,
                    dims: Sequence[int] | None = None) -> GeometryMsg:
    """The sample of ``tick``: vehicle j's position if it stepped the tick (``positions``), else None.
    A position the vehicles would refuse (cdus.wire.messages.decode_geometry: not finite, beyond
    MAX_COORDINATE, not of the vehicle's dimension ``dims[j]``) is None too: that vehicle is not
    heard, and the sample still goes out (refused, it would hold every lockstep vehicle forever)."""
    def fit(j: int, q: Sequence[float]) -> bool:
        return (len(q) in (2, 3) and (dims is None or len(q) == dims[j])
                and all(math.isfinite(x) and abs(x) <= MAX_COORDINATE for x in q))
    return GeometryMsg(tick, tuple(tuple(positions[j]) if j in positions and fit(j, positions[j]) else None
                                   for j in range(n)))


def radio_change_problem(change: Any, topology: str | None = None) -> str | None:
    """What is wrong with a run-time radio change ``{"tx_power": dBm, "station": [x, y(, z)]}``
    (either or both; cdus.scenario.radio.validate_radio_update), or None. Given the fleet's
    ``topology``, moving the station of an ``adhoc`` fleet (which has none) is refused too."""
    try:
        validate_radio_update(change, "radio command")
    except ConfigError as e:
        return str(e)
    if topology == "adhoc" and "station" in change:
        return ('radio.station: this fleet\'s radio is ad hoc (topology = "adhoc"): no station relays its '
                'messages, so moving one changes nothing; give tx_power only, or run a scenario with '
                'topology = "station"')
    return None


def apply_radio_change(channel: Any, change: dict, at: float) -> None:
    """A change (checked again here: :func:`radio_change_problem`) into ``channel`` for messages
    sent from ``at`` on."""
    tx, station = validate_radio_update(change, "radio command")
    channel.update(at, tx_power_dbm=tx, station=station)


class RadioWatch:
    """The world's (and the in-process fleet's) view of the radio: utilisation over time, link
    delivery probabilities, splits and rejoins of the communication graph (module docstring)."""

    def __init__(self, ids: Sequence[str], pairs: Iterable[tuple[str, str]], channel: Any, period: float,
                 threshold: float = SPLIT_P, hold: float = SPLIT_HOLD):
        self.ids = list(ids)
        self.index = {v: j for j, v in enumerate(self.ids)}
        self.pairs = [(i, k) for i, k in pairs]  # (listener, sender): i hears k
        self.channel = channel
        self.period = period
        self.threshold = threshold
        self.hold = hold
        self._pending: tuple[float, bool, list[str], int] | None = None  # (t, whole, cut, live) not reported yet
        self.utilisation: list[tuple[float, float]] = []  # (t of the sample, utilisation)
        self.links: dict[tuple[str, str], float] = {}  # (src, dst) -> delivery probability at the newest sample
        self.whole: bool | None = None  # has the communication graph a spanning tree (None: no sample yet)
        self.splits = 0
        self.station: tuple[float, float, float] | None = None
        self.points: dict[str, tuple[float, float, float]] = {}  # the newest sample's positions, by id

    def observe(self, msg: GeometryMsg) -> list[FleetEvent]:
        """Watch one (decoded) sample; the events it gives (a split or a rejoin)."""
        t = msg.tick * self.period
        geo = Geometry.of(msg.tick, tuple(None if q is None else as_point(q) for q in msg.positions), None)
        self.utilisation.append((t, float(self.channel.utilisation(geo))))
        if self.channel.spec.topology == "station":  # the station in force at the sample
            self.station = [st for start, _, st in self.channel.epochs if start <= t][-1]
        self.points = {v: as_point(q) for v, q in zip(self.ids, msg.positions) if q is not None}
        live = [v for v, q in zip(self.ids, msg.positions) if q is not None]
        alive = set(live)
        links = {}
        edges = []
        for i, k in self.pairs:
            if i in alive and k in alive:
                p = float(self.channel.delivery_probability(self.index[k], self.index[i], geo, t))
                links[(k, i)] = p
                if p >= self.threshold:
                    edges.append((i, k))
        self.links = links
        cut = graphs.unreachable(live, edges) if live else []
        whole = not cut
        if self.whole is None:  # the first sample: a fleet split from the start says so at once
            self.whole = whole
            if not whole:
                self.splits += 1
                return [self._event(t, whole, cut, len(live))]
            return []
        if whole == self.whole:
            self._pending = None
            return []
        if self._pending is None or self._pending[1] != whole:
            self._pending = (t, whole, cut, len(live))
        t0, _, cut0, n0 = self._pending
        if t - t0 < self.hold - 1e-9:
            return []
        self._pending = None
        self.whole = whole
        if not whole:
            self.splits += 1
        return [self._event(t0, whole, cut0, n0)]

    def _event(self, t: float, whole: bool, cut: list[str], live: int) -> FleetEvent:
        if whole:
            return FleetEvent.of(t, "radio_joined", f"radio: the communication graph is whole again ({live} live "
                                                    f"vehicles)")
        return FleetEvent.of(t, "radio_split", f"radio: the communication graph split (links with delivery probability "
                                               f"< {self.threshold:g} removed): {', '.join(cut)} cut off")

    def summary(self) -> dict:
        """``utilisation`` of the metrics' ``radio`` block: mean and max over the samples."""
        us = [u for _, u in self.utilisation]
        return {"mean": round(sum(us) / len(us), 9) if us else None, "max": round(max(us), 9) if us else None,
                "samples": len(us)}


def radio_metrics(counters: RadioCounters, watch: RadioWatch) -> RadioMetrics:
    """The metrics' ``radio`` block (docs/metrics.md): messages decided on the radio path,
    drops by cause (``fault``: the hand-set [link] fault; range, fading, collision, queue: the
    channel), channel utilisation (mean, max over the geometry samples) and the number of
    communication-graph splits."""
    return RadioMetrics(**counters.as_dict(), utilisation=Utilisation(**watch.summary()), splits=watch.splits)

"""The radio geometry in both runners: samples, the communication graph, utilisation, run-time changes.

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
from cdus.wire.messages import GeometryMsg
from cdus.wire.schemas import FleetEvent

#: a link whose delivery probability is below this is out of the communication graph
SPLIT_P = 0.5
RADIO_CHANGE_KEYS = ("tx_power", "station")
MAX_STATION = 1.0e6  # m: a station position's coordinates (a run-time change) stay within this
MAX_TX_POWER = 60.0  # dBm: 1 kW; a run-time change beyond is a typo
MIN_TX_POWER = -60.0


def geometry_sample(tick: int, positions: Mapping[int, Sequence[float]], n: int) -> GeometryMsg:
    """The sample of ``tick``: vehicle j's position if it stepped the tick (``positions``), else None."""
    return GeometryMsg(tick, tuple(tuple(positions[j]) if j in positions else None for j in range(n)))


def radio_change_problem(change: Any) -> str | None:
    """What is wrong with a run-time radio change ``{"tx_power": dBm, "station": [x, y, z]}``
    (at least one of the two), or None."""
    if not isinstance(change, dict) or not change:
        return "a radio change is a table with tx_power and/or station"
    extra = sorted(str(k) for k in change if k not in RADIO_CHANGE_KEYS)
    if extra:
        return f"unknown radio key(s) {', '.join(extra)}: use tx_power (dBm) and/or station ([x, y, z] m)"
    p = change.get("tx_power")
    if "tx_power" in change and (not isinstance(p, (int, float)) or isinstance(p, bool) or not math.isfinite(p)
                                 or not MIN_TX_POWER <= p <= MAX_TX_POWER):
        return f"tx_power must be a number of dBm in [{MIN_TX_POWER:g}, {MAX_TX_POWER:g}], got {p!r}"
    st = change.get("station")
    if "station" in change and (not isinstance(st, (list, tuple)) or len(st) != 3
                                or not all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                           and math.isfinite(x) and abs(x) <= MAX_STATION for x in st)):
        return f"station must be [x, y, z] in m (|x| <= {MAX_STATION:g}), got {st!r}"
    return None


def apply_radio_change(channel: Any, change: dict, at: float) -> None:
    """A checked change (:func:`radio_change_problem`) into ``channel`` from send time ``at`` on."""
    p = change.get("tx_power")
    st = change.get("station")
    channel.update(at, tx_power_dbm=None if p is None else float(p),
                   station=None if st is None else tuple(float(x) for x in st))


class RadioWatch:
    """The world's (and the in-process fleet's) view of the radio: utilisation over time, link
    delivery probabilities, splits and rejoins of the communication graph (module docstring)."""

    def __init__(self, ids: Sequence[str], pairs: Iterable[tuple[str, str]], channel: Any, period: float,
                 threshold: float = SPLIT_P):
        self.ids = list(ids)
        self.index = {v: j for j, v in enumerate(self.ids)}
        self.pairs = [(i, k) for i, k in pairs]  # (listener, sender): i hears k
        self.channel = channel
        self.period = period
        self.threshold = threshold
        self.utilisation: list[tuple[float, float]] = []  # (t of the sample, utilisation)
        self.links: dict[tuple[str, str], float] = {}  # (src, dst) -> delivery probability at the newest sample
        self.whole: bool | None = None  # has the communication graph a spanning tree (None: no sample yet)
        self.splits = 0
        self.station: tuple[float, float, float] | None = None
        self.points: dict[str, tuple[float, float, float]] = {}  # the newest sample's positions, by id

    def observe(self, msg: GeometryMsg) -> list[FleetEvent]:
        """Watch one (decoded) sample; the events it gives (a split or a rejoin)."""
        from cdus.core.radio import Geometry
        from cdus.core.radiolink import as_point
        t = msg.tick * self.period
        geo = Geometry.of(msg.tick, tuple(None if q is None else as_point(q) for q in msg.positions), None)
        self.utilisation.append((t, float(self.channel.utilisation(geo))))
        self.station = getattr(geo, "station", None)
        self.points = {v: as_point(q) for v, q in zip(self.ids, msg.positions) if q is not None}
        live = [v for v, q in zip(self.ids, msg.positions) if q is not None]
        alive = set(live)
        links = {}
        edges = []
        for i, k in self.pairs:
            if i in alive and k in alive:
                p = float(self.channel.delivery_probability(self.index[k], self.index[i], geo))
                links[(k, i)] = p
                if p >= self.threshold:
                    edges.append((i, k))
        self.links = links
        cut = graphs.unreachable(live, edges) if live else []
        out = []
        if cut and self.whole is not False:
            self.splits += 1
            out.append(FleetEvent.of(t, "radio_split", f"radio: the communication graph split (links with delivery "
                                                       f"probability < {self.threshold:g} removed): "
                                                       f"{', '.join(cut)} cut off"))
        elif not cut and self.whole is False:
            out.append(FleetEvent.of(t, "radio_joined", f"radio: the communication graph is whole again "
                                                        f"({len(live)} live vehicles)"))
        self.whole = not cut
        return out

    def summary(self) -> dict:
        """``utilisation`` of the metrics' ``radio`` block: mean and max over the samples."""
        us = [u for _, u in self.utilisation]
        return {"mean": round(sum(us) / len(us), 9) if us else None, "max": round(max(us), 9) if us else None,
                "samples": len(us)}


def radio_block(counters: Any, watch: RadioWatch) -> dict:
    """The metrics JSON's ``radio`` block (docs/metrics.md): messages decided on the radio path,
    drops by cause (``fault``: the hand-set [link] fault; range, fading, collision, queue: the
    channel), channel utilisation (mean, max over the geometry samples) and the number of
    communication-graph splits."""
    return {**counters.as_dict(), "utilisation": watch.summary(), "splits": watch.splits}

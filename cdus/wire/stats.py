"""What does a vehicle agent report about itself? Its counters, about once a second, to the world.

:class:`AgentStats` holds an agent's cumulative counters and the samples since its last
report: messages decided by its link model, rejects by reason, latencies, the link
emulator's counters (:data:`cdus.core.vocabulary.DROP_CAUSES`, ``LINK_STATES``), its bursts
of drops (:class:`BurstReport`), with [radio] its radio counters (``RADIO_CAUSES``), and a
``plant = "ros2"`` vehicle's spells without odometry (:class:`OdometryGap`).
:func:`decode_stats` checks every field, nested ones included, and rebuilds them from
numbers and ids (no map from the wire is passed on as it came), or returns Rejected.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, fields
from typing import Any, Collection

import msgpack

from cdus.core.vocabulary import DROP_CAUSES, FAULT_COUNTERS, LINK_STATES, RADIO_CAUSES
from cdus.wire.bounds import finite as _number
from cdus.wire.events import FleetEvent
from cdus.wire.fields import (MAX_COUNT, MAX_TIME, REASON_RE, SCHEMA_VERSION, known_id as _id, link_ends as _link,
                              unpack_map as _unpack)
from cdus.wire.rejected import Rejected

MAX_REASONS = 32
MAX_LATENCIES = 4096
MAX_BURSTS = 128  # vehicle_agent sends at most 100 (BURSTS_PER_STATS)
MAX_STATE_CHANGES = 64  # vehicle_agent sends its newest 50
MAX_LINKS = 256 * 255
MAX_ODOMETRY_GAPS = 16  # vehicle_agent.robot sends its newest 8


@dataclass(frozen=True)
class BurstReport:
    """A run of ``drops`` consecutive drops on link src->dst from t0 to t (an agent's
    link_burst event, rebuilt from its numbers and ids)."""

    t: float  # when it ended (the next message got through)
    t0: float
    src: str
    dst: str
    drops: int

    @property
    def link(self) -> str:
        return f"{self.src}->{self.dst}"

    def text(self) -> str:
        """The text cdus.core.link.burst_events writes."""
        return f"link {self.link}: {self.drops} messages dropped in a row ({self.t0:.2f}-{self.t:.2f} s)"

    def event(self, origin: str | None = None) -> FleetEvent:
        return FleetEvent.of(self.t, "link_burst", self.text(), link=self.link, origin=origin)


@dataclass(frozen=True)
class OdometryGap:
    """A robot's odometry missing (docs/ros2.md): its vehicle held from simulated time ``t`` (the
    tick it began to) to ``back`` (the tick it followed again; None: still holding)."""

    t: float
    back: float | None = None

    def as_dict(self) -> dict[str, float]:
        return {"t": self.t} if self.back is None else {"t": self.t, "back": self.back}


_BURST_TEXT = re.compile(r"^link ([A-Za-z0-9_-]{1,64})->([A-Za-z0-9_-]{1,64}): ([0-9]{1,12}) messages dropped in a "
                         r"row \(([0-9]{1,10}\.[0-9]{2})-([0-9]{1,10}\.[0-9]{2}) s\)$")


@dataclass(frozen=True)
class AgentStats:
    """A vehicle agent's counters (cumulative since it started) and samples since its last report."""

    id: str
    tick: int
    sent_to_me: int = 0  # messages addressed to this vehicle and decided by its link model
    delivered: int = 0
    dropped: int = 0
    duplicated: int = 0
    rejected: int = 0
    rejected_by_reason: dict[str, int] = field(default_factory=dict)
    missed_deadlines: int = 0
    joined_at: int = 0
    latencies_ms: tuple[float, ...] = ()  # new samples since the last report
    #: the link emulator's counters_summary(), newest state changes only; decoded: rebuilt
    #: from its checked numbers and ids ({"total", "links", "state_changes"})
    faults: dict | None = None
    #: new link_burst events: FleetEvent.as_dict() as an agent sends them; decoded: BurstReport
    bursts: tuple[Any, ...] = ()
    interventions: int = 0  # control steps at which the safety filter changed the velocity reference
    deflected: int = 0  # of those, the steps at which an [[obstacle]]'s row bound (cdus.core.vehicle)
    incarnation: int = 0  # drawn at random when the process starts: a new value is a new process (a restart)
    #: with [radio]: its RadioLink's counters ({sent, delivered, dropped, dropped_by: {fault, range,
    #: fading, collision, queue}, no_geometry}; cdus.core.radiolink.RadioCounters.as_dict); None without
    radio: dict | None = None
    #: a plant = "ros2" vehicle's newest spells without odometry, oldest first (empty for the others)
    odometry_gaps: tuple[OdometryGap, ...] = ()
    #: the agent's last report, sent as it closes its session after the world's stop: the world
    #: waits for no more from it before writing the metrics (world_sim.finish)
    final: bool = False

    def as_dict(self) -> dict[str, Any]:
        """A plain map of every field (containers copied): what encode_stats packs. Built field
        by field: dataclasses.asdict deep-copied every leaf, 88 µs of the 139 µs an agent spent
        on its once-a-second report (bench/realtime_capacity.py)."""
        d = {name: getattr(self, name) for name in _STAT_NAMES}
        d["rejected_by_reason"] = dict(self.rejected_by_reason)
        d["latencies_ms"] = list(self.latencies_ms)
        d["faults"] = _copy_tree(self.faults)
        d["bursts"] = [b.event().as_dict() if isinstance(b, BurstReport) else b for b in self.bursts]
        d["odometry_gaps"] = [g.as_dict() for g in self.odometry_gaps]
        return d


def _copy_tree(x: Any) -> Any:
    """A copy of nested dicts, lists and tuples (their leaves, numbers and strings, shared)."""
    if isinstance(x, dict):
        return {k: _copy_tree(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return type(x)(_copy_tree(v) for v in x)
    return x


_STAT_NAMES = tuple(f.name for f in fields(AgentStats))


_STAT_INTS = ("tick", "sent_to_me", "delivered", "dropped", "duplicated", "rejected", "missed_deadlines", "joined_at",
              "interventions", "incarnation", "deflected")
_STAT_FIELDS = {"v", "id", "rejected_by_reason", "latencies_ms", "faults", "bursts", "radio", "odometry_gaps",
                "final", *_STAT_INTS}


def encode_stats(s: AgentStats) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, **s.as_dict()}, use_bin_type=True)


def decode_stats(payload: bytes, ids: Collection[str] | None = None) -> AgentStats | Rejected:
    """An agent's stats, every field checked (``ids``: the fleet's vehicle ids, when known:
    the sender and every link must name them), or the reason: ``oversized``, ``malformed``,
    ``version``, ``unknown_field``, ``type``, ``range``, ``deflected`` (more deflected steps
    than interventions), ``unknown_sender``, ``reasons``,
    ``latencies``, ``faults``, ``bursts``, ``radio``, ``odometry_gaps``."""
    obj = _unpack(payload, limit=1 << 16)
    if isinstance(obj, Rejected):
        return obj
    if obj.get("v") != SCHEMA_VERSION:
        return Rejected("version")
    if not set(obj) <= _STAT_FIELDS:
        return Rejected("unknown_field")
    vid, final = obj.get("id"), obj.get("final", False)
    if not isinstance(vid, str) or type(final) is not bool:
        return Rejected("type")
    if not _id(vid, ids):
        return Rejected("unknown_sender")
    ints = {k: obj.get(k, 0) for k in _STAT_INTS}
    if not all(type(x) is int and x >= 0 for x in ints.values()):
        return Rejected("type")
    if not all(x < MAX_COUNT for x in ints.values()):
        return Rejected("range")
    if ints["deflected"] > ints["interventions"]:  # deflected steps are among those the filter changed
        return Rejected("deflected")
    by = obj.get("rejected_by_reason", {})
    lat = obj.get("latencies_ms", [])
    faults = obj.get("faults")
    bursts = obj.get("bursts", [])
    if not isinstance(by, dict) or not isinstance(lat, list) or faults is not None and not isinstance(faults, dict) \
            or not isinstance(bursts, list):
        return Rejected("type")
    if not all(isinstance(k, str) and type(x) is int for k, x in by.items()) or not all(_number(x) for x in lat):
        return Rejected("type")
    if len(by) > MAX_REASONS or not all(REASON_RE.match(k) and 0 <= x < MAX_COUNT for k, x in by.items()):
        return Rejected("reasons")
    if len(lat) > MAX_LATENCIES or not all(0 <= x <= 1e7 for x in lat):
        return Rejected("latencies")
    checked = None
    if faults is not None:
        checked = _faults(faults, ids)
        if checked is None:
            return Rejected("faults")
    if len(bursts) > MAX_BURSTS:
        return Rejected("bursts")
    reports = tuple(_burst(b, ids) for b in bursts)
    if not all(reports):
        return Rejected("bursts")
    radio = obj.get("radio")
    if radio is not None:
        radio = _radio_counters(radio)
        if radio is None:
            return Rejected("radio")
    gaps = _odometry_gaps(obj.get("odometry_gaps", []))
    if gaps is None:
        return Rejected("odometry_gaps")
    return AgentStats(vid, rejected_by_reason={k: int(x) for k, x in by.items()},
                      latencies_ms=tuple(float(x) for x in lat), faults=checked, bursts=reports, radio=radio,
                      odometry_gaps=gaps, final=final, **ints)


def _odometry_gaps(x: Any) -> tuple[OdometryGap, ...] | None:
    """A robot's spells without odometry, rebuilt from their numbers, or None: at most
    MAX_ODOMETRY_GAPS, each within 0..MAX_TIME and back at or after it began, in order without
    overlap, only the newest still open."""
    if not isinstance(x, list) or len(x) > MAX_ODOMETRY_GAPS:
        return None
    out: list[OdometryGap] = []
    for d in x:
        if not isinstance(d, dict) or "t" not in d or not set(d) <= {"t", "back"}:
            return None
        t, back = d["t"], d.get("back")
        if not _number(t) or not 0 <= t <= MAX_TIME:
            return None
        if back is not None and not (_number(back) and t <= back <= MAX_TIME):
            return None
        if out and (out[-1].back is None or t < out[-1].back):
            return None
        out.append(OdometryGap(float(t), None if back is None else float(back)))
    return tuple(out)


def _radio_counters(d: Any) -> dict | None:
    """A RadioLink's counters block, checked and rebuilt, or None."""
    if not isinstance(d, dict) or set(d) != {"sent", "delivered", "dropped", "dropped_by", "no_geometry"}:
        return None
    by = d["dropped_by"]
    if not isinstance(by, dict) or set(by) != set(RADIO_CAUSES):
        return None
    nums = [d["sent"], d["delivered"], d["dropped"], d["no_geometry"], *(by[c] for c in RADIO_CAUSES)]
    if not all(type(x) is int and 0 <= x < MAX_COUNT for x in nums):
        return None
    return {"sent": d["sent"], "delivered": d["delivered"], "dropped": d["dropped"],
            "dropped_by": {c: by[c] for c in RADIO_CAUSES}, "no_geometry": d["no_geometry"]}


def _counter_block(d: Any) -> dict | None:
    """A {sent, dropped, dropped_by: {loss, burst, down, partition}, duplicated, delayed} block, rebuilt."""
    if not isinstance(d, dict) or set(d) != {*FAULT_COUNTERS, "dropped_by"}:
        return None
    by = d["dropped_by"]
    if not isinstance(by, dict) or set(by) != set(DROP_CAUSES):
        return None
    nums = [d[k] for k in FAULT_COUNTERS] + [by[k] for k in DROP_CAUSES]
    if not all(type(x) is int and 0 <= x < MAX_COUNT for x in nums):
        return None
    return {"sent": d["sent"], "dropped": d["dropped"], "dropped_by": {c: by[c] for c in DROP_CAUSES},
            "duplicated": d["duplicated"], "delayed": d["delayed"]}


def _faults(d: dict, ids: Collection[str] | None) -> dict | None:
    """The link emulator's counters_summary(), checked field by field and rebuilt, or None."""
    if set(d) != {"total", "links", "state_changes"}:
        return None
    total, links, changes = _counter_block(d["total"]), d["links"], d["state_changes"]
    if total is None or not isinstance(links, dict) or not isinstance(changes, list) \
            or len(links) > MAX_LINKS or len(changes) > MAX_STATE_CHANGES:
        return None
    out_links = {}
    for name, block in links.items():
        ends = _link(name, ids) if isinstance(name, str) else None
        b = _counter_block(block)
        if ends is None or b is None:
            return None
        out_links[f"{ends[0]}->{ends[1]}"] = b
    out_changes = []
    for ch in changes:
        if not isinstance(ch, dict) or set(ch) != {"t", "link", "state"}:
            return None
        t, link, state = ch["t"], ch["link"], ch["state"]
        ends = _link(link, ids) if isinstance(link, str) else None
        if not _number(t) or not 0 <= t <= MAX_TIME or ends is None or state not in LINK_STATES:
            return None
        out_changes.append({"t": float(t), "link": f"{ends[0]}->{ends[1]}", "state": str(state)})
    return {"total": total, "links": out_links, "state_changes": out_changes}


def _burst(d: Any, ids: Collection[str] | None) -> BurstReport | None:
    """A link_burst event an agent sent (FleetEvent.as_dict()), rebuilt from its numbers and ids."""
    if not isinstance(d, dict) or not set(d) <= {"t", "kind", "text", "severity", "link", "origin"}:
        return None
    t, text, link = d.get("t"), d.get("text"), d.get("link")
    if d.get("kind") != "link_burst" or not _number(t) or not 0 <= t <= MAX_TIME or not isinstance(text, str) \
            or not isinstance(link, str):
        return None
    m = _BURST_TEXT.match(text)
    ends = _link(link, ids)
    if m is None or ends is None or (m[1], m[2]) != ends:
        return None
    drops, t0 = int(m[3]), float(m[4])
    if drops < 1 or t0 > t + 0.01:  # the text's times are rounded to 10 ms
        return None
    return BurstReport(float(t), t0, ends[0], ends[1], drops)

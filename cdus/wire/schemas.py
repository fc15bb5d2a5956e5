"""The fleet's reports, each with one versioned schema: events, agent stats, world status.

- :class:`FleetEvent`: something a person should know (a vehicle lost, a link down, a
  scheduled fault carried out), with a ``kind`` and a ``severity`` a program can act on,
  a ``text`` a person reads, and its ``origin`` (who saw it: ``world``, or the vehicle
  whose counters reported it). The world publishes them, the metrics JSON lists them,
  the Rerun event log shows them; the in-process fleet makes the same ones.
- :class:`AgentStats`: a vehicle agent's counters, about once a second, to the world.
- world status: the world's summary, about once a second, for ground stations and the
  launcher (:func:`encode_status` / :func:`decode_status`).

Every decoder validates every field, nested ones included, into typed records rebuilt
from numbers and ids (no map from the wire is passed on as it came), and never raises:
it returns the record or :class:`cdus.wire.rejected.Rejected` (the reason), so a receiver counts and drops.
Texts from the wire come out escaped (:func:`cdus.wire.text.printable`), safe to print.
"""

from __future__ import annotations

import hashlib
import hmac
import math
import re
from dataclasses import asdict, dataclass, field, fields
from typing import Any, Collection

import msgpack

from cdus.core.vocabulary import CLOCKS, DROP_CAUSES, FAULT_COUNTERS, KINDS, LINK_STATES, RADIO_CAUSES, ROSTER_STATES
from cdus.wire.bounds import finite as _number
from cdus.wire.messages import CTL_OPS, MAX_CONTROL_PAYLOAD, MSGPACK_ERRORS, SEQUENCED, decode_control
from cdus.wire.rejected import Rejected
from cdus.wire.text import printable

SCHEMA_VERSION = 1
SEVERITIES = ("info", "warn", "error")
#: event kind -> its severity
EVENT_KINDS: dict[str, str] = {
    "vehicle_lost": "warn",  # a vehicle's liveliness token went away
    "vehicle_back": "info",  # ... and came back
    "graph": "info",  # whether the live graph still has a spanning tree (severity warn if not)
    "fault": "warn",  # a scheduled vehicle fault carried out (kill, pause, resume, restart)
    "fault_missed": "error",  # a scheduled fault nobody carried out
    "gave_up": "error",  # the launcher used up a vehicle's restarts ([supervision] max_restarts)
    "link_state": "info",  # a directed link became up, lossy or down (warn for down)
    "link_burst": "warn",  # a run of consecutive drops on a link
    "link_changed": "info",  # link faults changed at run time
    "gains_changed": "info",  # guidance gains changed at run time
    "formation_changed": "info",  # the formation's phases changed (scheduled or commanded)
    "path_changed": "info",  # a vehicle's path changed (scheduled or commanded)
    "fleet": "info",  # the fleet paused, resumed or stopped
    "rejected": "warn",  # a command or message was rejected
    "suspect": "warn",  # a vehicle received ω that its sender cannot have sent (future, conflict, implausible)
    "radio_split": "warn",  # [radio]: the communication graph (links likely to deliver) lost its spanning tree
    "radio_joined": "info",  # ... and has one again
    "radio_changed": "info",  # [radio]: transmit power or the station changed at run time
    "recording_stopped": "warn",  # the world's .rrd file could not be written on (a full disk): the run goes on
}
MAX_TEXT = 300
MAX_ID = 64
ID_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")  # vehicle and process ids (cdus.wire.keys)
REASON_RE = re.compile(r"^[a-z0-9_]{1,40}$")  # a reject reason's name
MAX_TIME = 1e9  # s: a plausible simulated time (31 years); anything beyond is not a run's
MAX_COUNT = 2**53  # a counter beyond this is not a count a process can have made
MAX_REASONS = 32
MAX_LATENCIES = 4096
MAX_BURSTS = 128  # vehicle_agent sends at most 100 (BURSTS_PER_STATS)
MAX_STATE_CHANGES = 64  # vehicle_agent sends its newest 50
MAX_LINKS = 256 * 255
MAX_STATUS_IDS = 4096
MAX_STATUS_EVENTS = 64
ORIGIN_WORLD = "world"
ORIGINS = (ORIGIN_WORLD, "launcher")  # the processes that are not vehicles and report events


@dataclass(frozen=True)
class FleetEvent:
    t: float  # simulated seconds
    kind: str
    text: str
    severity: str = "info"
    vehicle: str | None = None
    link: str | None = None  # "src->dst"
    origin: str | None = None  # who saw it: "world", or the vehicle whose report it came from

    @staticmethod
    def of(t: float, kind: str, text: str, *, severity: str | None = None, vehicle: str | None = None,
           link: str | None = None, origin: str | None = None) -> "FleetEvent":
        """An event with its kind's default severity unless one is given."""
        return FleetEvent(t, kind, text[:MAX_TEXT], severity or EVENT_KINDS[kind], vehicle, link, origin)

    def line(self) -> str:
        """How a person reads it in a log."""
        return f"t = {self.t:.2f} s: {printable(self.text, MAX_TEXT)}"

    def as_dict(self) -> dict[str, Any]:
        return {k: v for k, v in asdict(self).items() if v is not None}


def event_from_dict(d: Any, ids: Collection[str] | None = None) -> FleetEvent | Rejected:
    """A FleetEvent from a decoded map (every field checked; the text escaped), or the reason.
    ``ids``: the fleet's vehicle ids, when the receiver knows them."""
    if not isinstance(d, dict):
        return Rejected("malformed")
    if not set(d) <= {"v", "t", "kind", "text", "severity", "vehicle", "link", "origin"}:
        return Rejected("unknown_field")
    t, kind, text, sev = d.get("t"), d.get("kind"), d.get("text"), d.get("severity", "info")
    if not _number(t) or not isinstance(kind, str) or kind not in EVENT_KINDS or not isinstance(text, str) \
            or not isinstance(sev, str) or sev not in SEVERITIES:
        return Rejected("type")
    if not 0 <= t <= MAX_TIME:
        return Rejected("range")
    veh, link, origin = d.get("vehicle"), d.get("link"), d.get("origin")
    if veh is not None and not isinstance(veh, str) or link is not None and not isinstance(link, str) \
            or origin is not None and not isinstance(origin, str):
        return Rejected("type")
    if veh is not None and not _id(veh, ids) or link is not None and _link(link, ids) is None \
            or origin is not None and not (origin in ORIGINS or _id(origin, ids)):
        return Rejected("unknown_sender")
    return FleetEvent(float(t), kind, printable(text, MAX_TEXT), sev, veh, link, origin)


def encode_event(e: FleetEvent) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, **e.as_dict()}, use_bin_type=True)


def decode_event(payload: bytes, ids: Collection[str] | None = None) -> FleetEvent | Rejected:
    obj = _unpack(payload)
    if isinstance(obj, Rejected):
        return obj
    if obj.get("v") != SCHEMA_VERSION:
        return Rejected("version")
    return event_from_dict(obj, ids)


# --------------------------------------------------------------------------- agent stats


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
    incarnation: int = 0  # drawn at random when the process starts: a new value is a new process (a restart)
    #: with [radio]: its RadioLink's counters ({sent, delivered, dropped, dropped_by: {fault, range,
    #: fading, collision, queue}, no_geometry}; cdus.core.radiolink.RadioCounters.as_dict); None without
    radio: dict | None = None

    def as_dict(self) -> dict[str, Any]:
        """A plain map of every field (containers copied): what encode_stats packs. Built field
        by field: dataclasses.asdict deep-copied every leaf, 88 µs of the 139 µs an agent spent
        on its once-a-second report (bench/realtime_capacity.py)."""
        d = {name: getattr(self, name) for name in _STAT_NAMES}
        d["rejected_by_reason"] = dict(self.rejected_by_reason)
        d["latencies_ms"] = list(self.latencies_ms)
        d["faults"] = _copy_tree(self.faults)
        d["bursts"] = [b.event().as_dict() if isinstance(b, BurstReport) else b for b in self.bursts]
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
              "interventions", "incarnation")
_STAT_FIELDS = {"v", "id", "rejected_by_reason", "latencies_ms", "faults", "bursts", "radio", *_STAT_INTS}


def encode_stats(s: AgentStats) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, **s.as_dict()}, use_bin_type=True)


def decode_stats(payload: bytes, ids: Collection[str] | None = None) -> AgentStats | Rejected:
    """An agent's stats, every field checked (``ids``: the fleet's vehicle ids, when known:
    the sender and every link must name them), or the reason: ``oversized``, ``malformed``,
    ``version``, ``unknown_field``, ``type``, ``range``, ``unknown_sender``, ``reasons``,
    ``latencies``, ``faults``, ``bursts``."""
    obj = _unpack(payload, limit=1 << 16)
    if isinstance(obj, Rejected):
        return obj
    if obj.get("v") != SCHEMA_VERSION:
        return Rejected("version")
    if not set(obj) <= _STAT_FIELDS:
        return Rejected("unknown_field")
    vid = obj.get("id")
    if not isinstance(vid, str):
        return Rejected("type")
    if not _id(vid, ids):
        return Rejected("unknown_sender")
    ints = {k: obj.get(k, 0) for k in _STAT_INTS}
    if not all(type(x) is int and x >= 0 for x in ints.values()):
        return Rejected("type")
    if not all(x < MAX_COUNT for x in ints.values()):
        return Rejected("range")
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
    return AgentStats(vid, rejected_by_reason={k: int(x) for k, x in by.items()},
                      latencies_ms=tuple(float(x) for x in lat), faults=checked, bursts=reports, radio=radio, **ints)


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


# --------------------------------------------------------------------------- world status

COMPLETED = "completed"  # the completion of a run that stepped every tick to its end (docs/metrics.md)
#: why a run did not complete: SIGINT/SIGTERM; a ground station's stop; vehicles lost with nobody
#: asking and not back by the end; the whole fleet gone with the world's router; the world died
#: (written by the launcher); the vehicles never all came up
COMPLETIONS = (COMPLETED, "interrupted", "stopped", "vehicles_lost", "router_lost", "world_lost", "not_started")

STATUS_KEYS = ("t", "duration", "clock", "alive", "ids", "path_error_max", "coord_error_max", "events", "paused",
               "roster")
#: optional fields (added within version 1; a status without them is still valid, and decodes
#: with them absent): what a live console shows and raises alarms on (docs/console.md)
#: - kinds: each vehicle's kind ("usv" | "uav"), in ``ids`` order
#: - states: each vehicle's state in the world's roster ("live" | "paused" | "gone"), in ``ids`` order
#: - edges: [a, b, error (rad) or None when an end is not live] per coordination edge, at the newest tick
#: - links: [src, dst, sent, dropped, state] per directed link the link emulator decides (a link with faults)
#: - rx: [ω messages addressed to the vehicle, dropped] per vehicle (None before its first counters)
#: - safety_radius: the scenario's [safety] radius R (m, its default when the table is absent)
#: - closest: [a, b, distance (m)]: the closest pair of live vehicles of one kind at the newest tick
#: - path_errors: each vehicle's |Φ| (m) at the newest tick, None where it is not live, in ``ids`` order
#: - directed: whether the graph is directed (``edges`` then go i -> k as the scenario's; else each pair once)
#: - completion: the run is over, and how (COMPLETIONS): the world's last status, sent before it
#:   tells the vehicles to stop, so their leaving is not read as vehicles lost
STATUS_EXTRA = ("kinds", "states", "edges", "links", "rx", "safety_radius", "closest", "path_errors", "directed",
                "completion")
MAX_STATUS_EDGES = 512
MAX_STATUS_LINKS = 512


@dataclass(frozen=True)
class StatusExtra:
    """The optional status fields the world fills in (see STATUS_EXTRA)."""

    kinds: list[str] | None = None
    states: list[str] | None = None
    edges: list[tuple[str, str, float | None]] | None = None
    links: list[tuple[str, str, int, int, str | None]] | None = None
    rx: list[tuple[int, int] | None] | None = None
    safety_radius: float | None = None
    closest: tuple[str, str, float] | None = None
    path_errors: list[float | None] | None = None
    directed: bool | None = None
    completion: str | None = None

    def as_dict(self) -> dict[str, Any]:
        d = {"kinds": self.kinds, "states": self.states,
             "edges": None if self.edges is None else [[a, b, _finite(e)] for a, b, e in self.edges[:MAX_STATUS_EDGES]],
             "links": None if self.links is None else [list(x) for x in self.links[:MAX_STATUS_LINKS]],
             "rx": None if self.rx is None else [None if r is None else list(r) for r in self.rx],
             "safety_radius": _finite(self.safety_radius),
             "closest": None if self.closest is None or _finite(self.closest[2]) is None else list(self.closest),
             "path_errors": None if self.path_errors is None else [_finite(x) for x in self.path_errors],
             "directed": self.directed, "completion": self.completion}
        return {k: v for k, v in d.items() if v is not None}


STATUS_LIMIT = 1 << 16  # bytes: decode_status takes no bigger status

#: The environment variable a launcher hands its world a per-run key in (hex): the world signs
#: each status it publishes with it (:func:`status_signature`, as the sample's Zenoh attachment),
#: and the launcher believes only statuses so signed: on an open fleet anyone may publish on
#: ``world/status``, and a forged one must not reach the launcher's ``world_lost`` metrics.
#: In the environment, not the command line: other users cannot read it (ps shows arguments).
STATUS_KEY_ENV = "CDUS_STATUS_KEY"


def status_signature(key: bytes, payload: bytes) -> bytes:
    """HMAC-SHA256 of a status payload under the run's key (16 bytes of it)."""
    return hmac.new(key, payload, hashlib.sha256).digest()[:16]


def signed_by(key: bytes, payload: bytes, attachment: bytes | None) -> bool:
    """Was ``payload`` signed under ``key`` (compared in constant time)?"""
    return attachment is not None and hmac.compare_digest(attachment, status_signature(key, payload))


def encode_status(t: float, duration: float, clock: str, alive: list[str], ids: list[str],
                  path_error_max: float | None, coord_error_max: float | None, events: list[FleetEvent],
                  paused: bool, roster: dict[str, str] | None = None,
                  extra: StatusExtra | None = None) -> bytes:
    """The status; the ``extra`` fields only as far as they fit in STATUS_LIMIT (a fleet of
    thousands: first the edges and links are left out, then the rest), never the summary."""
    base = {"v": SCHEMA_VERSION, "t": t, "duration": duration, "clock": clock, "alive": alive, "ids": ids,
            "path_error_max": _finite(path_error_max), "coord_error_max": _finite(coord_error_max),
            "events": [e.as_dict() for e in events], "paused": paused}
    if roster is not None:
        base["roster"] = roster
    more = extra.as_dict() if extra else {}
    for fields in (more, {k: v for k, v in more.items() if k not in ("edges", "links")},
                   {k: v for k, v in more.items() if k == "completion"}):
        out = msgpack.packb({**base, **fields}, use_bin_type=True)
        if len(out) <= STATUS_LIMIT:
            break
    return out


def decode_status(payload: bytes, ids: Collection[str] | None = None) -> dict[str, Any] | Rejected:
    """The world's status as a dict (STATUS_KEYS, and those of STATUS_EXTRA it carries; events
    as FleetEvent; ``roster`` None when the world did not send it), or the reject reason. Every field is checked: times finite and plausible,
    the clock a known one, ``alive`` a subset of ``ids`` (and ``ids`` the receiver's, when it
    knows them), errors finite or None, ``paused`` a bool, at most MAX_STATUS_EVENTS events,
    each a valid one (an invalid event is left out); the optional fields as STATUS_EXTRA says
    (``extra``: the reason when one is not)."""
    obj = _unpack(payload, limit=STATUS_LIMIT)
    if isinstance(obj, Rejected):
        return obj
    if obj.get("v") != SCHEMA_VERSION:
        return Rejected("version")
    if not set(obj) <= {"v", *STATUS_KEYS, *STATUS_EXTRA}:
        return Rejected("unknown_field")
    t, duration, alive, sids, events = obj.get("t"), obj.get("duration"), obj.get("alive"), obj.get("ids"), \
        obj.get("events")
    errors = (obj.get("path_error_max"), obj.get("coord_error_max"))
    if (not _number(t) or not _number(duration) or not isinstance(obj.get("clock"), str)
            or not _strings(alive) or not _strings(sids) or not isinstance(events, list)
            or not all(x is None or _number(x) for x in errors) or type(obj.get("paused", False)) is not bool):
        return Rejected("type")
    if not -1.0 <= t <= MAX_TIME or not 0 <= duration <= MAX_TIME or obj["clock"] not in CLOCKS \
            or not all(x is None or x >= 0 for x in errors):
        return Rejected("range")
    if len(sids) > MAX_STATUS_IDS or len(events) > MAX_STATUS_EVENTS or not all(_id(v, ids) for v in sids) \
            or not set(alive) <= set(sids):
        return Rejected("unknown_sender")
    roster = obj.get("roster")
    if roster is not None and (not isinstance(roster, dict)
                               or not all(isinstance(k, str) and isinstance(x, str) for k, x in roster.items())):
        return Rejected("type")
    if roster is not None and (not set(roster) <= set(sids) or not set(roster.values()) <= set(ROSTER_STATES)):
        return Rejected("roster")
    known = sids if ids is None else ids
    out = {k: obj.get(k) for k in STATUS_KEYS}
    out["t"], out["duration"] = float(t), float(duration)
    out["path_error_max"], out["coord_error_max"] = (None if x is None else float(x) for x in errors)
    out["events"] = [e for e in (event_from_dict(d, known) for d in events) if isinstance(e, FleetEvent)]
    out["paused"] = bool(obj.get("paused"))
    out["roster"] = None if roster is None else {k: str(x) for k, x in roster.items()}
    extra = _status_extra(obj, list(sids))
    if isinstance(extra, Rejected):
        return extra
    out.update(extra)
    return out


def _in(x: Any, allowed: Collection[str]) -> bool:
    """A string among ``allowed`` (a value off the wire may be unhashable)."""
    return isinstance(x, str) and x in allowed


def _count(x: Any) -> bool:
    return type(x) is int and 0 <= x < MAX_COUNT


def _status_extra(obj: dict, sids: list[str]) -> dict[str, Any] | Rejected:
    """The optional status fields present in ``obj``, checked against the status's own ``ids``
    and rebuilt, or ``extra`` (one of them is not what STATUS_EXTRA says)."""
    out: dict[str, Any] = {}
    n, known = len(sids), set(sids)
    for name in ("kinds", "states"):
        if name in obj:
            x, allowed = obj[name], KINDS if name == "kinds" else ROSTER_STATES
            if not _strings(x) or len(x) != n or not all(_in(s, allowed) for s in x):
                return Rejected("extra")
            out[name] = [str(s) for s in x]
    if "edges" in obj:
        x = obj["edges"]
        if not isinstance(x, list) or len(x) > MAX_STATUS_EDGES:
            return Rejected("extra")
        edges = []
        for e in x:
            if not (isinstance(e, list) and len(e) == 3 and _in(e[0], known) and _in(e[1], known) and e[0] != e[1]
                    and (e[2] is None or _number(e[2]) and e[2] >= 0)):
                return Rejected("extra")
            edges.append((str(e[0]), str(e[1]), None if e[2] is None else float(e[2])))
        out["edges"] = edges
    if "links" in obj:
        x = obj["links"]
        if not isinstance(x, list) or len(x) > MAX_STATUS_LINKS:
            return Rejected("extra")
        links = []
        for e in x:
            if not (isinstance(e, list) and len(e) == 5 and _in(e[0], known) and _in(e[1], known) and e[0] != e[1]
                    and _count(e[2]) and _count(e[3]) and e[3] <= e[2] and (e[4] is None or _in(e[4], LINK_STATES))):
                return Rejected("extra")
            links.append((str(e[0]), str(e[1]), int(e[2]), int(e[3]), None if e[4] is None else str(e[4])))
        out["links"] = links
    if "rx" in obj:
        x = obj["rx"]
        if not isinstance(x, list) or len(x) != n or not all(
                r is None or isinstance(r, list) and len(r) == 2 and _count(r[0]) and _count(r[1]) and r[1] <= r[0]
                for r in x):
            return Rejected("extra")
        out["rx"] = [None if r is None else (int(r[0]), int(r[1])) for r in x]
    if "safety_radius" in obj:
        r = obj["safety_radius"]
        if not _number(r) or not 0 < r <= MAX_TIME:
            return Rejected("extra")
        out["safety_radius"] = float(r)
    if "closest" in obj:
        c = obj["closest"]
        if not (isinstance(c, list) and len(c) == 3 and _in(c[0], known) and _in(c[1], known) and c[0] != c[1]
                and _number(c[2]) and 0 <= c[2] <= MAX_TIME):
            return Rejected("extra")
        out["closest"] = (str(c[0]), str(c[1]), float(c[2]))
    if "path_errors" in obj:
        x = obj["path_errors"]
        if not isinstance(x, list) or len(x) != n or not all(e is None or _number(e) and e >= 0 for e in x):
            return Rejected("extra")
        out["path_errors"] = [None if e is None else float(e) for e in x]
    if "directed" in obj:
        if type(obj["directed"]) is not bool:
            return Rejected("extra")
        out["directed"] = obj["directed"]
    if "completion" in obj:
        if not _in(obj["completion"], COMPLETIONS):
            return Rejected("extra")
        out["completion"] = str(obj["completion"])
    return out


# --------------------------------------------------------------------------- helpers


def _unpack(payload: bytes, limit: int = 4096) -> dict | Rejected:
    if len(payload) > limit:
        return Rejected("oversized")
    try:
        obj = msgpack.unpackb(payload, raw=False, max_str_len=limit, max_array_len=4096, max_map_len=256,
                              max_bin_len=0, max_ext_len=0, strict_map_key=True)
    except MSGPACK_ERRORS:
        return Rejected("malformed")
    except RecursionError:  # nesting deeper than the interpreter's stack
        return Rejected("malformed")
    return obj if isinstance(obj, dict) else Rejected("malformed")


def _strings(x: Any) -> bool:
    return isinstance(x, list) and all(isinstance(s, str) for s in x)


def _id(x: str, ids: Collection[str] | None) -> bool:
    """A well-formed id, and one of ``ids`` if they are known."""
    return (x in ids) if ids is not None else bool(ID_RE.match(x))


def _link(x: str, ids: Collection[str] | None) -> tuple[str, str] | None:
    """The (src, dst) of a "src->dst" link name of two ids (known ones, with ``ids``), or None."""
    if len(x) > 2 * MAX_ID + 2:
        return None
    src, sep, dst = x.partition("->")
    if not sep or not ID_RE.match(src) or not ID_RE.match(dst) or src == dst \
            or ids is not None and (src not in ids or dst not in ids):
        return None
    return src, dst


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


# --------------------------------------------------------------------------- command replies

REPLY_VERSION = 1
REPLY_STATUSES = ("applied", "rejected")
OP_RE = re.compile(r"^[a-z][a-z0-9_]{0,39}$")  # a command's op name (COMMAND_OPS, and ops added later)
MAX_REASON = 300
REPLY_KEYS = ("v", "status", "op", "reason", "tick", "t", "by")


@dataclass(frozen=True)
class CommandReply:
    """The world's answer to one command (a query on ``world/cmd/<from>``, docs/ground_station.md):

    - ``status``: ``applied`` (the world accepted it and it takes effect from ``tick``, at simulated
      time ``t``) or ``rejected`` (nothing was changed; ``reason`` says why);
    - ``op``: the command's op (``?`` when the command could not be read);
    - ``tick``/``t``: the simulated tick (and its time, s) the command takes effect from: a vehicle
      fault's landing tick, a pause's first tick not stepped, a link change's time; None when rejected;
    - ``by``: who the world recorded as the sender (as its event log names it).
    """

    status: str
    op: str
    reason: str = ""
    tick: int | None = None
    t: float | None = None
    by: str = ""

    @property
    def applied(self) -> bool:
        return self.status == "applied"

    def as_dict(self) -> dict[str, Any]:
        return {"v": REPLY_VERSION, "status": self.status, "op": self.op, "reason": self.reason, "tick": self.tick,
                "t": self.t, "by": self.by}


def encode_reply(r: CommandReply) -> bytes:
    return msgpack.packb(r.as_dict(), use_bin_type=True)


def decode_reply(payload: bytes) -> CommandReply | Rejected:
    """A command reply, every field checked (the reason and sender escaped), or the reject reason:
    ``oversized``, ``malformed``, ``version``, ``unknown_field``, ``type``, ``status``, ``op``,
    ``range``, ``unknown_sender``; never raises."""
    obj = _unpack(payload, limit=2048)
    if isinstance(obj, Rejected):
        return obj
    if obj.get("v") != REPLY_VERSION or type(obj.get("v")) is not int:
        return Rejected("version")
    if not set(obj) <= set(REPLY_KEYS):
        return Rejected("unknown_field")
    status, op, reason, tick, t, by = (obj.get(k) for k in ("status", "op", "reason", "tick", "t", "by"))
    reason = "" if reason is None else reason
    by = "" if by is None else by
    if not isinstance(status, str) or not isinstance(op, str) or not isinstance(reason, str) \
            or not isinstance(by, str) or tick is not None and type(tick) is not int \
            or t is not None and not _number(t):
        return Rejected("type")
    if status not in REPLY_STATUSES:
        return Rejected("status")
    if op != "?" and not OP_RE.match(op):
        return Rejected("op")
    if tick is not None and not 0 <= tick < MAX_COUNT or t is not None and not 0 <= t <= MAX_TIME:
        return Rejected("range")
    if status == "applied" and tick is None:  # an applied command always says when
        return Rejected("range")
    if by and not SENDER_RE.match(by):
        return Rejected("unknown_sender")
    return CommandReply(status, op, printable(reason, MAX_REASON), tick, None if t is None else float(t), by)


#: how the world names a command's sender: the key's sender (``gs``, ``launcher``), and a ground
#: station's own name after a colon (``gs:alice``)
SENDER_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}(:[A-Za-z0-9_-]{1,64})?$")


# --------------------------------------------------------------------------- settings in force

#: ``world/settings``: what a run's settings are now, beyond its scenario file: every run-time
#: change the world has made (the ``ctl`` commands it numbered with ``seq``, each with the
#: vehicle it was for or None for all, as sent), the phases of the formation as the changes
#: leave them, and the [link] table in force. ``cdus gs snapshot`` saves it.
SETTINGS_VERSION = 1
SETTINGS_LIMIT = 1 << 22  # bytes
MAX_SETTINGS_CHANGES = 10_000  # the newest ones (a run with more says how many it left out)
_PLAIN_DEPTH = 6


def encode_settings(changes: list[tuple[str | None, bytes]], phases: list[tuple[str, float]], link: dict,
                    total: int | None = None) -> bytes:
    """The settings reply; ``changes`` the world's command list (the newest MAX_SETTINGS_CHANGES
    of ``total``)."""
    kept = changes[-MAX_SETTINGS_CHANGES:]
    return msgpack.packb({"v": SETTINGS_VERSION, "changes": [[vid, p] for vid, p in kept],
                          "total": len(changes) if total is None else total,
                          "phases": [[vid, float(x)] for vid, x in phases], "link": link}, use_bin_type=True)


def _plain(x: Any, depth: int = 0) -> Any:
    """A value off the wire as JSON takes it: strings escaped, numbers that are not finite None,
    maps with string keys, no deeper than _PLAIN_DEPTH (None beyond)."""
    if depth > _PLAIN_DEPTH:
        return None
    if isinstance(x, bool) or x is None:
        return x
    if isinstance(x, int):
        return x if abs(x) < 2**63 else None
    if isinstance(x, float):
        return x if math.isfinite(x) else None
    if isinstance(x, str):
        return printable(x, 256)
    if isinstance(x, list):
        return [_plain(v, depth + 1) for v in x]
    if isinstance(x, dict):
        return {printable(str(k), 64): _plain(v, depth + 1) for k, v in x.items()}
    return None


def decode_settings(payload: bytes, ids: Collection[str] | None = None) -> dict[str, Any] | Rejected:
    """The settings as plain JSON-able values: ``changes`` [{seq, op, vehicle, fields}] (each
    command decoded by cdus.wire.messages.decode_control; one that does not decode is left out
    and counted in ``unreadable``), ``total``, ``phases`` {id: θ}, ``link``; or the reason."""
    if len(payload) > SETTINGS_LIMIT:
        return Rejected("oversized")
    try:
        obj = msgpack.unpackb(payload, raw=False, max_bin_len=MAX_CONTROL_PAYLOAD, max_ext_len=0,
                              max_array_len=max(MAX_SETTINGS_CHANGES, 4096), max_map_len=4096,
                              max_str_len=4096)
    except (*MSGPACK_ERRORS, RecursionError):
        return Rejected("malformed")
    if not isinstance(obj, dict):
        return Rejected("malformed")
    if obj.get("v") != SETTINGS_VERSION:
        return Rejected("version")
    changes, phases, link, total = obj.get("changes"), obj.get("phases"), obj.get("link"), obj.get("total")
    if not isinstance(changes, list) or not isinstance(phases, list) or not isinstance(link, dict) \
            or type(total) is not int or not len(changes) <= total < MAX_COUNT:
        return Rejected("type")
    out_changes, unreadable = [], 0
    for ch in changes:
        c = None
        if isinstance(ch, list) and len(ch) == 2 and (ch[0] is None or isinstance(ch[0], str) and _id(ch[0], ids)) \
                and isinstance(ch[1], bytes):
            c = decode_control(ch[1], CTL_OPS)
        if c is None or isinstance(c, str) or c.op not in SEQUENCED:
            unreadable += 1
            continue
        fields = {k: _plain(v) for k, v in c.fields.items() if k != "seq"}
        out_changes.append({"seq": c.fields.get("seq"), "op": c.op, "vehicle": ch[0], "fields": fields})
    theta = {}
    for p in phases:
        if not (isinstance(p, list) and len(p) == 2 and isinstance(p[0], str) and _id(p[0], ids) and _number(p[1])):
            return Rejected("phases")
        theta[p[0]] = float(p[1])
    return {"changes": out_changes, "total": total, "unreadable": unreadable, "phases": theta, "link": _plain(link)}

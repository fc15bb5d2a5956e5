"""What does the world say about the run, about once a second? Its status, for ground stations and the launcher.

:func:`encode_status` packs the world's summary (time, clock, who is alive, the worst errors,
recent events, the roster) and the optional fields a live console shows (STATUS_EXTRA);
:func:`decode_status` checks every field against the vocabularies (:mod:`cdus.core.vocabulary`)
and the status's own ids, or returns Rejected. A launcher believes only statuses signed with
its run's key (:func:`signed_by`).
"""

from __future__ import annotations

import hashlib
import hmac
from dataclasses import dataclass
from typing import Any, Collection

import msgpack

from cdus.core.vocabulary import CLOCKS, KINDS, LINK_STATES, ROSTER_STATES
from cdus.wire.bounds import finite as _number
from cdus.wire.events import FleetEvent, event_from_dict
from cdus.wire.fields import (MAX_TIME, SCHEMA_VERSION, count as _count, finite_or_none as _finite, known_id as _id,
                              one_of as _in, strings as _strings, unpack_map as _unpack)
from cdus.wire.rejected import Rejected

MAX_STATUS_IDS = 4096
MAX_STATUS_EVENTS = 64

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


@dataclass(frozen=True, kw_only=True)
class WorldStatus(StatusExtra):
    """The world's status as :func:`decode_status` checked it: a reader takes each field as it is.

    ``t`` and ``duration`` finite (s; ``t`` from -1), ``clock`` one of CLOCKS, ``alive`` a subset
    of ``ids`` (well-formed, or the receiver's own), the errors finite and >= 0 or None,
    ``events`` valid FleetEvents, ``roster`` {id: one of ROSTER_STATES} or None. The optional
    fields (STATUS_EXTRA, the :class:`StatusExtra` it extends) are None when the world did not send them; when present, ``kinds``,
    ``states``, ``rx`` and ``path_errors`` have one entry per id, ``edges``, ``links`` and
    ``closest`` name ids of the status, and each value is within its bounds.
    """

    t: float
    duration: float
    clock: str
    alive: list[str]
    ids: list[str]
    path_error_max: float | None
    coord_error_max: float | None
    events: list[FleetEvent]
    paused: bool
    roster: dict[str, str] | None


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


def decode_status(payload: bytes, ids: Collection[str] | None = None) -> WorldStatus | Rejected:
    """The world's status as a :class:`WorldStatus` (events as FleetEvent; ``roster`` None when the
    world did not send it; an optional field None when absent), or Rejected. Every field is checked: times finite and plausible,
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
    pe, ce = (None if x is None else float(x) for x in errors)
    extra = _status_extra(obj, list(sids))
    if isinstance(extra, Rejected):
        return extra
    return WorldStatus(t=float(t), duration=float(duration), clock=str(obj["clock"]), alive=[str(v) for v in alive],
                       ids=[str(v) for v in sids], path_error_max=pe, coord_error_max=ce,
                       events=[e for e in (event_from_dict(d, known) for d in events) if isinstance(e, FleetEvent)],
                       paused=bool(obj.get("paused")),
                       roster=None if roster is None else {k: str(x) for k, x in roster.items()}, **extra)


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

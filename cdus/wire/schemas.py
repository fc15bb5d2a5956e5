"""The fleet's reports, each with one versioned schema: events, agent stats, world status.

- :class:`FleetEvent`: something a person should know (a vehicle lost, a link down, a
  scheduled fault carried out), with a ``kind`` and a ``severity`` a program can act on,
  and a ``text`` a person reads. The world publishes them, the metrics JSON lists them,
  the Rerun event log shows them; the in-process fleet makes the same ones.
- :class:`AgentStats`: a vehicle agent's counters, about once a second, to the world.
- world status: the world's summary, about once a second, for ground stations and the
  launcher (:func:`encode_status` / :func:`decode_status`).

Every decoder validates and never raises: it returns the record or the reason it was
rejected, so a receiver counts and drops.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import msgpack

from cdus.wire.messages import MSGPACK_ERRORS

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
    "fleet": "info",  # the fleet paused, resumed or stopped
    "rejected": "warn",  # a command or message was rejected
}
MAX_TEXT = 300


@dataclass(frozen=True)
class FleetEvent:
    t: float  # simulated seconds
    kind: str
    text: str
    severity: str = "info"
    vehicle: str | None = None
    link: str | None = None  # "src->dst"

    @staticmethod
    def of(t: float, kind: str, text: str, *, severity: str | None = None, vehicle: str | None = None,
           link: str | None = None) -> "FleetEvent":
        """An event with its kind's default severity unless one is given."""
        return FleetEvent(t, kind, text[:MAX_TEXT], severity or EVENT_KINDS[kind], vehicle, link)

    def line(self) -> str:
        """How a person reads it in a log."""
        return f"t = {self.t:.2f} s: {self.text}"

    def as_dict(self) -> dict[str, Any]:
        return {k: v for k, v in asdict(self).items() if v is not None}


def event_from_dict(d: Any) -> FleetEvent | str:
    if not isinstance(d, dict):
        return "malformed"
    t, kind, text, sev = d.get("t"), d.get("kind"), d.get("text"), d.get("severity", "info")
    if not _number(t) or kind not in EVENT_KINDS or not isinstance(text, str) or sev not in SEVERITIES:
        return "type"
    veh, link = d.get("vehicle"), d.get("link")
    if veh is not None and not isinstance(veh, str) or link is not None and not isinstance(link, str):
        return "type"
    return FleetEvent(float(t), kind, text[:MAX_TEXT], sev, veh, link)


def encode_event(e: FleetEvent) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, **e.as_dict()}, use_bin_type=True)


def decode_event(payload: bytes) -> FleetEvent | str:
    obj = _unpack(payload)
    if isinstance(obj, str):
        return obj
    if obj.get("v") != SCHEMA_VERSION:
        return "version"
    return event_from_dict(obj)


# --------------------------------------------------------------------------- agent stats


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
    faults: dict | None = None  # the link emulator's counters_summary(), newest state changes only
    bursts: tuple[dict, ...] = ()  # new link_burst events (FleetEvent.as_dict())
    interventions: int = 0  # control steps at which the safety filter changed the velocity reference
    incarnation: int = 0  # drawn at random when the process starts: a new value is a new process (a restart)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["latencies_ms"] = list(self.latencies_ms)
        d["bursts"] = list(self.bursts)
        return d


_STAT_INTS = ("tick", "sent_to_me", "delivered", "dropped", "duplicated", "rejected", "missed_deadlines", "joined_at",
              "interventions", "incarnation")


def encode_stats(s: AgentStats) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, **s.as_dict()}, use_bin_type=True)


def decode_stats(payload: bytes) -> AgentStats | str:
    obj = _unpack(payload, limit=1 << 16)
    if isinstance(obj, str):
        return obj
    if obj.get("v") != SCHEMA_VERSION:
        return "version"
    vid = obj.get("id")
    if not isinstance(vid, str):
        return "type"
    ints = {k: obj.get(k, 0) for k in _STAT_INTS}
    if not all(type(x) is int and x >= 0 for x in ints.values()):
        return "type"
    by = obj.get("rejected_by_reason", {})
    lat = obj.get("latencies_ms", [])
    faults = obj.get("faults")
    bursts = obj.get("bursts", [])
    if (not isinstance(by, dict) or not all(isinstance(k, str) and type(x) is int for k, x in by.items())
            or not isinstance(lat, list) or not all(_number(x) for x in lat)
            or faults is not None and not isinstance(faults, dict) or not isinstance(bursts, list)):
        return "type"
    return AgentStats(vid, rejected_by_reason=by, latencies_ms=tuple(float(x) for x in lat), faults=faults,
                      bursts=tuple(b for b in bursts if isinstance(b, dict)), **ints)


# --------------------------------------------------------------------------- world status

STATUS_KEYS = ("t", "duration", "clock", "alive", "ids", "path_error_max", "coord_error_max", "events", "paused")


def encode_status(t: float, duration: float, clock: str, alive: list[str], ids: list[str],
                  path_error_max: float | None, coord_error_max: float | None, events: list[FleetEvent],
                  paused: bool) -> bytes:
    return msgpack.packb({"v": SCHEMA_VERSION, "t": t, "duration": duration, "clock": clock, "alive": alive,
                          "ids": ids, "path_error_max": _finite(path_error_max),
                          "coord_error_max": _finite(coord_error_max), "events": [e.as_dict() for e in events],
                          "paused": paused}, use_bin_type=True)


def decode_status(payload: bytes) -> dict[str, Any] | str:
    """The world's status as a dict (STATUS_KEYS; events as FleetEvent), or the reject reason."""
    obj = _unpack(payload, limit=1 << 16)
    if isinstance(obj, str):
        return obj
    if obj.get("v") != SCHEMA_VERSION:
        return "version"
    if (not _number(obj.get("t")) or not _number(obj.get("duration")) or not isinstance(obj.get("clock"), str)
            or not _strings(obj.get("alive")) or not _strings(obj.get("ids"))
            or not isinstance(obj.get("events"), list)):
        return "type"
    events = [e for e in (event_from_dict(d) for d in obj["events"]) if isinstance(e, FleetEvent)]
    out = {k: obj.get(k) for k in STATUS_KEYS}
    out["events"] = events
    out["paused"] = bool(obj.get("paused"))
    return out


# --------------------------------------------------------------------------- helpers


def _unpack(payload: bytes, limit: int = 4096) -> dict | str:
    if len(payload) > limit:
        return "oversized"
    try:
        obj = msgpack.unpackb(payload, raw=False, max_str_len=limit, max_array_len=4096, max_map_len=256,
                              max_bin_len=0, max_ext_len=0)
    except MSGPACK_ERRORS:
        return "malformed"
    return obj if isinstance(obj, dict) else "malformed"


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _strings(x: Any) -> bool:
    return isinstance(x, list) and all(isinstance(s, str) for s in x)


def _finite(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)

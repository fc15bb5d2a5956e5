"""What should a person know about a run? The fleet's events, one versioned schema.

A :class:`FleetEvent` is something a person should know (a vehicle lost, a link down, a
scheduled fault carried out), with a ``kind`` and a ``severity`` a program can act on, a
``text`` a person reads, and its ``origin`` (who saw it: ``world``, the launcher, or the
vehicle whose counters reported it). The world publishes them, the metrics JSON lists them,
the Rerun event log shows them; the in-process fleet makes the same ones. The decoder checks
every field and escapes the text (:func:`cdus.wire.text.printable`), or returns Rejected.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Collection

import msgpack

from cdus.wire.bounds import finite as _number
from cdus.wire.fields import MAX_TEXT, MAX_TIME, SCHEMA_VERSION, known_id as _id, link_ends as _link
from cdus.wire.fields import unpack_map as _unpack
from cdus.wire.rejected import Rejected
from cdus.wire.text import printable

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
    "odometry_stale": "warn",  # a plant = "ros2" vehicle's robot sent no odometry for its timeout: it holds
    "odometry_back": "info",  # ... and its odometry came back: it follows again
    "recording_stopped": "warn",  # the world's .rrd file could not be written on (a full disk): the run goes on
}
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

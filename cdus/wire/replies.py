"""What did the world answer to a command, and which settings are in force? Replies and settings.

- :class:`CommandReply`: the world's answer to one command (a query on ``world/cmd/<from>``):
  applied from a tick, or rejected with a reason (:func:`encode_reply` / :func:`decode_reply`).
- ``world/settings``: every run-time change the world has made, the formation's phases and the
  [link] table in force (:func:`encode_settings` / :func:`decode_settings`; ``cdus gs snapshot``).

The decoders check every field (texts escaped) or return Rejected; they never raise.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Collection

import msgpack

from cdus.wire.bounds import finite as _number
from cdus.wire.fields import MAX_COUNT, MAX_TIME, known_id as _id, unpack_map as _unpack
from cdus.wire.messages import CTL_OPS, MAX_CONTROL_PAYLOAD, MSGPACK_ERRORS, SEQUENCED, decode_control
from cdus.wire.rejected import Rejected
from cdus.wire.text import printable

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
        if c is None or isinstance(c, Rejected) or c.op not in SEQUENCED:
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

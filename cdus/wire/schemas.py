"""Where are the fleet's reports defined? One name for the versioned schemas of every report.

The schemas live in rooms of their own; this module gathers their names, so that
``from cdus.wire.schemas import X`` keeps working for every X it ever offered:

- :mod:`cdus.wire.events`: :class:`FleetEvent`, something a person should know;
- :mod:`cdus.wire.stats`: :class:`AgentStats`, a vehicle agent's counters, to the world;
- :mod:`cdus.wire.status`: the world's status, for ground stations and the launcher;
- :mod:`cdus.wire.replies`: :class:`CommandReply`, the world's answer to a command, and the
  settings in force (``world/settings``);
- :mod:`cdus.wire.fields`: the limits and checks the decoders share;
- :mod:`cdus.core.vocabulary`: the words the decoders check against (drop causes, link and
  roster states, kinds, clocks).

Every decoder validates every field, nested ones included, into typed records rebuilt from
numbers and ids (no map from the wire is passed on as it came), and never raises: it returns
the record or :class:`cdus.wire.rejected.Rejected` (the reason), so a receiver counts and
drops. Texts from the wire come out escaped (:func:`cdus.wire.text.printable`), safe to print.
"""

from __future__ import annotations

from cdus.core.vocabulary import CLOCKS, DROP_CAUSES, FAULT_COUNTERS, KINDS, LINK_STATES, RADIO_CAUSES, ROSTER_STATES
from cdus.wire.events import (EVENT_KINDS, ORIGIN_WORLD, ORIGINS, SEVERITIES, FleetEvent, decode_event, encode_event,
                              event_from_dict)
from cdus.wire.fields import ID_RE, MAX_COUNT, MAX_ID, MAX_TEXT, MAX_TIME, REASON_RE, SCHEMA_VERSION
from cdus.wire.rejected import Rejected
from cdus.wire.replies import (MAX_REASON, MAX_SETTINGS_CHANGES, OP_RE, REPLY_KEYS, REPLY_STATUSES, REPLY_VERSION,
                               SENDER_RE, SETTINGS_LIMIT, SETTINGS_VERSION, CommandReply, decode_reply,
                               decode_settings, encode_reply, encode_settings)
from cdus.wire.stats import (MAX_BURSTS, MAX_LATENCIES, MAX_LINKS, MAX_ODOMETRY_GAPS, MAX_REASONS, MAX_STATE_CHANGES,
                             AgentStats, BurstReport, OdometryGap, decode_stats, encode_stats)
from cdus.wire.status import (COMPLETED, COMPLETIONS, MAX_STATUS_EDGES, MAX_STATUS_EVENTS, MAX_STATUS_IDS,
                              MAX_STATUS_LINKS, STATUS_EXTRA, STATUS_KEY_ENV, STATUS_KEYS, STATUS_LIMIT, StatusExtra,
                              WorldStatus, decode_status, encode_status, signed_by, status_signature)

__all__ = [
    "CLOCKS", "DROP_CAUSES", "FAULT_COUNTERS", "KINDS", "LINK_STATES", "RADIO_CAUSES", "ROSTER_STATES",
    "EVENT_KINDS", "ORIGIN_WORLD", "ORIGINS", "SEVERITIES", "FleetEvent", "decode_event", "encode_event",
    "event_from_dict",
    "ID_RE", "MAX_COUNT", "MAX_ID", "MAX_TEXT", "MAX_TIME", "REASON_RE", "SCHEMA_VERSION", "Rejected",
    "MAX_REASON", "MAX_SETTINGS_CHANGES", "OP_RE", "REPLY_KEYS", "REPLY_STATUSES", "REPLY_VERSION", "SENDER_RE",
    "SETTINGS_LIMIT", "SETTINGS_VERSION", "CommandReply", "decode_reply", "decode_settings", "encode_reply",
    "encode_settings",
    "MAX_BURSTS", "MAX_LATENCIES", "MAX_LINKS", "MAX_ODOMETRY_GAPS", "MAX_REASONS", "MAX_STATE_CHANGES", "AgentStats",
    "BurstReport", "OdometryGap", "decode_stats", "encode_stats",
    "COMPLETED", "COMPLETIONS", "MAX_STATUS_EDGES", "MAX_STATUS_EVENTS", "MAX_STATUS_IDS", "MAX_STATUS_LINKS",
    "STATUS_EXTRA", "STATUS_KEY_ENV", "STATUS_KEYS", "STATUS_LIMIT", "StatusExtra", "WorldStatus", "decode_status",
    "encode_status",
    "signed_by", "status_signature",
]

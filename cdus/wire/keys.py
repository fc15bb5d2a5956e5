"""Where things are on Zenoh: the key space of a fleet (system.md "Zenoh").

Everything lives under ``cdus/<fleet>/`` so two fleets on one router never cross-talk.

    cdus/<fleet>/v/<id>/omega     ω messages (vehicle_agent.messages.OmegaMsg)
    cdus/<fleet>/v/<id>/state     telemetry at each control instant (StateMsg)
    cdus/<fleet>/v/<id>/stats     the agent's counters, about once a second
    cdus/<fleet>/alive/<id>       liveliness token of a vehicle agent (``world`` for the world)
    cdus/<fleet>/clock            the world's clock: start / grant / stop
    cdus/<fleet>/cmd/<target>     commands; <target> is a vehicle id, ``all`` or ``world``
    cdus/<fleet>/world/status     the world's status, about once a second
    cdus/<fleet>/world/events     human-readable events (vehicle lost, link changed, ...)
    cdus/<fleet>/world/last/<id>  queryable: a vehicle's newest telemetry (for a restarted agent)
"""

from __future__ import annotations

import re

FLEET_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
WORLD = "world"
ALL = "all"


def check_fleet(fleet: str) -> str:
    if not FLEET_RE.match(fleet):
        raise ValueError(f"fleet name {fleet!r}: use 1-64 letters, digits, '_' or '-'")
    return fleet


def prefix(fleet: str) -> str:
    return f"cdus/{fleet}"


def omega(fleet: str, vid: str) -> str:
    return f"cdus/{fleet}/v/{vid}/omega"


def state(fleet: str, vid: str) -> str:
    return f"cdus/{fleet}/v/{vid}/state"


def stats(fleet: str, vid: str) -> str:
    return f"cdus/{fleet}/v/{vid}/stats"


def alive(fleet: str, vid: str) -> str:
    return f"cdus/{fleet}/alive/{vid}"


def clock(fleet: str) -> str:
    return f"cdus/{fleet}/clock"


def cmd(fleet: str, target: str) -> str:
    return f"cdus/{fleet}/cmd/{target}"


def world_status(fleet: str) -> str:
    return f"cdus/{fleet}/world/status"


def world_events(fleet: str) -> str:
    return f"cdus/{fleet}/world/events"


def world_last(fleet: str, vid: str) -> str:
    return f"cdus/{fleet}/world/last/{vid}"


def any_vehicle(fleet: str, leaf: str) -> str:
    """Wildcard over every vehicle's ``leaf`` (omega, state, stats)."""
    return f"cdus/{fleet}/v/*/{leaf}"


def any_alive(fleet: str) -> str:
    return f"cdus/{fleet}/alive/*"


def vehicle_of(key: str) -> str | None:
    """The vehicle id in ``cdus/<fleet>/v/<id>/<leaf>`` or ``cdus/<fleet>/alive/<id>``."""
    parts = key.split("/")
    if len(parts) >= 5 and parts[2] == "v":
        return parts[3]
    if len(parts) == 4 and parts[2] == "alive":
        return parts[3]
    return None

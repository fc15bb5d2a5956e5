"""Where things are on Zenoh: the key space of a fleet (docs/architecture.md, "Key space").

Everything lives under ``cdus/<fleet>/`` so two fleets on one router never cross-talk.
A message meant for particular processes is *addressed*: its key carries the set of
its receivers as one chunk, ``+id1+id2+``, so every process takes all its input
through one subscription (``to/$*+<me>+$*/**``, :func:`inbox`) and waits in one place:

    cdus/<fleet>/to/<set>/omega/<src>   ω of vehicle <src> to the vehicles listening to it
    cdus/<fleet>/to/<set>/ctl           the world's clock, roster and relayed commands
    cdus/<fleet>/to/+<id>+/contacts     the world's proximity sensor: what vehicle <id> sees
    cdus/<fleet>/to/<set>/radio         the world's radio geometry samples (every vehicle's position)
    cdus/<fleet>/to/+world+/state/<src> telemetry batches of vehicle <src>
    cdus/<fleet>/to/+world+/stats/<src> its counters, about once a second
    cdus/<fleet>/to/+world+/cmd/<from>  commands to the world (ground stations, the launcher)
    cdus/<fleet>/to/+launcher+/cmd      scheduled vehicle faults, the world to the launcher
    cdus/<fleet>/to/+<id>+/wake         a process waking itself (session-local, never sent)
    cdus/<fleet>/to/+<id>+/ping         queryable: a vehicle answers once it can hear (link check)
    cdus/<fleet>/alive/<id>/<zid>       liveliness token of a process: readiness and loss (<zid>: its
                                        Zenoh session's id, so each process's token is its own)
    cdus/<fleet>/world/status           the world's status, about once a second
    cdus/<fleet>/world/events           fleet events as they happen (cdus.wire.schemas)
    cdus/<fleet>/world/last/<id>        queryable: a vehicle's newest telemetry
    cdus/<fleet>/world/cmd/<from>       queryable: a command to the world, answered applied/rejected

Anyone may listen: a ground station watches ``to/*/state/*`` and ``world/**``. Ids and
fleet names are letters, digits, ``_`` and ``-``, so ``+`` only ever delimits a set.
"""

from __future__ import annotations

import re
from typing import Iterable

FLEET_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
WORLD = "world"
LAUNCHER = "launcher"
GROUND = "gs"  # the sender name of a ground station's commands


def check_fleet(fleet: str) -> str:
    if not FLEET_RE.match(fleet):
        raise ValueError(f"fleet name {fleet!r}: use 1-64 letters, digits, '_' or '-'")
    return fleet


def prefix(fleet: str) -> str:
    return f"cdus/{fleet}"


def recipients(ids: Iterable[str]) -> str:
    """The chunk addressing ``ids``: ``+a+b+``."""
    ids = list(ids)
    return "+" + "+".join(ids) + "+" if ids else "+"


def inbox(fleet: str, me: str) -> str:
    """Everything addressed to ``me``."""
    return f"cdus/{fleet}/to/$*+{me}+$*/**"


def inbox_leaves(fleet: str, me: str) -> str:
    """The keys addressed to ``me`` that end right after the recipients (``ctl``, ``contacts``,
    ``radio``, ``wake``): a realtime agent's FIFO, its neighbours' ω having rings of their own."""
    return f"cdus/{fleet}/to/$*+{me}+$*/*"


def omega(fleet: str, src: str, listeners: Iterable[str]) -> str:
    return f"cdus/{fleet}/to/{recipients(listeners)}/omega/{src}"


def ctl(fleet: str, ids: Iterable[str]) -> str:
    return f"cdus/{fleet}/to/{recipients(ids)}/ctl"


def contacts(fleet: str, vid: str) -> str:
    return f"cdus/{fleet}/to/+{vid}+/contacts"


def radio(fleet: str, ids: Iterable[str]) -> str:
    """The radio geometry samples the world sends to the vehicles ``ids`` (docs/radio.md)."""
    return f"cdus/{fleet}/to/{recipients(ids)}/radio"


def state(fleet: str, src: str) -> str:
    return f"cdus/{fleet}/to/+{WORLD}+/state/{src}"


def stats(fleet: str, src: str) -> str:
    return f"cdus/{fleet}/to/+{WORLD}+/stats/{src}"


def world_cmd(fleet: str, sender: str) -> str:
    return f"cdus/{fleet}/to/+{WORLD}+/cmd/{sender}"


def launcher_cmd(fleet: str) -> str:
    return f"cdus/{fleet}/to/+{LAUNCHER}+/cmd"


def wake(fleet: str, me: str) -> str:
    return f"cdus/{fleet}/to/+{me}+/wake"


def ping(fleet: str, vid: str) -> str:
    """A vehicle's link check: a reply proves the asker holds its subscription (see vehicle_agent)."""
    return f"cdus/{fleet}/to/+{vid}+/ping"


ZID_RE = re.compile(r"^[0-9a-f]{1,32}$")  # a Zenoh session id as str(session.zid()) spells it


def alive(fleet: str, name: str, zid: str) -> str:
    """The liveliness token of process ``name`` whose Zenoh session id is ``zid``. The id makes
    each process's token a key of its own: Zenoh merges the tokens of one key (a second one on it
    is never news, and its holder keeps the key up after the first goes), so on a bare
    ``alive/<name>`` anyone's token would hide that process's loss (docs/security.md, "Liveliness")."""
    return f"cdus/{fleet}/alive/{name}/{zid}"


def alive_of(fleet: str, name: str) -> str:
    """Every token of process ``name`` (one per session that declared one)."""
    return f"cdus/{fleet}/alive/{name}/*"


def any_alive(fleet: str) -> str:
    """What a process watches: every token of the fleet. A token on a wildcard key (``alive/**``)
    intersects it too, and arrives with that key: :func:`alive_token` refuses it."""
    return f"cdus/{fleet}/alive/*/*"


ANY_FLEET_WORLD = "cdus/*/alive/world/*"  # every fleet's world at a router (a mistyped --fleet's hint)


def fleet_of(key: str) -> str | None:
    """The fleet in ``cdus/<fleet>/...``, None if ``key`` is not in a fleet's key space."""
    parts = key.split("/")
    return parts[1] if len(parts) > 2 and parts[0] == "cdus" and FLEET_RE.match(parts[1]) else None


def any_state(fleet: str) -> str:
    return f"cdus/{fleet}/to/*/state/*"


def any_omega(fleet: str) -> str:
    return f"cdus/{fleet}/to/*/omega/*"


def any_stats(fleet: str) -> str:
    return f"cdus/{fleet}/to/*/stats/*"


def world_status(fleet: str) -> str:
    return f"cdus/{fleet}/world/status"


def world_events(fleet: str) -> str:
    return f"cdus/{fleet}/world/events"


def world_settings(fleet: str) -> str:
    """The world's settings in force (cdus.wire.schemas.encode_settings), a queryable."""
    return f"cdus/{fleet}/world/settings"


def world_last(fleet: str, vid: str) -> str:
    return f"cdus/{fleet}/world/last/{vid}"


def world_command(fleet: str, sender: str) -> str:
    """The world's command queryable as ``sender`` asks it (``gs`` for ground stations): each
    command is a query whose payload is the command, answered with a CommandReply."""
    return f"cdus/{fleet}/world/cmd/{sender}"


def any_world_command(fleet: str) -> str:
    return f"cdus/{fleet}/world/cmd/*"


def leaf(key: str) -> tuple[str, str]:
    """(kind, source) of an addressed key: ``.../to/<set>/omega/usv1`` -> ("omega", "usv1"),
    ``.../to/<set>/ctl`` -> ("ctl", ""); ("", "") if ``key`` is not addressed."""
    parts = key.split("/")
    if len(parts) >= 5 and parts[2] == "to":
        return parts[4], parts[5] if len(parts) > 5 else ""
    return "", ""


def leaf_kind(key: str) -> str:
    """The kind of an addressed key that ends with it, exactly ``cdus/<fleet>/to/<set>/<kind>``
    (:func:`ctl`, :func:`contacts`, :func:`radio`, :func:`wake`, :func:`ping`, :func:`launcher_cmd`):
    ``.../to/+usv1+/ctl`` -> "ctl"; "" for any other key (one with a source after its kind, or
    more or fewer chunks)."""
    parts = key.split("/")
    return parts[4] if len(parts) == 5 and parts[0] == "cdus" and parts[2] == "to" else ""


def alive_token(key: str) -> tuple[str, str] | None:
    """(name, zid) of a token exactly as :func:`alive` makes it, ``cdus/<fleet>/alive/<name>/<zid>``;
    None for any other key a liveliness watch can deliver: a token declared on a key expression
    (``alive/**``, ``alive/*/x``, which intersects every watch), a bare ``alive/<name>``, a name
    or session id that is not one."""
    parts = key.split("/")
    if (len(parts) == 5 and parts[0] == "cdus" and parts[2] == "alive" and FLEET_RE.match(parts[1])
            and FLEET_RE.match(parts[3]) and ZID_RE.match(parts[4])):
        return parts[3], parts[4]
    return None


def hold_token(held: dict[str, set[str]], key: str, up: bool) -> tuple[str, bool] | None:
    """One token came (``up``) or went: ``held`` (name -> the session ids of its tokens up) is
    updated; returns (name, whether the name holds a token now), None if ``key`` is no token's
    (:func:`alive_token`). For a watcher that only asks "is it up" (the launcher, a ground
    station); the world asks whose (world_sim)."""
    token = alive_token(key)
    if token is None:
        return None
    name, zid = token
    ids = held.setdefault(name, set())
    (ids.add if up else ids.discard)(zid)
    if not ids:
        del held[name]
    return name, bool(ids)


def alive_name(key: str) -> str | None:
    """The process name of a token key (:func:`alive_token`), None if ``key`` is not one."""
    token = alive_token(key)
    return None if token is None else token[0]

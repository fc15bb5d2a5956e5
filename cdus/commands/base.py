"""What do all commands share? Their names on each surface, and the outcome of applying one.

Every command type carries a :class:`Names` (``NAMES``): the word a ground station's CLI takes
(``pause-vehicle``), the op on the wire (``pause_vehicle``) and the action of a scenario
``[[event]]`` (``pause``), each written once here for the command, plus the older wire spellings
a decoder still takes (``set_gains``). Applying a command gives an :class:`Applied` or a
:class:`cdus.wire.rejected.Rejected`, a value returned by whoever applied it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

from cdus.scenario.errors import ConfigError
from cdus.wire.bounds import BOUNDS, is_number
from cdus.wire.rejected import Rejected


@dataclass(frozen=True)
class Names:
    """A command's words: ``cli`` (a ground station's action), ``op`` (the wire's), ``event`` (a
    scenario event's ``action``, None: no event does it), ``old_ops`` (spellings decoded too)."""

    cli: str
    op: str
    event: str | None = None
    old_ops: tuple[str, ...] = ()


@dataclass(frozen=True)
class Applied:
    """A command carried out from control tick ``tick`` (and, for a change named in time, from
    simulated time ``at``); ``note`` says anything the asker should know (a past time moved)."""

    tick: int
    at: float | None = None
    note: str = ""


Outcome = Applied | Rejected


def taken(done: Any) -> Applied | Rejected:
    """A node's own outcome (cdus.core.changes: Applied(tick, at) or Refused(reason)) as a
    command's: the tick (and time) the node took, which may be later than asked (the next tick
    it steps), or its reason."""
    if not done:
        return Rejected(done.reason)
    return Applied(done.tick, getattr(done, "at", None))

#: a vehicle id as the fleet's keys spell it (cdus.wire.keys.FLEET_RE)
ID_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")
MAX_ID = 64


def vehicle_id(fields: Mapping[str, Any], key: str = "vehicle", *, empty_ok: bool = False) -> str | Rejected:
    """The vehicle id in ``fields[key]``: 1-64 letters, digits, ``_`` or ``-`` (or "" for every
    vehicle when ``empty_ok``)."""
    v = fields.get(key)
    if v is None:
        return Rejected("missing: name the vehicle, e.g. usv2", key)
    if not isinstance(v, str):
        return Rejected(f"must be a vehicle id, got {_shown(v)}", key)
    if v == "" and empty_ok:
        return v
    if not 0 < len(v) <= MAX_ID or not set(v) <= ID_CHARS:
        return Rejected(f"must be a vehicle id (1-{MAX_ID} letters, digits, '_' or '-'), got {_shown(v)}", key)
    return v


def table(fields: Mapping[str, Any], key: str, example: str) -> dict | Rejected:
    """``fields[key]`` as a table (a dict with string keys), or why not."""
    v = fields.get(key)
    if not isinstance(v, dict) or not all(isinstance(k, str) for k in v):
        return Rejected(f"must be a table, e.g. {example}, got {_shown(v)}", key)
    return v


def when(fields: Mapping[str, Any], key: str = "at") -> float | None | Rejected:
    """A simulated time ``fields[key]`` within ``link.at``'s bound; None or a negative time: as
    soon as possible (None is returned for both)."""
    v = fields.get(key)
    if v is None:
        return None
    problem = BOUNDS["link.at"].problem(v, " (s of simulated time; < 0: as soon as possible)")
    if problem is not None:
        return Rejected(problem, key)
    return None if v < 0 else float(v)


def keyed_table(fields: Mapping[str, Any], allowed: tuple[str, ...], key: str, example: str) -> dict | Rejected:
    """``fields[key]`` as a table, once no key of ``fields`` is outside ``allowed``."""
    return unknown_keys(fields, allowed) or table(fields, key, example)


def unknown_keys(fields: Mapping[str, Any], allowed: tuple[str, ...]) -> Rejected | None:
    """The first key of ``fields`` outside ``allowed``, refused (sorted: the same one every time)."""
    extra = sorted(str(k) for k in fields if k not in allowed)
    if extra:
        return Rejected(f"unknown; this command takes {', '.join(allowed) or 'nothing'}", extra[0])
    return None


def _shown(v: Any) -> str:
    """A value in a refusal: numbers with :g, anything else by repr, cut at 60 characters."""
    if is_number(v):
        return f"{v:g}"
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def config_rejected(e: ConfigError, prefix: str | None = None) -> Rejected:
    """The first problem of a scenario check's ConfigError as a Rejected (its field inside ``prefix``)."""
    field, message = e.problems[0] if e.problems else ("", str(e))
    if prefix and field.startswith(prefix + "."):
        field = field[len(prefix) + 1:]
    return Rejected(message, field or None)


def freeze(v: Any) -> Any:
    """Tables -> sorted (key, value) pairs, lists -> tuples, recursively: a command's table kept
    hashable and comparable (:func:`thaw` gives it back)."""
    if isinstance(v, dict):
        return tuple(sorted((k, freeze(x)) for k, x in v.items()))
    if isinstance(v, (list, tuple)):
        return ("__list__", *(freeze(x) for x in v))
    return v


def thaw(v: Any) -> Any:
    """The table or list :func:`freeze` was given."""
    if isinstance(v, tuple) and v[:1] == ("__list__",):
        return [thaw(x) for x in v[1:]]
    if isinstance(v, tuple):
        return {k: thaw(x) for k, x in v}
    return v

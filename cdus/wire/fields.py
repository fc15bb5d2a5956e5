"""Is a value off the wire one a record may hold? The checks every decoder of a report shares.

The limits a report's fields keep to (an id's shape, a plausible time, a count), and the
small checks built on them: a map unpacked within a size (:func:`unpack_map`), an id known
to the receiver (:func:`known_id`), a ``src->dst`` link name (:func:`link_ends`). Each
answers a yes or no, or returns the checked value, and never raises.
"""

from __future__ import annotations

import math
import re
from typing import Any, Collection

import msgpack

from cdus.wire.messages import MSGPACK_ERRORS
from cdus.wire.rejected import Rejected

SCHEMA_VERSION = 1  # of events, agent stats and the world's status
MAX_TEXT = 300
MAX_ID = 64
ID_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")  # vehicle and process ids (cdus.wire.keys)
REASON_RE = re.compile(r"^[a-z0-9_]{1,40}$")  # a reject reason's name
MAX_TIME = 1e9  # s: a plausible simulated time (31 years); anything beyond is not a run's
MAX_COUNT = 2**53  # a counter beyond this is not a count a process can have made


def unpack_map(payload: bytes, limit: int = 4096) -> dict | Rejected:
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


def strings(x: Any) -> bool:
    return isinstance(x, list) and all(isinstance(s, str) for s in x)


def known_id(x: str, ids: Collection[str] | None) -> bool:
    """A well-formed id, and one of ``ids`` if they are known."""
    return (x in ids) if ids is not None else bool(ID_RE.match(x))


def link_ends(x: str, ids: Collection[str] | None) -> tuple[str, str] | None:
    """The (src, dst) of a "src->dst" link name of two ids (known ones, with ``ids``), or None."""
    if len(x) > 2 * MAX_ID + 2:
        return None
    src, sep, dst = x.partition("->")
    if not sep or not ID_RE.match(src) or not ID_RE.match(dst) or src == dst \
            or ids is not None and (src not in ids or dst not in ids):
        return None
    return src, dst


def finite_or_none(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def one_of(x: Any, allowed: Collection[str]) -> bool:
    """A string among ``allowed`` (a value off the wire may be unhashable)."""
    return isinstance(x, str) and x in allowed


def count(x: Any) -> bool:
    return type(x) is int and 0 <= x < MAX_COUNT

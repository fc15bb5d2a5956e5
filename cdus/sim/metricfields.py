"""How is one field of a metrics JSON read and checked? Once, into its Python value, or a
:class:`_Bad` naming the field and what docs/metrics.md says it is (cdus.sim.runmetrics's parts
use these while decoding a file).
"""

from __future__ import annotations

from typing import Any, Mapping

from cdus.wire.bounds import is_number
from cdus.wire.rejected import Rejected


class _Bad(ValueError):
    """A field that is not what docs/metrics.md says: raised inside the decoding, which
    :meth:`Metrics.from_json` turns into the Rejected naming the field."""

    def __init__(self, field: str, reason: str):
        self.rejected = Rejected(reason, field)
        super().__init__(f"metrics: {self.rejected}")


def _bad(where: str, expected: str, value: Any) -> _Bad:
    shown = repr(value)
    return _Bad(where, f"expected {expected}, got {shown[:60] + ('...' if len(shown) > 60 else '')}")


def _num(d: Mapping, key: str, where: str, null: bool = False) -> Any:
    v = d[key] if key in d else _missing(where, key)
    if v is None and null:
        return None
    if not is_number(v):
        raise _bad(f"{where}{key}", "a number" + (" or null" if null else ""), v)
    return v


def _int(d: Mapping, key: str, where: str) -> int:
    v = d[key] if key in d else _missing(where, key)
    if isinstance(v, bool) or not isinstance(v, int):
        raise _bad(f"{where}{key}", "an integer", v)
    return v


def _str(d: Mapping, key: str, where: str, null: bool = False) -> Any:
    v = d[key] if key in d else (None if null else _missing(where, key))
    if v is None and null:
        return None
    if not isinstance(v, str):
        raise _bad(f"{where}{key}", "a string", v)
    return v


def _bool(d: Mapping, key: str, where: str) -> bool:
    v = d[key] if key in d else _missing(where, key)
    if not isinstance(v, bool):
        raise _bad(f"{where}{key}", "true or false", v)
    return v


def _table(v: Any, where: str) -> Mapping:
    if not isinstance(v, dict):
        raise _bad(where, "an object", v)
    return v


def _numbers_by_id(d: Mapping, key: str, where: str) -> dict[str, float | None]:
    table = _table(d[key] if key in d else _missing(where, key), f"{where}{key}")
    return {k: _num(table, k, f"{where}{key}.", null=True) for k in table}


def _counts(v: Any, where: str) -> dict[str, int]:
    table = _table(v, where)
    return {k: _int(table, k, f"{where}.") for k in table}


def _ids(d: Mapping, key: str, where: str) -> tuple[str, ...]:
    v = d[key] if key in d else _missing(where, key)
    if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
        raise _bad(f"{where}{key}", "a list of vehicle ids", v)
    return tuple(v)


def _missing(where: str, key: str) -> Any:
    raise _Bad(f"{where}{key}", "missing (docs/metrics.md lists the fields)")


def _opt(value: Any, out: dict, key: str) -> None:
    if value is not None:
        out[key] = value

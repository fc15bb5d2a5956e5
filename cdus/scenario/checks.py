"""How is a value checked, and how is a problem worded? The one validation toolkit.

Every section validator of the scenario file (and the run-time link commands) collects
its problems in a :class:`Problems` and checks values with its methods, so one kind of
mistake reads the same wherever it is made:

    rates.control: must be a number >= 0.001 and <= 100000 Hz, got -1
    rates.control: must be a number >= 0.001 and <= 100000 Hz, got the string "fast"
    scenario.durration: unknown key; did you mean "duration"? valid keys here: name, description, ...
    graph.topology: unknown topology "rign" (did you mean "ring"?); choose one of ring, chain, ...
    link.down[0].src: "usv9" is not a vehicle (did you mean "usv1"?); ids are usv1, usv2 or "*" (any vehicle)

A number's range is its field's bound in :data:`cdus.wire.bounds.BOUNDS` (``p.number(v, field,
"rates.control")``), written once for the config, the run-time commands and the wire alike.

The rule for "got": a value of the wrong type is described with its type ("the string
"fast""), a value of the right type out of range is shown as written ("-1"); values are
always shown in TOML spelling. A ``note`` (e.g. " (set in [defaults])") goes after the
value. A check returns the checked value, or None after recording the problem.
"""

from __future__ import annotations

import difflib
import math
from typing import Any, Iterable, Iterator, Mapping, Sequence

from cdus.wire.bounds import BOUNDS, Bound, finite, is_number  # noqa: F401 (is_number: importable from here too)
from cdus.wire.text import is_printable, printable

ANY_VEHICLE = "*"  # the wildcard of link.override/down src and dst


# --------------------------------------------------------------------------- spelling


def quote(s: Any) -> str:
    """``usv1`` -> ``"usv1"``."""
    return '"' + str(s).replace('"', '\\"') + '"'


#: A value shown in a message is cut after this many characters.
MAX_SHOWN = 200


def show(v: Any) -> str:
    """A value as the user wrote it in TOML (cut after :data:`MAX_SHOWN` characters)."""
    text = _show(v)
    return text if len(text) <= MAX_SHOWN else text[:MAX_SHOWN] + f"... ({len(text)} characters)"


def _show(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return quote(v)
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else str(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_show(x) for x in v[:MAX_SHOWN]) + (", ...]" if len(v) > MAX_SHOWN else "]")
    if isinstance(v, dict):
        items = list(v.items())
        return "{" + ", ".join(f"{k} = {_show(x)}" for k, x in items[:MAX_SHOWN]) + \
            (", ...}" if len(items) > MAX_SHOWN else "}")
    return repr(v)


def describe(v: Any) -> str:
    """A value with its TOML type: ``the string "fast"``, ``the number 3``, ``the table {...}``."""
    kind = ("boolean" if isinstance(v, bool) else "string" if isinstance(v, str)
            else "number" if isinstance(v, (int, float)) else "list" if isinstance(v, (list, tuple))
            else "table" if isinstance(v, dict) else None)
    return f"the {kind} {show(v)}" if kind else repr(v)


def num(x: float) -> str:
    """A bound or a limit in a message: 50.0 -> 50."""
    return f"{x:g}"


def did_you_mean(word: Any, options: Iterable[str]) -> str:
    """`` (did you mean "ring"?)`` when an option is close to ``word``, else ``""``."""
    close = difflib.get_close_matches(str(word), list(options), n=1, cutoff=0.6)
    return f" (did you mean {quote(close[0])}?)" if close else ""


def join(prefix: str, key: Any) -> str:
    """The dotted field name of ``key`` inside ``prefix`` (``""``: top level)."""
    return f"{prefix}.{key}" if prefix else str(key)


def _bounds(b: Bound) -> str:
    text = b.text()
    return f" {text}" if text else ""


def _as_bound(key: str | None, gt: float | None, ge: float | None, le: float | None, allow_inf: bool) -> Bound:
    """The field's bound from cdus.wire.bounds.BOUNDS (``key``), or one from gt/ge/le."""
    if key is not None:
        return BOUNDS[key]
    lo, lo_open = (gt, True) if gt is not None else (ge, False) if ge is not None else (-math.inf, False)
    return Bound(lo, math.inf if le is None else le, lo_open=lo_open, inf_ok=allow_inf)


def names(ids: Iterable[str], most: int = 10) -> str:
    """``a, b, c`` for a few names; past ``most``, the first ones and how many more."""
    ids = list(ids)
    shown = ", ".join(ids[:most])
    return shown if len(ids) <= most else f"{shown} and {len(ids) - most} more"


class IdList(list):
    """The vehicle ids, in file order, with O(1) membership (``id in ids``) and index
    (:meth:`position`): references to ids are checked once each, so the checks stay
    linear in the size of the file."""

    def __init__(self, ids: Iterable[str] = ()) -> None:
        super().__init__(ids)
        self._pos = {v: j for j, v in enumerate(self)}

    def __contains__(self, v: object) -> bool:
        try:
            return v in self._pos
        except TypeError:  # unhashable
            return False

    def position(self, v: str) -> int:
        return self._pos[v]


# --------------------------------------------------------------------------- problems

#: Problems kept for the error message; the rest are counted ("and N more problems").
MAX_PROBLEMS = 100
#: "did you mean" suggestions made at most (each compares the word with every option).
MAX_SUGGESTIONS = 50


class Problems:
    """Collects (field, message) problems, each once, in the order they were found.

    ``len()`` counts every problem; :attr:`items` holds the first :data:`MAX_PROBLEMS`
    and then one line saying how many more there are, so a file with thousands of
    mistakes gives a readable error in time linear in its size.
    """

    def __init__(self) -> None:
        self._kept: list[tuple[str, str]] = []
        self._seen: set[tuple[str, str]] = set()
        self._more = 0
        self.suggestions = 0

    @property
    def items(self) -> list[tuple[str, str]]:
        more = [("...", f"and {self._more} more problem{'s' if self._more != 1 else ''} not shown; fix these "
                        f"first")] if self._more else []
        return self._kept + more

    def add(self, field: str, message: str) -> None:
        key = (field, message)
        if key in self._seen:
            return
        self._seen.add(key)
        if len(self._kept) < MAX_PROBLEMS:
            self._kept.append(key)
        else:
            self._more += 1

    def __len__(self) -> int:
        return len(self._seen)

    def __iter__(self) -> Iterator[tuple[str, str]]:
        return iter(self.items)

    def since(self, mark: int) -> bool:
        """Were problems added after ``mark = len(problems)``?"""
        return len(self) > mark

    def suggest(self, word: Any, options: Iterable[str]) -> str:
        """:func:`did_you_mean`, at most :data:`MAX_SUGGESTIONS` times per file."""
        if self.suggestions >= MAX_SUGGESTIONS:
            return ""
        self.suggestions += 1
        return did_you_mean(word, options)

    # ---- scalars

    def number(self, v: Any, field: str, key: str | None = None, *, gt: float | None = None,
               ge: float | None = None, le: float | None = None, unit: str = "", note: str = "",
               allow_inf: bool = False) -> float | None:
        """A finite number (or +inf where the bound allows it) within the bounds, as a float:
        the bound of ``key`` in cdus.wire.bounds.BOUNDS, else the one gt/ge/le give."""
        b = _as_bound(key, gt, ge, le, allow_inf)
        want = f"a number{_bounds(b)}{unit}"
        if not is_number(v):
            self.add(field, f"must be {want}, got {describe(v)}{note}")
            return None
        if not finite(v) and not (b.inf_ok and v == math.inf):
            self.add(field, f"must be a finite number{_bounds(b)}{unit}, got {show(v)}{note}")
            return None
        if not b.holds(v):
            self.add(field, f"must be {want}, got {show(v)}{note}")
            return None
        return float(v)

    def probability(self, v: Any, field: str, what: str, note: str = "") -> float | None:
        """A number in [0, 1]; ``what`` says what it is the probability of."""
        if not finite(v) or not 0.0 <= v <= 1.0:
            got = show(v) if is_number(v) else describe(v)
            self.add(field, f"must be a probability in [0, 1] ({what}), got {got}{note}")
            return None
        return float(v)

    def integer(self, v: Any, field: str, *, ge: int | None = None, unit: str = "", note: str = "") -> int | None:
        """An integer (not a float, not a boolean) >= ``ge``."""
        want = f"an integer{_bounds(_as_bound(None, None, ge, None, False))}{unit}"
        if not isinstance(v, int) or isinstance(v, bool):
            self.add(field, f"must be {want}, got {describe(v)}{note}")
            return None
        if ge is not None and v < ge:
            self.add(field, f"must be {want}, got {show(v)}{note}")
            return None
        return v

    def boolean(self, v: Any, field: str, *, true: str = "", false: str = "", note: str = "") -> bool | None:
        """true or false; ``true``/``false`` say what each means, e.g. " (per-link FIFO)"."""
        if not isinstance(v, bool):
            self.add(field, f"must be true{true} or false{false}, got {describe(v)}{note}")
            return None
        return v

    def string(self, v: Any, field: str, *, nonempty: bool = False, note: str = "",
               one_line: bool = False) -> str | None:
        """A string (a non-empty one with ``nonempty``; with ``one_line``, one a terminal shows as
        it is: no control characters, escape sequences or line breaks)."""
        if not isinstance(v, str) or (nonempty and not v.strip()):
            self.add(field, f"must be a {'non-empty ' if nonempty else ''}string, got {describe(v)}{note}")
            return None
        if one_line and not is_printable(v):
            self.add(field, f"must be printable text on one line (no control characters, escape sequences or "
                            f"line breaks: it is printed and names files), got '{printable(v, 80)}'{note}")
            return None
        return v

    def choice(self, v: Any, field: str, options: Iterable[str], what: str, *, note: str = "",
               extra: str = "") -> str | None:
        """One of ``options``: ``unknown <what> "x" (did you mean "y"?); choose one of a, b<extra>``."""
        options = list(options)
        if isinstance(v, str) and v in options:
            return v
        self.add(field, f"unknown {what} {show(v)}{note}{self.suggest(v, options)}; "
                        f"choose one of {', '.join(options)}{extra}")
        return None

    def vehicle(self, v: Any, field: str, ids: Sequence[str] | None, *, wildcard: bool = False) -> str | None:
        """A vehicle id, or ``"*"`` where ``wildcard``. ``ids = None``: the ids are not known
        yet (a vehicle's own id is bad), so only the type is checked."""
        star = f" or {quote(ANY_VEHICLE)} (any vehicle)" if wildcard else ""
        if not isinstance(v, str):
            self.add(field, f"must be a vehicle id{star}, got {describe(v)}")
            return None
        if (wildcard and v == ANY_VEHICLE) or ids is None or v in ids:
            return v
        self.add(field, f"{quote(v)} is not a vehicle{self.suggest(v, ids)}; ids are "
                        f"{names(ids) or '(none)'}{star}")
        return None

    # ---- compounds

    def vector(self, v: Any, field: str, n: int, what: str, note: str = "", key: str | None = None
               ) -> tuple[float, ...] | None:
        """A list of ``n`` finite numbers (``what`` they are, e.g. "a usv position [x, y] in m"),
        each within the bound of ``key`` (cdus.wire.bounds.BOUNDS) if given."""
        b = BOUNDS[key] if key is not None else None
        if isinstance(v, list) and len(v) == n and all(finite(x) and (b is None or b.holds(x)) for x in v):
            return tuple(float(x) for x in v)
        got = f"{len(v)} numbers {show(v)}" if isinstance(v, list) and all(map(is_number, v)) else describe(v)
        self.add(field, f"must be a list of {n} numbers"
                        f"{'' if b is None else ' ' + b.text()} ({what}), got {got}{note}")
        return None

    def table(self, v: Any, field: str, example: str, note: str = "") -> dict | None:
        """A table; ``example`` shows one (``{ base = 0.1 }`` or ``a [rates] section``)."""
        if not isinstance(v, dict):
            self.add(field, f"must be a table, e.g. {example}, got {describe(v)}{note}")
            return None
        return v

    def tables(self, v: Any, field: str, section: str, hint: str = "") -> list[dict]:
        """An array of tables (``[[section]]``), or [] after recording the problem."""
        if not isinstance(v, list) or not all(isinstance(t, dict) for t in v):
            self.add(field, f"must be an array of tables ([[{section}]] sections{hint}), got {describe(v)}")
            return []
        return v

    def unknown_keys(self, table: Mapping, allowed: Iterable[str], prefix: str, *, what: str = "key",
                     valid: str | None = None, skip: Iterable[str] = ()) -> None:
        """Every key of ``table`` not in ``allowed``: ``unknown key; did you mean "x"? valid keys here: ...``."""
        allowed = list(allowed)
        skip = set(skip)
        for key in table:
            if key in allowed or key in skip:
                continue
            close = difflib.get_close_matches(str(key), allowed, n=1, cutoff=0.6) \
                if self.suggestions < MAX_SUGGESTIONS else []
            self.suggestions += 1
            hint = f"did you mean {quote(close[0])}? " if close else ""
            self.add(join(prefix, key), f"unknown {what}; {hint}{valid or f'valid {what}s here'}: "
                                        f"{', '.join(allowed)}")

    def missing(self, field: str, hint: str) -> None:
        """A required key is absent: ``missing; <hint>``."""
        self.add(field, f"missing; {hint}")

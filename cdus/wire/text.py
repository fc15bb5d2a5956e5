"""How is text that came over the wire made safe to print, log or store?

Anything a process prints that another process (or an outsider on an open fleet) wrote
goes through :func:`printable` first: control characters (ANSI escapes, carriage returns,
bells, newlines that would forge a log line) are shown escaped, not acted on, and the
text is cut to a bound, so a message can neither repaint a terminal nor fake a line in a
log. Pure; no I/O.
"""

from __future__ import annotations

import unicodedata

MAX_PRINTABLE = 300


def _unprintable(ch: str) -> bool:
    """A control or format character (Cc, Cf, Cs, Co, Cn) or a line separator: what a terminal
    may act on rather than show."""
    return unicodedata.category(ch)[0] == "C" or ch in "\u2028\u2029"


def is_printable(text: str) -> bool:
    """Does ``text`` reach a terminal as it is (:func:`printable` would change nothing but its length)?"""
    return not any(_unprintable(ch) for ch in text)


def printable(text: object, limit: int = MAX_PRINTABLE) -> str:
    """``text`` with every control or format character escaped (``\\x1b``, ``\\n``, ``\\u202e``),
    cut to ``limit`` characters (marked with an ellipsis). Non-strings are shown by ``repr``."""
    if not isinstance(text, str):
        text = repr(text)
    out = []
    size = 0
    for ch in text:
        if _unprintable(ch):
            piece = ch.encode("unicode_escape").decode("ascii") if ch.isascii() or ord(ch) > 0xff \
                else f"\\x{ord(ch):02x}"
        else:
            piece = ch
        if size + len(piece) > limit:
            out.append("…")
            break
        out.append(piece)
        size += len(piece)
    return "".join(out)

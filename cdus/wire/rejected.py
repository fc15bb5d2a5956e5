"""Why was an input refused? The one result a decoder or a parse returns instead of raising.

Every decoder of :mod:`cdus.wire` returns the record it decoded or ``Rejected(reason)``, and
never raises, so a receiver counts the reason and drops the message without a try/except:

    msg = decode_omega(payload)
    if isinstance(msg, Rejected):
        counters[msg.reason] += 1

A decoder's reason is a short lowercase word (``malformed``, ``version``, ``type``, ``range``,
...) that its docstring lists; the receivers count them by name in their ``rejected_by_reason``.
A parse of a run-time command (:mod:`cdus.commands`) gives the reason in words (for a person,
short enough for a reply) and, where one field is at fault, that field's name as the user wrote
it (``k``, ``phases.usv2``, ``vehicle``). It is the lowest layer's (cdus.wire) so that every
decoder and parse above can return it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Rejected:
    """An input refused: ``reason`` (what is wrong, and for a person the fix) and the ``field``
    at fault (None: the input as a whole)."""

    reason: str
    field: str | None = None

    def __str__(self) -> str:
        return f"{self.field}: {self.reason}" if self.field else self.reason

    def under(self, prefix: str) -> "Rejected":
        """The same refusal with its field named inside ``prefix`` (``phases`` + ``usv2`` ->
        ``phases.usv2``; an index ``[0]`` is appended as is)."""
        if not self.field:
            return Rejected(self.reason, prefix)
        sep = "" if self.field.startswith("[") else "."
        return Rejected(self.reason, f"{prefix}{sep}{self.field}")

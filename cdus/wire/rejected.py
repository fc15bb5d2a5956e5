"""Why was an input refused? The one result a parse or a decoder returns instead of raising.

A decoder or a parse returns what it made, or a :class:`Rejected`: the reason in words (for a
person, and short enough for a reply) and, where one field is at fault, that field's name as
the user wrote it (``k``, ``phases.usv2``, ``vehicle``). It is the lowest layer's (cdus.wire)
so that every decoder above can return it.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Rejected:
    """An input refused: ``reason`` (what is wrong and the fix) and the ``field`` at fault (None:
    the input as a whole)."""

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

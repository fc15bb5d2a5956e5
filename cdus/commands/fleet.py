"""What may an operator ask of the whole fleet? Stop, pause and resume.

They take no fields. They are the clocks' own to carry out (the world pauses its grants or the
wall clock, and stops the run), so none applies to a vehicle's node: :meth:`apply` says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

from cdus.commands.base import Applied, Names, Rejected, unknown_keys


class _FleetCommand:
    NAMES: ClassVar[Names]
    KEYS: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def parse(cls, fields: Mapping[str, Any]) -> Any:
        bad = unknown_keys(fields, cls.KEYS)
        return bad if bad is not None else cls()

    def fields(self) -> dict:
        return {}

    def apply(self, node: Any, tick: int, context: Any = None) -> Applied | Rejected:
        """A fleet's command changes no vehicle's node: the clock carries it out."""
        return Rejected(f"the fleet's clock carries out a {self.NAMES.cli}, not a vehicle")


@dataclass(frozen=True)
class Stop(_FleetCommand):
    """End the run after the present tick; every process writes its metrics."""

    NAMES: ClassVar[Names] = Names(cli="stop", op="stop")


@dataclass(frozen=True)
class Pause(_FleetCommand):
    """Pause the whole fleet (lockstep: no more grants; realtime: the clock stands still)."""

    NAMES: ClassVar[Names] = Names(cli="pause", op="pause")


@dataclass(frozen=True)
class Resume(_FleetCommand):
    """Resume a paused fleet."""

    NAMES: ClassVar[Names] = Names(cli="resume", op="resume")

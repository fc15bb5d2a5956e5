"""What may change in the radio at run time? The transmit power and the station's place.

With a ``[radio]`` table (docs/radio.md), a radio command sets ``tx_power`` (dBm) and/or moves
the ``station`` ([x, y] or [x, y, z] m) for messages sent from simulated time ``at`` (none or
negative: as soon as possible). Its numbers are checked as the scenario's
(cdus.scenario.radio.validate_radio_update). A scenario event (``action = "radio"``) carries
the same two keys at its top level; :meth:`Radio.parse` takes them in the command's shape
(cdus.commands.parse.parse_event moves them).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

from cdus.commands.base import Applied, Names, Rejected, config_rejected, keyed_table, when
from cdus.commands.effect import tick_of
from cdus.scenario.errors import ConfigError
from cdus.scenario.radio import validate_radio_update

ADHOC = ('this fleet\'s radio is ad hoc (topology = "adhoc"): no station relays its messages, so moving one '
         'changes nothing; give tx_power only, or run a scenario with topology = "station"')


@dataclass(frozen=True)
class Radio:
    """A new ``tx_power`` (dBm) and/or ``station`` (x, y, z m) from simulated time ``at``."""

    tx_power: float | None
    station: tuple[float, float, float] | None
    at: float | None = None

    NAMES: ClassVar[Names] = Names(cli="radio", op="radio", event="radio")
    KEYS: ClassVar[tuple[str, ...]] = ("radio", "at")
    CHANGE_KEYS: ClassVar[tuple[str, ...]] = ("tx_power", "station")

    @classmethod
    def parse(cls, fields: Mapping[str, Any]) -> "Radio | Rejected":
        """From ``{"radio": {tx_power, station}, "at": s | < 0 | None}``."""
        raw = keyed_table(fields, cls.KEYS, "radio", "{ tx_power = 10.0 }")
        if isinstance(raw, Rejected):
            return raw
        try:
            tx, station = validate_radio_update(raw, "radio command")
        except ConfigError as e:
            return config_rejected(e, "radio")
        at = when(fields)
        if isinstance(at, Rejected):
            return at
        return cls(tx, station, at)

    def change(self) -> dict:
        """The change as a radio table (what the wire and the events carry)."""
        out: dict = {}
        if self.tx_power is not None:
            out["tx_power"] = self.tx_power
        if self.station is not None:
            out["station"] = list(self.station)
        return out

    def fields(self) -> dict:
        return {"radio": self.change(), "at": -1.0 if self.at is None else self.at}

    def topology_problem(self, topology: str | None) -> Rejected | None:
        """A station moved in an ad hoc fleet (which has none) is refused."""
        if topology == "adhoc" and self.station is not None:
            return Rejected(ADHOC, "station")
        return None

    def apply(self, node: Any, at: float, context: Any = None) -> Applied | Rejected:
        """Change ``node``'s radio channel for messages sent from ``at``."""
        radio = getattr(node, "radio", None)
        if radio is None:
            return Rejected("this scenario has no [radio] table")
        try:
            radio.channel.update(at, tx_power_dbm=self.tx_power, station=self.station)
        except ValueError as e:
            return Rejected(str(e))
        return Applied(tick_of(at, node.period), at)

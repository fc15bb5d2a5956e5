"""What may change in the link at run time? A ``[link]`` table merged over the one in force.

A link command carries keys of the scenario's ``[link]`` table (docs/config.md) and the
simulated time its messages are affected from (``at``; none or a negative one: as soon as every
vehicle can take it, cdus.commands.effect.effect_time). The table is checked as the scenario's
(cdus.scenario.link.validate_link) when parsed, and again merged over the table in force when
applied (a change that leaves the merged table invalid is refused there).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping, Sequence

from cdus.commands.base import Applied, Names, Rejected, config_rejected, freeze, keyed_table, taken, thaw, when
from cdus.commands.effect import tick_of
from cdus.scenario.config import nesting_problem
from cdus.scenario.errors import ConfigError
from cdus.scenario.link import merge_link_tables, validate_link

#: a link table's depth (link.override[...].delay.base is 3 deep)
LINK_DEPTH = 4



@dataclass(frozen=True)
class Link:
    """Link faults ``table`` (keys of [link]) for messages sent from simulated time ``at``
    (None: as soon as possible)."""

    table: tuple  # the table, frozen (cdus.commands.base.freeze; .link_table() gives it back)
    at: float | None = None

    NAMES: ClassVar[Names] = Names(cli="link", op="link")
    KEYS: ClassVar[tuple[str, ...]] = ("link", "at")

    @classmethod
    def parse(cls, fields: Mapping[str, Any]) -> "Link | Rejected":
        """From ``{"link": {...}, "at": s | < 0 | None}``."""
        raw = keyed_table(fields, cls.KEYS, "link", "{ loss = 0.3 }")
        if isinstance(raw, Rejected):
            return raw
        if nesting_problem(raw, LINK_DEPTH):
            return Rejected("nested too deep", "link")
        try:
            validate_link(raw, None, "link command")
        except ConfigError as e:
            return config_rejected(e, "link")
        at = when(fields)
        if isinstance(at, Rejected):
            return at
        return cls(freeze(raw), at)

    def link_table(self) -> dict:
        """The [link] keys this command changes, as given."""
        return thaw(self.table)

    def fields(self) -> dict:
        return {"link": self.link_table(), "at": -1.0 if self.at is None else self.at}

    def merged(self, base: Mapping[str, Any], ids: Sequence[str] | None) -> dict | Rejected:
        """This change over the table in force ``base``, checked whole against the fleet's ids."""
        out = merge_link_tables(dict(base), self.link_table())
        try:
            validate_link(out, ids, "link command")
        except ConfigError as e:
            return config_rejected(e, "link")
        return out

    def apply(self, node: Any, at: float, context: tuple[Mapping[str, Any], Sequence[str]] = ({}, ())
              ) -> Applied | Rejected:
        """Set the merged link on ``node`` for messages sent from ``at`` (``context``: the table
        in force and the fleet's ids); a policy or timeout in it changes the stale-neighbour
        policy from the first tick at or after. Applied from the time the node took."""
        base, ids = context
        merged = self.merged(base, list(ids) or None)
        if isinstance(merged, Rejected):
            return merged
        spec = validate_link(merged, list(ids) or None, "link command")
        done = node.set_link(spec, at)
        if done and any(k in self.link_table() for k in ("policy", "timeout")):
            policy = node.set_policy(spec.policy, spec.timeout, tick_of(done.at, node.period))
            if not policy:
                return taken(policy)
        return taken(done)

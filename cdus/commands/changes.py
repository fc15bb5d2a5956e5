"""What may change in the formation and the paths at run time? Phases, offsets and a new path.

A formation command gives new phases ``{id: θ}`` (ω units; the other vehicles keep theirs) or
offsets on listening edges ``[{i, k, delta}]`` (exactly one of them), which the world resolves
into phases against the phases in force (:meth:`Formation.resolve`: the offsets with those on
the other edges must close around every cycle). A path command gives one vehicle a path table
as the config's (docs/config.md), checked against its dimension when applied. The checks are
the scenario's own (cdus.scenario.events: check_phases, check_offsets, check_path), so a change
refused in a file is refused at run time alike.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping, Sequence

from cdus.commands.base import (Applied, Names, Rejected, _shown, freeze, keyed_table, taken, thaw, unknown_keys,
                                vehicle_id)
from cdus.core.vocabulary import FORMATION, PATH
from cdus.scenario.config import nesting_problem
from cdus.scenario.events import check_offsets, check_path, check_phases, offsets_to_phases
from cdus.wire.bounds import BOUNDS

#: a path table's depth (center = [x, y, z] is 2 deep)
PATH_DEPTH = 2
#: a formation command's phases or offsets (a control map holds 64 entries; the world splits them)
MAX_ENTRIES = 64


@dataclass(frozen=True)
class Formation:
    """New ``phases`` ((id, θ), ...) or ``offsets`` ((i, k, Δ), ...): exactly one non-empty."""

    phases: tuple[tuple[str, float], ...] = ()
    offsets: tuple[tuple[str, str, float], ...] = ()

    NAMES: ClassVar[Names] = Names(cli="formation", op="formation", event=FORMATION)
    KEYS: ClassVar[tuple[str, ...]] = ("phases", "offsets")

    @classmethod
    def parse(cls, fields: Mapping[str, Any]) -> "Formation | Rejected":
        """From ``{"phases": {id: θ}, "offsets": [{i, k, delta}]}`` (either may be empty or absent)."""
        bad = unknown_keys(fields, cls.KEYS)
        if bad is not None:
            return bad
        phases, offsets = fields.get("phases") or {}, fields.get("offsets") or []
        if not isinstance(phases, dict):
            return Rejected(f"must be a table of vehicle = θ (ω units), e.g. {{ usv2 = 2.0944 }}, got "
                            f"{_shown(phases)}", "phases")
        if not isinstance(offsets, list):
            return Rejected(f'must be a list of {{ i = "usv2", k = "usv1", delta = ... }}, got {_shown(offsets)}',
                            "offsets")
        if bool(phases) == bool(offsets):
            return Rejected("give either phases (id = θ, ω units) or offsets (I listens to K: Δ), exactly one",
                            "phases")
        if len(phases) + len(offsets) > MAX_ENTRIES:
            return Rejected(f"at most {MAX_ENTRIES} entries in one command", "phases" if phases else "offsets")
        out_p = []
        for vid, theta in phases.items():
            v = vehicle_id({"v": vid}, "v")
            if isinstance(v, Rejected):
                return Rejected(v.reason, "phases")
            problem = BOUNDS["vehicle.phase"].problem(theta, " (ω units)")
            if problem is not None:
                return Rejected(problem, f"phases.{vid}")
            out_p.append((vid, float(theta)))
        out_o = []
        for j, row in enumerate(offsets):
            where = f"offsets[{j}]"
            if not isinstance(row, dict) or sorted(row) != ["delta", "i", "k"]:
                return Rejected('must be { i = "usv2", k = "usv1", delta = ... } (i listens to k)', where)
            for key in ("i", "k"):
                v = vehicle_id(row, key)
                if isinstance(v, Rejected):
                    return v.under(where)
            problem = BOUNDS["graph.edge.delta"].problem(row["delta"], " (ω units)")
            if problem is not None:  # named by its pair, as a ground station's offsets.I.K=Δ
                return Rejected(problem, f"offsets.{row['i']}.{row['k']}")
            out_o.append((row["i"], row["k"], float(row["delta"])))
        return cls(tuple(out_p), tuple(out_o))

    def fields(self) -> dict:
        return {"phases": dict(self.phases), "offsets": [{"i": i, "k": k, "delta": d} for i, k, d in self.offsets]}

    def resolve(self, ids: Sequence[str], current: Sequence[float], edges: Sequence[Any], directed: bool
                ) -> "Formation | Rejected":
        """The phases this command sets in a fleet of ``ids`` whose phases in force are ``current``
        on graph ``edges`` (.i, .k): checked ids, and offsets turned into phases (in ids' order)."""
        if self.phases:
            checked = check_phases(dict(self.phases), ids)
            if isinstance(checked, tuple):
                return Rejected(checked[1], "phases" + (f".{checked[0]}" if checked[0] else ""))
        else:
            given = check_offsets([{"i": i, "k": k, "delta": d} for i, k, d in self.offsets], ids, edges, directed)
            if isinstance(given, tuple):
                return Rejected(given[1], "offsets" + given[0])
            checked = offsets_to_phases(ids, current, edges, given, directed)
            if isinstance(checked, str):
                return Rejected(checked, "offsets")
        return Formation(tuple((vid, checked[vid]) for vid in ids if vid in checked))

    def apply(self, node: Any, tick: int, context: Sequence[str] = ()) -> Applied | Rejected:
        """Set the (resolved) phases on ``node`` from ``tick``; ``context``: the fleet's ids."""
        if self.offsets:
            return Rejected("offsets are resolved into phases first (Formation.resolve)", "offsets")
        ids = list(context)
        checked = check_phases(dict(self.phases), ids)
        if isinstance(checked, tuple):
            return Rejected(checked[1], "phases" + (f".{checked[0]}" if checked[0] else ""))
        return taken(node.set_formation({ids.index(vid): theta for vid, theta in checked.items()}, tick))


@dataclass(frozen=True)
class Path:
    """Vehicle ``vehicle`` follows the path ``table`` (sorted items, nested tables frozen)."""

    vehicle: str
    table: tuple  # the path table, frozen (cdus.commands.base.freeze)

    NAMES: ClassVar[Names] = Names(cli="path", op="path", event=PATH)
    KEYS: ClassVar[tuple[str, ...]] = ("vehicle", "path")

    @classmethod
    def parse(cls, fields: Mapping[str, Any]) -> "Path | Rejected":
        """From ``{"vehicle": id, "path": {family, ...}}`` (checked for any dimension: a 3-D
        path's third coordinate is the vehicle's to take or refuse when applied)."""
        raw = keyed_table(fields, cls.KEYS, "path", '{ family = "circle", center = [0, 0], radius = 10 }')
        vid = vehicle_id(fields)
        if isinstance(raw, Rejected) or isinstance(vid, Rejected):
            return raw if isinstance(raw, Rejected) else vid
        if nesting_problem(raw, PATH_DEPTH):
            return Rejected("nested too deep", "path")
        found = None
        for dim in (2, 3):  # a table fit for either dimension is a path; the vehicle's is checked on apply
            checked = check_path(raw, dim)
            if not isinstance(checked, tuple):
                return cls(vid, freeze(raw))
            found = found or checked
        return Rejected(found[1], "path" + (f".{found[0]}" if found[0] else ""))

    def path_table(self) -> dict:
        """The path table as given (nested tables and lists as they were)."""
        return thaw(self.table)

    def fields(self) -> dict:
        return {"vehicle": self.vehicle, "path": self.path_table()}

    def checked_for(self, dim: int) -> Any:
        """The cdus.core.paths.Path a vehicle of ``dim`` axes follows, or why it cannot."""
        checked = check_path(self.path_table(), dim)
        if isinstance(checked, tuple):
            return Rejected(f"{checked[1]} (vehicle {self.vehicle} is {dim}-D)",
                            "path" + (f".{checked[0]}" if checked[0] else ""))
        return checked

    def apply(self, node: Any, tick: int, context: Sequence[str] = ()) -> Applied | Rejected:
        """Set the path on ``node`` from ``tick`` (``context``: the fleet's ids, to check the node
        is this command's vehicle; empty: not checked)."""
        if context and list(context)[node.index] != self.vehicle:
            return Rejected(f"this path is for {self.vehicle}, not {list(context)[node.index]}", "vehicle")
        path = self.checked_for(node.vehicle.dim)
        if isinstance(path, Rejected):
            return path
        return taken(node.set_path(path, tick))


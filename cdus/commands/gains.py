"""Which guidance gains may a vehicle take at run time? The gains rule, written once.

A gains command names ``k`` (the path gain: one number for every axis, or with one vehicle
named, one per axis) and/or ``c`` (the coordination gain), each a finite number > 0 within
``gains.k`` / ``gains.c`` (cdus.wire.bounds). For one vehicle, k's length must be its number
of axes and both gains must be below what the discrete controller takes at its rates, plant
and edge weights (cdus.core.gain_bounds, the bound the scenario's [gains] is checked against).
:class:`Gains` is the command; :func:`expand_k` is the one place a single k becomes per-axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping

from cdus.commands.base import Applied, Names, Rejected, _shown, keyed_table, taken, unknown_keys, vehicle_id
from cdus.core.gain_bounds import gains_problem_for_rate
from cdus.wire.bounds import BOUNDS

GAIN_KEYS = ("k", "c")
MAX_AXES = 3


def expand_k(k: float | tuple[float, ...], dim: int) -> tuple[float, ...]:
    """One k per axis: a number for every one of ``dim`` axes, or the per-axis tuple as given."""
    return tuple(float(x) for x in k) if isinstance(k, tuple) else (float(k),) * dim


def gains_table(raw: Any, *, one_vehicle: bool) -> tuple[float | tuple[float, ...] | None, float | None] | Rejected:
    """``(k, c)`` from a gains table ``{k = number | [per axis], c = number}`` (None: not given),
    or why not. A per-axis k needs ``one_vehicle`` (boats have 2 axes, drones 3)."""
    if not isinstance(raw, dict):
        return Rejected(f"must be a table of k and/or c, e.g. {{ k = 2.0, c = 0.5 }}, got {_shown(raw)}", "gains")
    bad = unknown_keys(raw, GAIN_KEYS)
    if bad is not None:
        return Rejected("unknown gain; gains are k (a number or, for one vehicle, one per axis) and c", bad.field)
    if not raw:
        return Rejected("changes nothing; give k=... and/or c=...", "gains")
    k = raw.get("k")
    if isinstance(k, (list, tuple)):
        if not one_vehicle:
            return Rejected("one value per axis needs one vehicle named (--vehicle): boats have 2 axes, drones "
                            "3; a single number sets every axis", "k")
        if not 0 < len(k) <= MAX_AXES or not all(BOUNDS["gains.k"].holds(x) for x in k):
            return Rejected(f"must be 1 to {MAX_AXES} finite numbers > 0 (one per axis), got {_shown(list(k))}", "k")
        k = tuple(float(x) for x in k)
    elif k is not None:
        if not BOUNDS["gains.k"].holds(k):
            return Rejected(f"must be a finite number > 0, got {_shown(k)}", "k")
        k = float(k)
    c = raw.get("c")
    if c is not None:
        if not BOUNDS["gains.c"].holds(c):
            return Rejected(f"must be a finite number > 0, got {_shown(c)}", "c")
        c = float(c)
    return k, c


@dataclass(frozen=True)
class Gains:
    """New guidance gains for ``vehicle`` (None: every vehicle): ``k`` (a number, or one per
    axis) and/or ``c``; a gain not given is kept."""

    k: float | tuple[float, ...] | None
    c: float | None
    vehicle: str | None = None

    NAMES: ClassVar[Names] = Names(cli="gains", op="gains", event=None, old_ops=("set_gains",))
    KEYS: ClassVar[tuple[str, ...]] = ("gains", "vehicle")

    @classmethod
    def parse(cls, fields: Mapping[str, Any]) -> "Gains | Rejected":
        """From ``{"gains": {k, c}, "vehicle": id | "" (every vehicle)}``."""
        raw = keyed_table(fields, cls.KEYS, "gains", "{ k = 2.0, c = 0.5 }")
        vid = vehicle_id(fields, empty_ok=True) if fields.get("vehicle") is not None else ""
        if isinstance(raw, Rejected) or isinstance(vid, Rejected):
            return raw if isinstance(raw, Rejected) else vid
        kc = gains_table(raw, one_vehicle=bool(vid))
        if isinstance(kc, Rejected):
            return kc
        return cls(kc[0], kc[1], vid or None)

    def fields(self) -> dict:
        """The wire's fields (cdus.wire.messages.COMMAND_OPS)."""
        g: dict = {}
        if self.k is not None:
            g["k"] = list(self.k) if isinstance(self.k, tuple) else self.k
        if self.c is not None:
            g["c"] = self.c
        return {"gains": g, "vehicle": self.vehicle or ""}

    def for_vehicle(self, dim: int, k0: tuple[float, ...], c0: float, *, control_hz: float | None = None,
                    plant: str = "ideal", physics_hz: float | None = None,
                    weight_sum: float = 0.0) -> tuple[tuple[float, ...], float] | Rejected:
        """The (k per axis, c) a vehicle of ``dim`` axes with gains ``k0``, ``c0`` takes from this
        command, checked against its rates (``control_hz`` None: not checked), or why not."""
        if isinstance(self.k, tuple) and len(self.k) != dim:
            return Rejected(f"must be {dim} numbers > 0 for this vehicle, got {list(self.k)}", "k")
        if control_hz is not None:
            problem = gains_problem_for_rate(self.k, self.c, control_hz, plant=plant, physics_hz=physics_hz,
                                             weight_sum=weight_sum)
            if problem is not None:
                return Rejected(problem)
        k = expand_k(self.k, dim) if self.k is not None else tuple(k0)
        return k, float(self.c if self.c is not None else c0)

    def apply(self, node: Any, tick: int, context: Mapping[str, Any] | None = None) -> Applied | Rejected:
        """Set the gains on ``node`` (a VehicleNode) from ``tick``; ``context``: its gain bounds'
        inputs (cdus.scenario.model.Scenario.gain_context), else taken from the node."""
        v = node.vehicle
        if context is None:
            hz = 1.0 / node.period
            context = {"control_hz": hz, "plant": v.plant, "physics_hz": hz * v.physics_steps,
                       "weight_sum": sum(ln.weight for ln in node.table.links)}
        kc = self.for_vehicle(v.dim, tuple(v.k), v.c, **context)
        if isinstance(kc, Rejected):
            return kc
        return taken(node.set_gains(kc[0], kc[1], tick))

"""Which formation and path are in force at a tick? The run-time changes every runner applies alike.

A fleet's formation is its offsets Δ_ik, the targets of ω_i - ω_k (docs/control.md §2).
They are reachable only when they come from per-vehicle phases, Δ_ik = θ_i - θ_k, so a
change of formation is given, on the wire and in every runner, as **phases**: θ (ω units,
float64) for some vehicles, from a tick on; the vehicles it does not name keep theirs.
Every process holds the same :class:`FormationSchedule` (the phases in force at the start,
the scenario's scheduled changes, then the ground stations' in the order the world relays
them) and computes Δ_ik = θ_i - θ_k with the same float64 operations, so the offsets in
force at a tick are the same bits in the in-process fleet, in every agent and in the
world's metrics recorder. Before the first change, the scenario's own Δs are used as they
are (so a run without a change is the run it always was).

Offsets given per edge are turned into phases where they enter
(:func:`phases_from_offsets`): the given Δs together with the Δs in force on every other
edge must close around every cycle (the same check as the config's ``[graph]``), and the
phases are solved along a spanning tree, the first vehicle keeping its phase.

A path change (:class:`PathChange`) gives one vehicle a new path from a tick; its ω carries
on (the formation does not jump), so the vehicle flies from where it is to the point
f_new(ω) and the guidance's -KΦ term takes it there (docs/control.md, "Changes at run time").

Pure: no I/O.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Sequence

from cdus.core import graph as graphs
from cdus.wire.bounds import MAX_PHASE  # noqa: F401 (|θ| above it is refused where a phase enters)


@dataclass(frozen=True)
class FormationChange:
    """From simulated time ``at`` on, the vehicles named in ``phases`` ((id, θ) pairs, in
    scenario order) have these phases; the others keep theirs."""

    at: float
    phases: tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class PathChange:
    """From simulated time ``at`` on, vehicle ``vehicle`` follows ``path`` (a validated path
    table as sorted pairs, lists as tuples: ``make_path(dict(path))``)."""

    at: float
    vehicle: str
    path: tuple[tuple[str, Any], ...]


class FormationSchedule:
    """The phases of every vehicle over ticks: ``base`` (the phases in force at the start)
    and updates ``(tick, {index: θ})``, applied in tick order, updates of the same tick in
    the order they were added. Every runner adds the same updates in the same order."""

    def __init__(self, base: Sequence[float]):
        self.base = tuple(float(x) for x in base)
        self._ticks: list[int] = []
        self._updates: list[tuple[tuple[int, float], ...]] = []

    def add(self, tick: int, phases: Mapping[int, float]) -> None:
        """Phases ``{vehicle index: θ}`` from ``tick`` on (after the updates of that tick already added)."""
        if tick < 0:
            raise ValueError(f"a formation change needs a tick >= 0, got {tick}")
        n = len(self.base)
        items = tuple(sorted((int(j), float(x)) for j, x in phases.items()))
        for j, x in items:
            if not 0 <= j < n or not math.isfinite(x):
                raise ValueError(f"a phase is a finite number for one of {n} vehicles, got vehicle {j}, θ = {x}")
        at = bisect.bisect_right(self._ticks, tick)
        self._ticks.insert(at, tick)
        self._updates.insert(at, items)

    @property
    def ticks(self) -> tuple[int, ...]:
        """The ticks at which a change applies, in order (one per update)."""
        return tuple(self._ticks)

    def count_by(self, n: int) -> int:
        """How many updates apply at or before tick ``n``."""
        return bisect.bisect_right(self._ticks, n)

    def changed_by(self, n: int) -> bool:
        """Has a change applied at or before tick ``n``?"""
        return bool(self._ticks) and self._ticks[0] <= n

    def phases_at(self, n: int) -> tuple[float, ...]:
        """Every vehicle's phase in force at tick ``n``."""
        theta = list(self.base)
        for tick, items in zip(self._ticks, self._updates):
            if tick > n:
                break
            for j, x in items:
                theta[j] = x
        return tuple(theta)

    def epochs(self) -> list[tuple[int, tuple[float, ...]]]:
        """``(tick, phases in force from it)`` for each distinct tick a change applies at, in
        order, built in one pass (phases_at for each would cost the square of the changes)."""
        theta = list(self.base)
        out = []
        for idx, (tick, items) in enumerate(zip(self._ticks, self._updates)):
            for j, x in items:
                theta[j] = x
            if idx + 1 == len(self._ticks) or self._ticks[idx + 1] != tick:
                out.append((tick, tuple(theta)))
        return out

    def offset(self, i: int, k: int, base_delta: float, n: int) -> float:
        """Δ_ik in force at tick ``n``: the scenario's ``base_delta`` before any change, θ_i - θ_k after."""
        if not self.changed_by(n):
            return base_delta
        theta = self.phases_at(n)
        return theta[i] - theta[k]


def base_phases(ids: Sequence[str], phases: Mapping[str, float], edges: Iterable[Any]) -> tuple[float, ...]:
    """The phases in force at the start: the vehicles' own ``phase`` when every edge's Δ is
    θ_i - θ_k of them (no ``delta`` given in [graph]), else phases solved from the edges' Δs
    along a spanning tree, the first vehicle keeping its ``phase``. ``edges``: (i, k, Δ) ids
    or objects with ``.i``, ``.k``, ``.delta``; they must be consistent (the config checks it)."""
    edges = list(edges)
    triples = graphs._triples(edges)
    if all(d == phases.get(i, 0.0) - phases.get(k, 0.0) for i, k, d in triples):
        return tuple(float(phases.get(v, 0.0)) for v in ids)
    solved = graphs.suggest_phases(ids, triples)
    shift = float(phases.get(ids[0], 0.0)) if ids else 0.0
    return tuple(solved[v] + shift for v in ids)


def phases_from_offsets(ids: Sequence[str], current: Sequence[float], edges: Iterable[tuple[str, str]],
                        given: Mapping[tuple[str, str], float], directed: bool
                        ) -> dict[str, float] | tuple[list[str], float]:
    """The phase updates that give the listening pairs ``given`` their Δ (``(i, k) -> Δ_ik``;
    in an undirected graph Δ_ki = -Δ_ik) while every other edge keeps θ_i - θ_k of
    ``current``: ``{id: θ}`` for the vehicles whose phase changes (the first vehicle keeps
    its own), or ``(cycle, sum)`` when the offsets do not close around a cycle
    (:func:`cdus.core.graph.inconsistent_cycle`). Pairs must be edges of the graph (checked
    by the caller)."""
    index = {v: j for j, v in enumerate(ids)}
    fixed: dict[tuple[str, str], float] = {}
    for (i, k), d in given.items():
        fixed[(i, k)] = float(d)
        if not directed:
            fixed[(k, i)] = -float(d)
    triples = [(i, k, fixed[(i, k)] if (i, k) in fixed else current[index[i]] - current[index[k]])
               for i, k in edges]
    found = graphs.inconsistent_cycle(ids, triples)
    if found is not None:
        return found
    solved = graphs.suggest_phases(ids, triples)
    shift = current[0] - solved[ids[0]] if ids else 0.0
    out = {}
    for j, v in enumerate(ids):
        theta = solved[v] + shift
        # a vehicle on no changed constraint keeps its phase to the bit (the tree's sums round)
        if abs(theta - current[j]) > 1e-9 * max(1.0, abs(theta), abs(current[j])):
            out[v] = theta
    return out

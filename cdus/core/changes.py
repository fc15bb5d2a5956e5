"""How does a run-time change reach a vehicle, and what became of it?

:class:`RunTimeChanges` is the part of :class:`cdus.core.node.VehicleNode` that takes the
run-time changes (link faults, stale-neighbour policy, guidance gains, formation phases, its
path) at a simulated time, so every runner applies them on the same tick
(cdus.core.formation). Each returns its outcome: :class:`Applied` (from which tick or time)
or :class:`Refused` (the reason), never an exception, so the caller (the agent, the
in-process fleet) reads the outcome of a command from the call, not off a counter.
The gains rule a command is checked against before it reaches here is cdus.commands.gains.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

from cdus.core.events import event_tick
from cdus.core.formation import FormationSchedule
from cdus.core.linkspec import LinkSpec
from cdus.core.models import UnknownName
from cdus.core.neighbours import NeighbourLink
from cdus.core.paths import Path
from cdus.core.policies import make_policy


@dataclass(frozen=True)
class Applied:
    """The change is in force from tick ``tick`` (``at``: the simulated time it applies from,
    for a link change, which applies to messages sent from then on)."""

    tick: int
    at: float | None = None

    def __bool__(self) -> bool:
        return True

    def or_raise(self) -> Applied:
        """This outcome (for a caller that treats a refusal as an error)."""
        return self


@dataclass(frozen=True)
class Refused:
    """The change was not taken; ``reason`` says why and what would be taken."""

    reason: str

    def __bool__(self) -> bool:
        return False

    def or_raise(self) -> Applied:
        """A refusal as a ValueError with its reason (for a caller that treats it as an error)."""
        raise ValueError(self.reason)


Outcome = Applied | Refused


def _schedule(changes: list[tuple], change: tuple) -> None:
    """Put ``change`` (a tuple whose first item is the tick it applies from) into ``changes``, kept
    in tick order: appended when it is the latest, as the world's always are (O(1); a sort at each
    made a flood of gains changes quadratic, and a restarted vehicle sent 18,000 of them spent
    10 s of CPU on them); one at the tick of a change already there replaces it (a step applies
    every change due, in order: the later is the one that shows)."""
    i = bisect.bisect_right(changes, change[0], key=lambda g: g[0])
    if i and changes[i - 1][0] == change[0]:
        changes[i - 1] = change
    else:
        changes.insert(i, change)


def _due(changes: list[tuple], n: int) -> tuple | None:
    """Take the changes of ``changes`` (in tick order) due at tick ``n`` out: the last of them (the
    one in force from ``n``), or None."""
    i = 0
    while i < len(changes) and changes[i][0] <= n:
        i += 1
    if i == 0:
        return None
    last = changes[i - 1]
    del changes[:i]
    return last


class RunTimeChanges:
    """The run-time changes of :class:`cdus.core.node.VehicleNode` (a mixin: it uses the node's
    attributes, set in the node's ``__init__``)."""

    def set_link(self, spec: LinkSpec, at: float) -> Outcome:
        """New link faults for messages sent from simulated time ``at`` on (not before the
        newest change): Applied with the time they apply from (``at``) and its tick, or Refused
        if this vehicle's link model cannot change at run time."""
        epochs = getattr(self.link, "epochs", None)
        if epochs is None:
            return Refused("this vehicle's link model cannot change at run time")
        at = max(at, epochs[-1][0])
        self.link.update(spec, at)
        self._floors.clear()  # the lookahead's delay bounds (waiting_for)
        return Applied(self._from(event_tick(at, self.period)), at)

    def set_policy(self, policy: str, timeout: float, tick: int) -> Outcome:
        """A new stale-neighbour policy (and its timeout, s) from tick ``tick`` on."""
        try:
            make_policy(policy, timeout)
        except UnknownName as e:
            return Refused(str(e))
        if not (isinstance(timeout, (int, float)) and timeout > 0):
            return Refused(f"the policy's timeout must be > 0 s, got {timeout}")
        _schedule(self._policies, (tick, policy, float(timeout)))
        return Applied(self._from(tick))

    def set_gains(self, k: tuple[float, ...], c: float, tick: int) -> Outcome:
        """New guidance gains from tick ``tick`` (or the next tick stepped)."""
        if len(k) != self.vehicle.dim or not all(x > 0 for x in k) or not c > 0:
            return Refused(f"gains need k > 0 ({self.vehicle.dim} values) and c > 0, got k = {k}, c = {c}")
        _schedule(self._gains, (tick, tuple(float(x) for x in k), float(c)))
        return Applied(self._from(tick))

    def set_formation(self, phases: dict[int, float], tick: int) -> Outcome:
        """Phases ``{vehicle index: θ}`` (ω units) from tick ``tick`` (or the next tick
        stepped); every other vehicle keeps its phase. Δ_ik becomes θ_i - θ_k on every link."""
        if self.formation is None:  # built without the scenario's phases: derive this node's own
            self.formation = FormationSchedule(self._local_phases())
        self.formation.add(tick, phases)
        return Applied(self._from(tick))

    def _from(self, tick: int) -> int:
        """The tick a change asked for ``tick`` is in force from: the next one stepped, if later."""
        return max(tick, self.tick)

    def _local_phases(self) -> list[float]:
        """Phases that reproduce this node's Δs, θ_i = 0 and θ_k = -Δ_ik (a node built alone)."""
        n = max((ln.k for ln in self._base_links), default=0)
        theta = [0.0] * (max(n, self.index) + 1)
        for ln in self._base_links:
            theta[ln.k] = -ln.delta
        return theta

    def set_path(self, path: Path, tick: int) -> Outcome:
        """A new path (of this vehicle's dimension) from tick ``tick`` (or the next tick stepped);
        ω carries on."""
        if path.dim != self.vehicle.dim:
            return Refused(f"a {self.vehicle.dim}-D vehicle needs a {self.vehicle.dim}-D path, got {path.dim}-D")
        self._paths.append((tick, path))
        self._paths.sort(key=lambda g: g[0])
        return Applied(self._from(tick))

    def _apply_changes(self, n: int) -> None:
        """The path and formation changes due at tick ``n``."""
        while self._paths and self._paths[0][0] <= n:
            self.vehicle.path = self._paths.pop(0)[1]
        f = self.formation
        if f is None:
            return
        count = f.count_by(n)
        if count == self._formation_at:
            return
        self._formation_at = count
        theta = f.phases_at(n)
        me = self.index
        self.table.links = tuple(NeighbourLink(ln.k, ln.weight, theta[me] - theta[ln.k]) for ln in self._base_links)

"""What may be done to one vehicle's process? Kill, pause, resume and restart it.

A vehicle fault names one vehicle. The launcher carries it out on the process (a signal, or a
new process); every other vehicle learns it as a roster change from the tick it lands on
(cdus.core.events: kill -> gone, pause -> paused, resume -> live, restart -> gone and live
again as a new process). :meth:`apply` gives a node that roster change, so the in-process
fleet and a neighbour's agent take a fault alike. Its three names differ on purpose: the CLI's
``pause-vehicle`` (``pause`` is the fleet's) and the wire's ``pause_vehicle``, written here only,
and the scenario event's ``pause`` (an event always names its vehicle), the core's word
(cdus.core.vocabulary.FAULT_ACTIONS, which the roster is planned with).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Mapping, Sequence

from cdus.commands.base import Applied, Names, Rejected, unknown_keys, vehicle_id
from cdus.core.events import RosterChange
from cdus.core.vocabulary import KILL, PAUSE, RESTART, RESUME


@dataclass(frozen=True)
class _VehicleFault:
    vehicle: str

    NAMES: ClassVar[Names]
    KEYS: ClassVar[tuple[str, ...]] = ("vehicle",)
    #: the roster states a neighbour sees from the fault's tick (in order) and whether the last is a new process
    STATES: ClassVar[tuple[str, ...]]
    FRESH: ClassVar[bool] = False

    @classmethod
    def parse(cls, fields: Mapping[str, Any]) -> Any:
        """From ``{"vehicle": id}``."""
        bad = unknown_keys(fields, cls.KEYS)
        if bad is not None:
            return bad
        vid = vehicle_id(fields)
        return vid if isinstance(vid, Rejected) else cls(vid)

    def fields(self) -> dict:
        return {"vehicle": self.vehicle}

    def roster(self, tick: int, index: int) -> tuple[RosterChange, ...]:
        """The roster changes this fault makes for the vehicle at ``index``, from ``tick``."""
        last = len(self.STATES) - 1
        return tuple(RosterChange(tick, index, s, self.FRESH and j == last) for j, s in enumerate(self.STATES))

    def apply(self, node: Any, tick: int, context: Sequence[str] = ()) -> Applied | Rejected:
        """Tell ``node`` (a VehicleNode; ``context``: the fleet's ids) of this fault from ``tick``."""
        if self.vehicle not in context:
            return Rejected(f"no vehicle {self.vehicle!r} in this fleet", "vehicle")
        for change in self.roster(tick, list(context).index(self.vehicle)):
            node.on_roster(change)
        return Applied(tick)


@dataclass(frozen=True)
class Kill(_VehicleFault):
    """SIGKILL the vehicle's process: gone from the fault's tick (a restart brings it back)."""

    NAMES: ClassVar[Names] = Names(cli="kill", op="kill", event=KILL)
    STATES: ClassVar[tuple[str, ...]] = ("gone",)


@dataclass(frozen=True)
class PauseVehicle(_VehicleFault):
    """SIGSTOP the process: paused (silent, its last ω held), gone once its lease lapses."""

    NAMES: ClassVar[Names] = Names(cli="pause-vehicle", op="pause_vehicle", event=PAUSE)
    STATES: ClassVar[tuple[str, ...]] = ("paused",)


@dataclass(frozen=True)
class ResumeVehicle(_VehicleFault):
    """SIGCONT a paused process: live again, carrying on where it was."""

    NAMES: ClassVar[Names] = Names(cli="resume-vehicle", op="resume_vehicle", event=RESUME)
    STATES: ClassVar[tuple[str, ...]] = ("live",)


@dataclass(frozen=True)
class Restart(_VehicleFault):
    """A new process for the vehicle: gone and live again at the fault's tick, rejoining where
    the world last saw it."""

    NAMES: ClassVar[Names] = Names(cli="restart", op="restart", event=RESTART)
    STATES: ClassVar[tuple[str, ...]] = ("gone", "live")
    FRESH: ClassVar[bool] = True


VehicleFault = Kill | PauseVehicle | ResumeVehicle | Restart
VEHICLE_FAULTS: tuple[type[_VehicleFault], ...] = (Kill, PauseVehicle, ResumeVehicle, Restart)
BY_EVENT = {f.NAMES.event: f for f in VEHICLE_FAULTS}
BY_OP = {f.NAMES.op: f for f in VEHICLE_FAULTS}

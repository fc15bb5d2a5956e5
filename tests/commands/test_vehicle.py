"""cdus.commands.vehicle and cdus.commands.fleet: a vehicle's faults, the fleet's commands."""

from __future__ import annotations

from cdus.commands.base import Applied, Rejected
from cdus.commands.fleet import Pause, Resume, Stop
from cdus.commands.vehicle import BY_EVENT, BY_OP, Kill, PauseVehicle, Restart, ResumeVehicle
from cdus.core.events import Event, RosterChange, plan_roster
from cdus.core.vocabulary import FAULT_ACTIONS

from .common import RecordedNode


def test_each_fault_gives_a_neighbour_the_roster_change_the_scenario_plans():
    ids = ["usv1", "usv2"]
    for fault in (Kill("usv2"), PauseVehicle("usv2"), ResumeVehicle("usv2"), Restart("usv2")):
        n = RecordedNode()
        assert fault.apply(n, 7, ids) == Applied(7)
        before = [Event(0.0, "pause", "usv2")] if isinstance(fault, ResumeVehicle) else []
        planned = [c for c in plan_roster([*before, Event(0.7, fault.NAMES.event, "usv2")], ids, 0.1) if c.tick == 7]
        assert n.calls == planned, fault
    assert Restart("usv2").roster(7, 1) == (RosterChange(7, 1, "gone"), RosterChange(7, 1, "live", True))
    assert Kill("usv9").apply(RecordedNode(), 7, ids) == Rejected("no vehicle 'usv9' in this fleet", "vehicle")


def test_faults_parse_their_vehicle_only():
    assert Kill.parse({"vehicle": "usv2"}) == Kill("usv2") and Kill("usv2").fields() == {"vehicle": "usv2"}
    assert Kill.parse({"vehicle": "usv2", "at": 1}) == Rejected("unknown; this command takes vehicle", "at")
    assert PauseVehicle.parse({}).field == "vehicle"
    assert tuple(BY_EVENT) == FAULT_ACTIONS  # each fault action the roster is planned with has its command
    assert sorted(BY_OP) == ["kill", "pause_vehicle", "restart", "resume_vehicle"]


def test_the_fleets_commands_take_nothing_and_change_no_node():
    for cls in (Stop, Pause, Resume):
        assert cls.parse({}) == cls() and cls().fields() == {}
        assert cls.parse({"x": 1}) == Rejected("unknown; this command takes nothing", "x")
        assert cls().apply(RecordedNode(), 3) == Rejected(f"the fleet's clock carries out a {cls.NAMES.cli}, not a "
                                                          "vehicle")

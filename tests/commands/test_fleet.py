"""cdus.commands.fleet: stop, pause and resume take no fields and change no vehicle's node."""

from __future__ import annotations

from cdus.commands.base import Rejected
from cdus.commands.fleet import Pause, Resume, Stop


def test_each_fleet_command_has_one_word_for_the_cli_and_the_wire():
    assert [(c.NAMES.cli, c.NAMES.op) for c in (Stop, Pause, Resume)] == [
        ("stop", "stop"), ("pause", "pause"), ("resume", "resume")]


def test_a_fleet_command_parses_from_no_fields_and_says_none():
    for c in (Stop, Pause, Resume):
        assert c.parse({}) == c() and c().fields() == {}


def test_a_fleet_command_with_a_field_is_refused_naming_it():
    r = Pause.parse({"vehicle": "usv1", "at": 1.0})
    assert r == Rejected("unknown; this command takes nothing", "at")  # sorted: the same one each time


def test_a_fleet_command_is_the_clocks_not_a_vehicles():
    r = Stop().apply(object(), 3)
    assert isinstance(r, Rejected) and r.reason == "the fleet's clock carries out a stop, not a vehicle"

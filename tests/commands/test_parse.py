"""cdus.commands.parse: the three entries give one command, any wire fields parse or are refused
naming a field, and every name round-trips."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings, strategies as st

from cdus.commands.base import Applied, Rejected
from cdus.commands.changes import Formation, Path
from cdus.commands.effect import effect_time, effect_tick, lead_ticks, never_applies
from cdus.commands.gains import Gains, expand_k
from cdus.commands.parse import BY_CLI, BY_EVENT, BY_OP, COMMANDS, decode_command, parse_cli, parse_event, parse_wire, wire_of
from cdus.commands.radio import Radio
from cdus.commands.vehicle import FAULT_EVENTS, Kill, PauseVehicle, Restart, ResumeVehicle
from cdus.core.events import ACTIONS, RosterChange
from cdus.scenario.events import CHANGE_ACTIONS
from cdus.wire.messages import COMMAND_OPS, LAUNCHER_OPS, encode_control

_scalar = st.one_of(st.none(), st.booleans(), st.integers(-2**63, 2**63 - 1), st.floats(), st.text(max_size=8))
_value = st.recursive(_scalar, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.text(max_size=6), inner, max_size=4)),
                      max_leaves=12)
_keys = st.sampled_from(["vehicle", "gains", "link", "at", "phases", "offsets", "path", "radio", "k", "c", "x"])


@settings(max_examples=600, deadline=None)
@given(op=st.sampled_from(sorted(BY_OP) + ["nope"]), fields=st.dictionaries(_keys, _value, max_size=4))
def test_any_wire_fields_parse_to_a_command_or_a_refusal_naming_a_field_never_raise(op, fields):
    got = parse_wire(op, fields)
    if isinstance(got, Rejected):
        assert got.reason and (got.field is None or isinstance(got.field, str))
        return
    assert type(got) is BY_OP[op]
    assert parse_wire(*wire_of(got)) == got  # what it sends reads back as itself
    hash(got)  # frozen: a command can key a table


@settings(max_examples=300, deadline=None)
@given(payload=st.binary(max_size=200) | st.builds(lambda op, f: encode_control(op, **f), st.sampled_from(sorted(COMMAND_OPS)),
                                                    st.dictionaries(_keys, _value, max_size=3)))
def test_any_payload_decodes_to_a_command_or_a_refusal(payload):
    got = decode_command(payload)
    assert isinstance(got, (Rejected, *COMMANDS))


def test_a_refusal_names_the_field_at_fault():
    assert parse_wire("gains", {"gains": {"k": -1.0}, "vehicle": ""}).field == "k"
    assert parse_wire("gains", {"gains": {"c": math.inf}, "vehicle": ""}).field == "c"
    assert parse_wire("gains", {"gains": {"q": 1.0}, "vehicle": ""}).field == "q"
    assert parse_wire("kill", {"vehicle": "a b"}).field == "vehicle"
    assert parse_wire("kill", {"vehicle": "usv1", "x": 1}).field == "x"
    assert parse_wire("formation", {"phases": {"usv1": math.nan}, "offsets": []}).field == "phases.usv1"
    assert parse_wire("formation", {"phases": {}, "offsets": [{"i": "a", "k": "b", "delta": 1e300}]}).field == "offsets.a.b"
    assert parse_wire("path", {"vehicle": "uav1", "path": {"family": "circle", "center": [0, 0], "radius": -1}}
                      ).field == "path.radius"
    assert parse_wire("link", {"link": {"loss": 3}, "at": -1.0}).field == "loss"
    assert parse_wire("link", {"link": {"loss": 0.1}, "at": math.inf}).field == "at"
    assert parse_wire("radio", {"radio": {"tx_power": 1e308}, "at": -1.0}).field == "tx_power"
    assert parse_wire("nope", {}).field == "op"


@pytest.mark.parametrize("cli, wire, event", [
    (("kill", [], "usv2", None), ("kill", {"vehicle": "usv2"}), {"at": 3.0, "action": "kill", "vehicle": "usv2"}),
    (("pause-vehicle", [], "usv2", None), ("pause_vehicle", {"vehicle": "usv2"}),
     {"at": 3.0, "action": "pause", "vehicle": "usv2", "duration": 2.0}),
    (("resume-vehicle", [], "usv2", None), ("resume_vehicle", {"vehicle": "usv2"}),
     {"at": 3.0, "action": "resume", "vehicle": "usv2"}),
    (("restart", [], "usv2", None), ("restart", {"vehicle": "usv2"}), {"at": 3.0, "action": "restart", "vehicle": "usv2"}),
    (("formation", ["phases.usv2=2.5"], None, None), ("formation", {"phases": {"usv2": 2.5}, "offsets": []}),
     {"at": 3.0, "action": "formation", "phases": {"usv2": 2.5}}),
    (("formation", ["offsets.usv2.usv1=1.5"], None, None),
     ("formation", {"phases": {}, "offsets": [{"i": "usv2", "k": "usv1", "delta": 1.5}]}),
     {"at": 3.0, "action": "formation", "offsets": [{"i": "usv2", "k": "usv1", "delta": 1.5}]}),
    (("path", ["family=circle", "center=[0,0]", "radius=15"], "usv1", None),
     ("path", {"vehicle": "usv1", "path": {"family": "circle", "center": [0, 0], "radius": 15}}),
     {"at": 3.0, "action": "path", "vehicle": "usv1", "path": {"family": "circle", "center": [0, 0], "radius": 15}}),
    (("radio", ["tx_power=5.0"], None, None), ("radio", {"radio": {"tx_power": 5.0}, "at": -1.0}),
     {"at": 3.0, "action": "radio", "tx_power": 5.0}),
])
def test_the_three_entries_give_equal_commands_for_equal_input(cli, wire, event):
    action, settings_, vehicle, at = cli
    a = parse_cli(action, settings_, vehicle=vehicle, at=at)
    b = parse_wire(*wire)
    c = parse_event(event)
    assert a == b == c and not isinstance(a, Rejected), (a, b, c)


def test_gains_and_link_from_the_cli_equal_the_wires_and_the_old_spelling_still_reads():
    assert parse_cli("gains", ["k=2", "c=0.5"]) == parse_wire("gains", {"gains": {"k": 2.0, "c": 0.5}, "vehicle": ""}) \
        == parse_wire("set_gains", {"gains": {"k": 2, "c": 0.5}, "vehicle": ""}) == Gains(2.0, 0.5, None)
    assert parse_cli("link", ["loss=0.3", "delay.base=0.1"], at=4.0) == parse_wire(
        "link", {"link": {"delay": {"base": 0.1}, "loss": 0.3}, "at": 4.0})
    assert parse_cli("gains", ["k=[1,2]"]).field == "k"  # per axis needs one vehicle


def test_every_name_round_trips_and_is_defined_once():
    for cls in COMMANDS:
        n = cls.NAMES
        assert BY_CLI[n.cli] is cls and BY_OP[n.op] is cls
        assert all(BY_OP[o] is cls for o in n.old_ops)
        if n.event is not None:
            assert BY_EVENT[n.event] is cls
    assert len({c.NAMES.cli for c in COMMANDS}) == len({c.NAMES.op for c in COMMANDS}) == len(COMMANDS)
    assert set(BY_OP) <= set(COMMAND_OPS)  # every op the world is sent is one it decodes
    assert {f.NAMES.op for f in (Kill, PauseVehicle, ResumeVehicle, Restart)} == set(LAUNCHER_OPS)
    assert FAULT_EVENTS == ACTIONS  # the roster's (cdus.core.events, below this room) in the same order
    assert CHANGE_ACTIONS == (Formation.NAMES.event, Path.NAMES.event)
    assert Radio.NAMES.event == "radio"


def test_the_effect_tick_is_one_rule_for_both_clocks():
    assert effect_tick(41, 1) == 42  # lockstep: past the grant
    assert lead_ticks(0.02) == 25 and lead_ticks(1.0) == 1 and lead_ticks(0.5) == 1 and lead_ticks(0.3) == 2
    assert effect_tick(100, lead_ticks(0.02)) == 125  # realtime: 0.5 s ahead of the wall clock's tick
    assert effect_tick(-1, 0) == 1
    assert effect_time(None, 41, 1, 0.1) == (pytest.approx(4.2), "")
    assert effect_time(9.0, 41, 1, 0.1) == (9.0, "")
    t, note = effect_time(1.0, 41, 1, 0.1)
    assert t == pytest.approx(4.2) and "had passed" in note
    assert never_applies(10, 10, 0.1) is None and "never apply" in never_applies(11, 10, 0.1).reason


def test_expand_k_and_the_vehicle_rule():
    assert expand_k(2.0, 3) == (2.0, 2.0, 2.0) and expand_k((1.0, 2.0), 2) == (1.0, 2.0)
    g = Gains((1.0, 2.0), None, "usv1")
    assert g.for_vehicle(3, (1.0, 1.0, 1.0), 1.0).field == "k"
    assert g.for_vehicle(2, (5.0, 5.0), 0.7) == ((1.0, 2.0), 0.7)
    assert "too large" in Gains(100.0, None).for_vehicle(2, (1.0, 1.0), 1.0, control_hz=10.0).reason
    assert Gains(None, 0.3).for_vehicle(2, (1.0, 1.0), 1.0, control_hz=10.0) == ((1.0, 1.0), 0.3)


class _Node:
    """What a command calls on a VehicleNode, recorded."""

    def __init__(self, index=0, dim=2):
        self.index, self.period, self.calls = index, 0.1, []
        self.vehicle = type("V", (), {"dim": dim, "k": (1.0,) * dim, "c": 1.0, "plant": "ideal", "physics_steps": 1})()
        self.table = type("T", (), {"links": ()})()

    def on_roster(self, ch):
        self.calls.append(ch)

    def set_gains(self, k, c, tick):
        self.calls.append(("gains", k, c, tick))

    def set_formation(self, phases, tick):
        self.calls.append(("formation", phases, tick))

    def set_path(self, path, tick):
        self.calls.append(("path", path.dim, tick))


def test_applying_a_command_returns_its_outcome():
    ids = ["usv1", "usv2"]
    n = _Node()
    assert Restart("usv2").apply(n, 7, ids) == Applied(7)
    assert n.calls == [RosterChange(7, 1, "gone"), RosterChange(7, 1, "live", True)]
    assert Kill("usv9").apply(n, 7, ids).field == "vehicle"
    assert Gains(2.0, None).apply(n, 8) == Applied(8) and n.calls[-1] == ("gains", (2.0, 2.0), 1.0, 8)
    assert isinstance(Gains(50.0, None).apply(n, 8), Rejected)  # k·T >= 2 at 10 Hz: refused, nothing set
    assert n.calls[-1][0] == "gains" and n.calls[-1][1] == (2.0, 2.0)
    assert parse_cli("formation", ["phases.usv2=3"]).apply(n, 9, ids) == Applied(9)
    assert n.calls[-1] == ("formation", {1: 3.0}, 9)
    assert parse_cli("formation", ["offsets.usv2.usv1=3"]).apply(n, 9, ids).field == "offsets"
    p = parse_cli("path", ["family=circle", "center=[0,0]", "radius=5"], vehicle="usv1")
    assert p.apply(n, 10, ids) == Applied(10) and n.calls[-1] == ("path", 2, 10)
    assert p.apply(_Node(index=1), 10, ids).field == "vehicle"
    assert isinstance(parse_cli("stop").apply(n, 1), Rejected)

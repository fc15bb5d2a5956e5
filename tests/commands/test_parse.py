"""cdus.commands.parse: the three entries give one command, any wire fields parse or are refused
naming a field, and every name round-trips."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings, strategies as st

from cdus.commands.base import Rejected
from cdus.commands.changes import Formation, Path
from cdus.commands.gains import Gains
from cdus.commands.parse import BY_CLI, BY_EVENT, BY_OP, COMMANDS, decode_command, parse_cli, parse_event, parse_wire, wire_of
from cdus.commands.radio import Radio
from cdus.commands.vehicle import Kill, PauseVehicle, Restart, ResumeVehicle
from cdus.core.vocabulary import CHANGE_ACTIONS, FAULT_ACTIONS
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
    # every scenario action (cdus.core.vocabulary's words) has the one command that parses it, and no
    # command answers to an action the scenario does not take
    assert sorted(BY_EVENT) == sorted([*FAULT_ACTIONS, *CHANGE_ACTIONS, Radio.NAMES.event])
    assert (BY_EVENT["formation"], BY_EVENT["path"]) == (Formation, Path)


@pytest.mark.parametrize("command", [
    Gains((1.0, 2.0), 0.5, "usv1"), Gains(2.0, None), parse_cli("link", ["loss=0.3", "delay.base=0.1"], at=3.0),
    parse_cli("radio", ["tx_power=5", "station=[0,1,2]"]), parse_cli("formation", ["offsets.usv2.usv1=1"]),
    parse_cli("formation", ["phases.usv2=1"]), parse_cli("path", ["family=circle", "center=[0,0]", "radius=5"], vehicle="u"),
    Kill("u"), Restart("u"), PauseVehicle("u"), ResumeVehicle("u"), parse_cli("stop"),
])
def test_what_a_command_sends_reads_back_as_itself(command):
    op, fields = wire_of(command)
    assert parse_wire(op, fields) == command and decode_command(encode_control(op, **fields)) == command


def test_the_cli_settings_and_the_entries_refusals():
    assert parse_cli("nope") == Rejected("no command 'nope'; commands are " + ", ".join(BY_CLI), "action")
    assert parse_cli("stop", ["x=1"]) == Rejected("stop takes no KEY=VALUE settings", "x=1")
    assert parse_cli("link", ["loss"]) == Rejected("expected KEY=VALUE, e.g. loss=0.3", "loss")
    assert parse_cli("link", ["=1"]).field == "=1"
    assert parse_cli("gains", ["k=1", "k.x=2"]) == Rejected("given both a value and, in k.x=2, fields of it; give one", "k")
    assert parse_cli("link", ["delay.base=1", "delay=2"]) == Rejected(
        "given both fields of it and, in delay=2, a value; give one", "delay")
    assert parse_cli("formation", ["phases.a=1", "offsets.b.c=1"]).field == "formation"
    assert parse_cli("formation", ["speed=3"]).field == "speed"
    assert parse_cli("formation", ["phases=3"]).field == "phases"
    assert parse_cli("formation", ["offsets.usv2=1"]) == Rejected("write offsets.I.K=Δ (I listens to K)", "offsets.usv2")
    assert parse_cli("gains", ["k=2"], vehicle="usv1") == Gains(2.0, None, "usv1")
    assert parse_cli("kill", vehicle=None).field == "vehicle"
    assert parse_cli("link", ["loss=0.1"]).at is None
    assert parse_event({"action": "dance"}).field == "action" and parse_event({}).field == "action"
    assert parse_event({"at": 1.0, "action": "kill", "vehicle": "usv1", "x": 2}).field == "x"
    assert parse_wire(3, {}).field == "op"
    assert decode_command(b"\xc1") == Rejected("malformed")
    assert decode_command(encode_control("kill", vehicle=3)) == Rejected("type")


def test_a_setting_without_its_value_is_refused_with_an_example_of_its_own_command():
    # `cdus gs gains k 2` was answered "k: expected KEY=VALUE, e.g. loss=0.3", a link's example
    assert parse_cli("gains", ["k", "2"]) == Rejected("expected KEY=VALUE: did you mean k=2?", "k")
    assert parse_cli("gains", ["k"]) == Rejected("expected KEY=VALUE, e.g. k=2", "k")
    assert parse_cli("radio", ["tx_power"]) == Rejected("expected KEY=VALUE, e.g. tx_power=20", "tx_power")
    assert parse_cli("path", ["family", "radius=5"], vehicle="usv1") == \
        Rejected("expected KEY=VALUE, e.g. family=circle", "family")
    assert parse_cli("formation", ["phases.usv2"]).reason == "expected KEY=VALUE, e.g. phases.usv2=3.1416"


def test_a_path_argument_is_named_as_it_was_typed():
    # `cdus gs path --vehicle usv1 waypoints=...` was refused as "path.waypoints: ...", where every
    # other command names its argument as typed (loss, k, tx_power); the wire and events keep path.*
    got = parse_cli("path", ["family=spline", "waypoints=[[0,0],[0,0],[1,1]]"], vehicle="usv1")
    assert got.field == "waypoints" and got.reason.startswith("waypoint 1 [0, 0] repeats waypoint 0")
    assert parse_cli("path", ["family=circx"], vehicle="usv1").field == "family"
    assert parse_wire("path", {"vehicle": "usv1", "path": {"family": "circx"}}).field == "path.family"


@pytest.mark.parametrize("action, setting, field", [
    ("gains", "k", "k"), ("gains", "c", "c"), ("link", "loss", "loss"), ("link", "delay.base", "delay.base"),
    ("radio", "tx_power", "tx_power"), ("formation", "phases.usv1", "phases.usv1")])
def test_a_cli_integer_beyond_a_float_is_refused_naming_its_field(action, setting, field):
    # TOML reads k=1 followed by 400 zeros as an int; math.isfinite raised OverflowError on it and
    # `cdus gs ... gains k=1000...0` was a traceback instead of a refusal
    got = parse_cli(action, [f"{setting}=1{'0' * 400}"], vehicle="usv1")
    assert isinstance(got, Rejected) and got.field == field, got
    assert len(got.reason) < 400, got.reason  # the number is not printed whole (401 digits)


def _ring(n: int) -> str:
    r = n / (2 * math.pi)  # waypoints about 1 m apart on a circle: a spline the checks take
    return "[" + ",".join(f"[{r * math.cos(2 * math.pi * i / n):.3f},{r * math.sin(2 * math.pi * i / n):.3f}]"
                          for i in range(n)) + "]"


def test_a_cli_path_too_large_for_one_message_is_refused_here_naming_the_waypoints():
    # a spline of 65 waypoints parsed, was sent, and the world answered "the command could not be
    # read: malformed" (the control map holds 64 entries a list); 64 still go, with the longest --name
    assert isinstance(parse_cli("path", ['family="spline"', f"waypoints={_ring(64)}"], vehicle="usv1"), Path)
    for n in (65, 500):
        got = parse_cli("path", ['family="spline"', f"waypoints={_ring(n)}"], vehicle="usv1")
        assert isinstance(got, Rejected) and got.field == "waypoints", got  # named as typed
        assert "too large for one command message" in got.reason and "scenario" in got.reason


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 80))
def test_what_the_cli_takes_the_world_can_read(n):
    got = parse_cli("formation", [f"phases.v{i}=0.5" for i in range(n)])
    if not isinstance(got, Rejected):
        assert decode_command(encode_control(*wire_of(got)[:1], **wire_of(got)[1], name="n" * 64)) == got

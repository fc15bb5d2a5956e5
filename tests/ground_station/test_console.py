import pytest

from cdus.scenario.config import ConfigError
from cdus.commands.parse import nested
from cdus.wire.rejected import Rejected
from ground_station.console import FleetView, status_table
from cdus.wire.messages import StateMsg
from cdus.wire.schemas import FleetEvent, StatusExtra, WorldStatus, decode_status, encode_status
from ground_station.__main__ import main as gs_main


def status(t: float, duration: float, clock: str, alive: list[str], ids: list[str], path: float | None = None,
           coord: float | None = None, events: tuple = (), roster: dict | None = None, **extra) -> WorldStatus:
    """A status as the console gets it: encoded by the world's encoder, decoded by decode_status."""
    st = decode_status(encode_status(t, duration, clock, alive, ids, path, coord, list(events), False, roster,
                                     StatusExtra(**extra)))
    assert isinstance(st, WorldStatus), st
    return st


def test_settings_become_a_nested_link_table():
    assert nested(["loss=0.3", "delay.base=0.1", "delay.distribution=normal", "policy=extrapolate"]) == {
        "loss": 0.3, "delay": {"base": 0.1, "distribution": "normal"}, "policy": "extrapolate"}
    got = nested(["loss"])
    assert isinstance(got, Rejected) and "KEY=VALUE" in got.reason and got.field == "loss"


def test_status_table_shows_every_known_vehicle_the_world_and_its_events():
    view = FleetView()
    view.states["usv1"] = StateMsg(0, 500, 10.0, (1.0, 2.0), 0.3, 10.0, -9.9, -1.0, 0.06)
    view.alive = {"usv1", "world"}
    view.world = status(10.0, 250.0, "realtime", ["usv1"], ["usv1", "uav1"], 0.06, 0.5,
                        [FleetEvent.of(9.0, "vehicle_lost", "vehicle uav1 lost", vehicle="uav1")])
    text = status_table(view)
    lines = text.splitlines()
    assert any(ln.startswith("usv1") and "yes" in ln and "0.060" in ln and "(1.0, 2.0)" in ln for ln in lines)
    assert any(ln.startswith("uav1") and "NO" in ln for ln in lines)  # known from the world, not alive
    assert "world: t = 10.0 / 250 s (realtime), 1/2 vehicles alive" in text
    assert "t = 9.00 s: vehicle uav1 lost  [WARN]" in text


def test_status_table_rows_and_footer_agree_when_every_vehicle_has_left():
    """At the end of a run every vehicle's token goes while the world's last status still lists
    them all: the rows said NO on every line and the footer "2/2 vehicles alive"."""
    view = FleetView()
    view.world_seen = True
    view.alive = {"world"}  # the vehicles have left; the world is winding down
    view.world = status(250.0, 250.0, "lockstep", ["usv1", "uav1"], ["usv1", "uav1"], 0.06, 0.5,
                        states=["live", "live"])
    text = status_table(view)
    assert "0/2 vehicles alive" in text, text
    assert all(" NO " in ln for ln in text.splitlines() if ln.startswith(("usv1", "uav1")))
    view.alive = {"world", "usv1"}
    text = status_table(view)
    assert "1/2 vehicles alive" in text and any(ln.startswith("usv1") and " yes " in ln for ln in text.splitlines())


def test_status_table_after_the_worlds_last_status_says_ended_not_lost():
    view = FleetView()
    view.world_seen = True
    view.alive = {"world"}
    view.world = status(250.0, 250.0, "lockstep", ["usv1", "uav1"], ["usv1", "uav1"], 0.06, 0.5,
                        roster={"usv1": "live", "uav1": "gone"}, states=["live", "gone"], completion="completed")
    text = status_table(view)
    assert "0/2 vehicles alive" in text and "the run is over: completed" in text, text
    assert any(ln.startswith("usv1") and "(the run ended)" in ln for ln in text.splitlines())
    assert any(ln.startswith("uav1") and "(gone)" in ln for ln in text.splitlines())  # gone before the end


def test_status_table_before_anything_is_heard():
    assert "world: no status yet" in status_table(FleetView())


@pytest.mark.parametrize("argv, says", [
    (["--fleet", "bad/name", "stop"], "--fleet"),
    (["--fleet", "f", "gains", "c=abc"], "c: must be a finite number > 0"),
    (["--fleet", "f", "gains", "k=-3"], "k: must be a finite number > 0"),
    (["--fleet", "f", "gains", "k=inf"], "k: must be a finite number > 0, got inf"),  # not "a number > 0, got inf"
    (["--fleet", "f", "gains", "c=inf"], "c: must be a finite number > 0, got inf"),
    (["--fleet", "f", "gains", "--vehicle", "usv1", "k=[1,inf]"], "k: must be 1 to 3 finite numbers > 0 (one per axis)"),
    (["--fleet", "f", "gains", "k=[1,2]"], "needs one vehicle named (--vehicle)"),
    (["--fleet", "f", "gains", "x=1"], "gains are k"),
    (["--fleet", "f", "link", "loss=3"], "error: command line: loss: "),
    # issue 27: answered "applied" by the world, it crashed every agent (OverflowError in needed_seq)
    (["--fleet", "f", "link", "delay.base=1e308"], "delay.base: must be a number >= 0 and <= 3600"),
    (["--fleet", "f", "link", "delay.jitter=inf"], "delay.jitter: must be a finite number >= 0 and <= 3600"),
    (["--fleet", "f", "link", "timeout=1e308"], "timeout: must be a number > 0 and <= 1e+09"),
    (["--fleet", "f", "formation", "phases.usv1=1e308"], "phases.usv1: must be a finite number >= -1e+09 and <= 1e+09"),
    (["--fleet", "f", "formation", "offsets.usv2.usv1=nan"], "offsets.usv2.usv1: must be a finite number >= -1e+09"),
    (["--fleet", "f", "path", "--vehicle", "usv1", "family=circle", "center=[0,0]", "radius=1e300"],
     "radius: must be a finite number > 0 and <= 1e+06 m, got 1e+300"),
    (["--fleet", "f", "path", "--vehicle", "usv1", "family=circle", "center=[1e308,0]", "radius=5"],
     "center: must contain numbers >= -1e+06 and <= 1e+06"),
    (["--fleet", "f", "radio", "tx_power=1e308"], "tx_power: must be a number >= -50 and <= 50"),
])
def test_bad_commands_are_refused_before_connecting(argv, says, capsys):
    assert gs_main(["-e", "tcp/127.0.0.1:1", *argv]) == 2  # nothing listens there: it never got that far
    assert says in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--fleet", "f", "link", "--at", "-5", "loss=0.1"],
                                  ["--fleet", "f", "status", "--interval", "0"],
                                  ["--fleet", "f", "-e", "nonsense", "stop"],
                                  ["--fleet", "f", "-e", "tcp/127.0.0.1:port", "stop"]])
def test_bad_arguments_are_usage_errors(argv):
    with pytest.raises(SystemExit) as e:
        gs_main(argv)
    assert e.value.code == 2


@pytest.mark.parametrize("argv, says", [
    (["--fleet", "f", "gains", "c=1", "--timeout", "abc"], "argument --timeout: must be a number of seconds > 0"),
    (["--fleet", "f", "--timeout", "soon", "stop"], "argument --timeout: must be a number of seconds > 0"),
    (["--fleet", "f", "status", "--interval", "x"], "argument --interval: must be a number of seconds > 0"),
    (["--fleet", "f", "link", "--at", "later", "loss=0.1"], "argument --at: must be a simulated time >= 0 s, got later"),
])
def test_a_number_that_is_not_one_gets_the_options_own_message(argv, says, capsys):
    """`gains c=1 --timeout abc` said "invalid _positive value: 'abc'", the name of a function."""
    with pytest.raises(SystemExit) as e:
        gs_main(argv)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert says in err and "_positive" not in err and "_sim_time" not in err


def test_drop_bursts_do_not_push_the_other_events_out_of_the_status():
    view = FleetView()
    view.events = [FleetEvent.of(1.0, "vehicle_lost", "vehicle uav1 lost", vehicle="uav1")]
    view.events += [FleetEvent.of(2.0 + i, "link_burst", f"{i} drops in a row", link="usv1->usv2") for i in range(50)]
    out = status_table(view)
    assert "vehicle uav1 lost" in out and "49 drops in a row" in out and "48 drops in a row" not in out.split("uav1 lost")[0]
    assert "(50 drop bursts heard" in out
    assert out.count("drops in a row") == 7


def test_the_console_prints_a_few_bursts_per_link_then_says_so_once():
    from cdus.sim.reports import ConsoleQuota
    q = ConsoleQuota(per_link=2)
    ev = lambda link: FleetEvent.of(1.0, "link_burst", "3 drops in a row", link=link)  # noqa: E731
    lines = [line for _ in range(5) for line in q.lines(ev("a->b"))] + q.lines(ev("b->a"))
    assert len(lines) == 4 and "not printed" in lines[2]
    assert q.lines(FleetEvent.of(1.0, "vehicle_lost", "vehicle a lost", vehicle="a")) != []


# ---------------------------------------------------------------- what came over the wire is shown, not obeyed

import math  # noqa: E402
import unicodedata  # noqa: E402

from hypothesis import given, settings, strategies as st  # noqa: E402

from ground_station.console import GroundStation, num  # noqa: E402
from cdus.wire.schemas import encode_event, encode_status  # noqa: E402
from cdus.wire.messages import encode_states  # noqa: E402


def test_numbers_that_are_not_finite_numbers_are_shown_as_such():
    assert num(1.23456) == "1.235" and num(None) == "-"
    assert num(math.nan) == "nan" and num(math.inf) == "inf" and num(-math.inf) == "-inf"
    assert num(1e308, ".1f") == "1e+308"  # not 309 digits
    assert num("x\x1b[31m") == "?'x\\x1b[31m'" and num(True) == "?True" and num([1]) == "?[1]"


def test_a_status_of_bad_values_never_reaches_the_table_and_what_does_is_escaped():
    """The table read the status as a map and checked each value again (t = 1e308, a clock of
    escape codes, alive not a list, ids that are no ids, an error as a string or NaN). Such a
    status is refused where it enters (decode_status, counted) and the table reads the typed
    fields; the strings that do reach it (a telemetry sender's name, an event's text) are escaped."""
    import msgpack

    esc = "\x1b[2J\x1b[31mOK\r\n"
    gs = GroundStation("f", None)
    good = msgpack.unpackb(encode_status(10.0, 250.0, "realtime", ["usv1"], ["usv1"], 0.06, 0.5, [], False))
    for bad in ({"t": 1e308}, {"clock": esc}, {"alive": "not a list"}, {"ids": [esc, 7, None]},
                {"path_error_max": "0.0"}, {"coord_error_max": math.nan}):
        gs._on_status(Sample("cdus/f/world/status", msgpack.packb({**good, **bad})))
    assert gs.view.world is None and gs.view.rejected == 6
    view = gs.view
    view.states[esc] = StateMsg(0, 1, math.nan, (math.inf, 1e308), 0.0, 0.0, -math.inf, 1.0, math.nan)
    view.alive = {esc, "world"}
    text = status_table(view)
    assert "\x1b" not in text and "\r" not in text and "\\x1b[2J" in text
    assert "nan" in text.splitlines()[1] and "(inf, 1e+308)" in text
    view.world = status(10.0, 250.0, "realtime", ["usv1"], ["usv1"], 0.06, None,
                        [FleetEvent.of(1.0, "fleet", esc + "t = 250 s: done")])
    text = status_table(view)
    assert "\x1b" not in text and "\r" not in text
    assert text.count("\n") == len(text.splitlines()) - 1 and "\\x1b[2J" in text
    assert "world: t = 10.0 / 250 s (realtime), 0/1 vehicles alive" in text and "worst edge error - rad" in text


class Sample:
    def __init__(self, key: str, payload: bytes):
        self.key_expr = key
        self.payload = type("P", (), {"to_bytes": lambda _self: payload})()


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=200), st.text(max_size=20))
def test_no_message_escapes_the_ground_stations_handlers_and_the_table_always_prints(payload, text):
    gs = GroundStation("f", None)
    gs._on_state(Sample(f"cdus/f/to/+world+/state/{text}", payload))
    gs._on_status(Sample("cdus/f/world/status", payload))
    gs._on_event(Sample("cdus/f/world/events", payload))
    gs._on_event(Sample("cdus/f/world/events", encode_event(FleetEvent.of(0.0, "fleet", text))))
    gs._on_status(Sample("cdus/f/world/status", encode_status(0.0, 1.0, text, [text], [text], None, None, [], False)))
    gs._on_state(Sample(f"cdus/f/to/+world+/state/{text}", encode_states([StateMsg(0, 1, 0.0, (0.0, 0.0), 0.0, 0.0,
                                                                                       0.0, 0.0, 0.0)])))
    out = status_table(gs.view)
    lines = out.split("\n")
    assert len(lines) == len(out.splitlines())  # no line breaks but the table's own
    assert not any(unicodedata.category(ch)[0] == "C" for ln in lines for ch in ln), out


def test_the_console_keeps_a_bounded_number_of_events():
    from ground_station.console import MAX_EVENTS

    gs = GroundStation("f", None)
    for i in range(MAX_EVENTS + 50):
        gs._on_event(Sample("cdus/f/world/events", encode_event(FleetEvent.of(float(i), "fleet", "x"))))
    assert len(gs.view.events) == MAX_EVENTS and gs.view.events[-1].t == MAX_EVENTS + 49


def test_forged_names_are_not_tracked():
    from ground_station.console import MAX_NAMES

    gs = GroundStation("f", None)
    row = encode_states([StateMsg(0, 1, 0.0, (0.0, 0.0), 0.0, 0.0, 0.0, 0.0, 0.0)])
    gs._on_state(Sample("cdus/f/to/+world+/state/us\x1bv1", row))
    gs._on_state(Sample("cdus/f/to/+world+/state/usv1", row))
    assert set(gs.view.states) == {"usv1"} and gs.view.rejected == 1
    gs.view.states.update({f"v{i}": None for i in range(MAX_NAMES)})
    gs._on_state(Sample("cdus/f/to/+world+/state/one_more", row))
    assert "one_more" not in gs.view.states and gs.view.rejected == 2

    class Alive(Sample):
        kind = "SampleKind.PUT"

    gs._on_alive(Alive("cdus/f/alive/\x1b[2J/e1", b""))
    gs._on_alive(Alive("cdus/f/alive/usv1/a1", b""))
    assert gs.view.alive == {"usv1"} and gs.view.rejected == 3


def test_an_unreachable_router_says_that_nothing_listens_and_that_fleets_take_credentials(capsys, monkeypatch):
    """Nothing listens at the endpoint: no answer (exit 3), and the hint for a secured fleet."""
    import ground_station.__main__ as gs_main
    from cdus.wire.transport import free_tcp_port
    from ground_station.__main__ import main

    monkeypatch.setattr(gs_main, "GS_CONNECT_TIMEOUT_MS", 1000)  # nobody will answer: 1 s says so as well as 5
    code = main(["--fleet", "nobody", "-e", f"tcp/127.0.0.1:{free_tcp_port()}", "status", "--once"])
    err = capsys.readouterr().err
    assert code == 3 and "could not reach the fleet's router" in err and "within 1 s" in err
    assert "nothing listens there" in err
    assert "--zenoh-config RUN/secure/ground.json5" in err


def test_a_router_that_refuses_the_session_is_reported_as_such_with_the_file_to_use(tmp_path, capsys, monkeypatch):
    """A secured router is up and refuses a session without credentials (or with a wrong
    password): the ground station says so (exit 4, denied) and names ground.json5, not a bare
    'Timeout!'."""
    import json

    from cdus.app.credentials import make_credentials
    from cdus.wire.transport import Transport, free_tcp_port, open_session
    import ground_station.__main__ as gs_main
    from ground_station.__main__ import main

    # a refused session is told from nobody there by probing the port after the failure: the wait is not the check
    monkeypatch.setattr(gs_main, "GS_CONNECT_TIMEOUT_MS", 1000)
    ep = f"tcp/127.0.0.1:{free_tcp_port()}"
    cred = make_credentials(tmp_path, "f1", {"usv1": ["usv2"], "usv2": ["usv1"]}, (ep,))
    router = open_session(Transport(mode="router", listen=cred.listen, extra=cred.router_extra()))
    try:
        code = main(["--fleet", "f1", "-e", ep, "status", "--once"])
        err = capsys.readouterr().err
        assert code == 4 and "is up but refused or closed this session, which had no credentials" in err, err
        assert "--zenoh-config RUN/secure/ground.json5" in err and "Timeout" not in err
        wrong = json.loads(cred.file("ground").read_text())
        wrong["transport"]["auth"]["usrpwd"]["password"] = "guess"
        (tmp_path / "wrong.json5").write_text(json.dumps(wrong))
        code = main(["--fleet", "f1", "--zenoh-config", str(tmp_path / "wrong.json5"), "status", "--once"])
        err = capsys.readouterr().err
        assert code == 4 and "the credentials of 'ground' from" in err and "guess" not in err, err
        assert "use the ground.json5 of this run" in err and "add --zenoh-config" not in err, err  # one was given
    finally:
        router.close()


def test_the_connect_timeout_holds_with_the_runs_credentials_file(tmp_path):
    """`cdus gs -e EP --zenoh-config RUN/secure/ground.json5 status` (the line cdus launch prints)
    at a fleet that had ended hung 30 s (the agents' connect timeout, set with every -e) and then
    said "within 5 s": the ground station's own timeout was given only without a file."""
    import json

    from cdus.wire.transport import zenoh_config
    from ground_station.__main__ import GS_CONNECT_TIMEOUT_MS, build_parser, gs_transport

    ground = tmp_path / "ground.json5"
    ground.write_text(json.dumps({"mode": "client", "connect": {"endpoints": ["tcp/127.0.0.1:1"]}}))
    for argv in (["-e", "tcp/127.0.0.1:1", "--zenoh-config", str(ground)],  # the printed line
                 ["--zenoh-config", str(ground)],  # the file's endpoint
                 ["-e", "tcp/127.0.0.1:1"]):
        t = gs_transport(build_parser("gs").parse_args(["--fleet", "f", *argv, "status", "--once"]))
        assert json.loads(zenoh_config(t).get_json("connect/timeout_ms")) == GS_CONNECT_TIMEOUT_MS, argv
    own = tmp_path / "own.json5"  # a file that sets its own, with no -e: the file's is kept
    own.write_text(json.dumps({"mode": "client", "connect": {"endpoints": ["tcp/127.0.0.1:1"], "timeout_ms": 1234}}))
    t = gs_transport(build_parser("gs").parse_args(["--fleet", "f", "--zenoh-config", str(own), "status"]))
    assert json.loads(zenoh_config(t).get_json("connect/timeout_ms")) == 1234


def test_a_link_command_on_every_link_is_one_line_of_the_status_table_not_twelve():
    from cdus.sim.reports import link_state_event
    from ground_station.console import group_link_states

    links = [f"{a}->{b}" for a, b in [("usv1", "usv2"), ("usv2", "usv1"), ("usv2", "usv3"), ("usv3", "usv2"),
                                      ("usv3", "uav1"), ("uav1", "usv3")]]
    cmd = FleetEvent.of(10.0, "link_changed", "link loss=0.1 by gs:alice")
    lossy = [link_state_event(10.02 + 0.01 * j, ln, "lossy") for j, ln in enumerate(links)]
    later = link_state_event(30.0, links[0], "down")
    grouped = group_link_states([cmd, *lossy, later])
    assert [e.text for e in grouped] == [
        "link loss=0.1 by gs:alice",
        "6 links lossy (from t = 10.02 s): usv1->usv2, usv2->usv1, usv2->usv3, usv3->usv2 and 2 more",
        "link usv1->usv2 down (from t = 30.00 s)"]
    assert grouped[1].t == 10.02 and grouped[2] is later
    # far apart, or one link twice: separate changes
    apart = [link_state_event(1.0, links[0], "lossy"), link_state_event(5.0, links[1], "lossy")]
    assert group_link_states(apart) == apart
    twice = [link_state_event(1.0, links[0], "lossy"), link_state_event(1.1, links[0], "lossy")]
    assert group_link_states(twice) == twice
    view = FleetView()
    view.world = status(31.0, 250.0, "realtime", [], ["usv1", "usv2", "usv3", "uav1"], None, None,
                        [cmd, *lossy, later])
    text = status_table(view)
    assert "link loss=0.1 by gs:alice" in text and "6 links lossy" in text and text.count("lossy") == 1


def test_a_mistyped_fleet_is_told_the_fleet_its_credentials_are_for_or_the_fleets_running(tmp_path):
    from cdus.app.credentials import make_credentials
    from ground_station.__main__ import _other_fleets
    from ground_station.console import credentials_fleet

    cred = make_credentials(tmp_path / "secure", "lake_demo", {"usv1": ["usv2"], "usv2": ["usv1"]},
                            ("tcp/127.0.0.1:7447",))
    ground = str(tmp_path / "secure" / "ground.json5")
    assert credentials_fleet(ground) == "lake_demo" and cred is not None
    assert credentials_fleet(str(tmp_path / "elsewhere.json5")) is None and credentials_fleet(None) is None
    (tmp_path / "secure" / "router.json5").write_text("{not json")
    assert credentials_fleet(ground) is None
    assert _other_fleets([], "lake_dem", "lake_demo", ground) == (
        f"; the credentials in {ground} are for fleet 'lake_demo' (did you mean --fleet lake_demo?)")
    assert _other_fleets([], "lake_demo", "lake_demo", ground) == ""  # right fleet, not running: no hint
    assert _other_fleets(["lake_demo", "other"], "lake_dem") == (
        "; fleets running there: lake_demo, other (did you mean --fleet lake_demo?)")
    assert _other_fleets(["zzz"], "lake_dem") == "; fleets running there: zzz"
    assert _other_fleets([f"f{j:02d}" for j in range(12)], "x").endswith("f09 and 2 more")


def test_status_table_has_no_row_for_the_fleets_own_non_vehicle_tokens():
    """`cdus gs status` on a `cdus launch --ros2` fleet showed the ROS 2 bridge's token
    (alive/ros2) as a vehicle row, "ros2  NO  -  (no data yet)"; the console did not (one rule
    for both: ground_station.console.row_ids)."""
    view = FleetView()
    view.world_seen = True
    view.states["usv1"] = StateMsg(0, 500, 10.0, (1.0, 2.0), 0.3, 10.0, -9.9, -1.0, 0.06)
    view.states["forged"] = view.states["usv1"]
    view.alive = {"usv1", "world", "ros2", "launcher"}
    view.world = status(10.0, 250.0, "realtime", ["usv1"], ["usv1"], 0.06, 0.5)
    rows = [ln.split()[0] for ln in status_table(view).splitlines()[1:] if not ln.startswith("world:")]
    assert rows == ["usv1"]
    view.world = None  # before the world's first status: whoever is heard, but no process of the fleet's own
    rows = [ln.split()[0] for ln in status_table(view).splitlines()[1:] if not ln.startswith("world:")]
    assert rows == ["forged", "usv1"]


def test_json_num_takes_a_finite_number_and_never_a_bool():
    """_json_num(True) gave 1.0 (True is an int to Python): a --json line said t = 1.0 for a
    value that is no number; now it is null, as nan and inf are (cdus.wire.bounds.finite)."""
    from ground_station.console import _json_num
    assert _json_num(True) is None and _json_num(False) is None
    assert _json_num(math.nan) is None and _json_num(math.inf) is None and _json_num("1") is None
    assert _json_num(2) == 2.0 and isinstance(_json_num(2), float) and _json_num(-0.5) == -0.5

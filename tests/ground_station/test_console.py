import pytest

from cdus.scenario.config import ConfigError
from ground_station.__main__ import nested
from ground_station.console import FleetView, status_table
from cdus.wire.messages import StateMsg
from cdus.wire.schemas import FleetEvent
from cdus.core.node import gains_problem
from ground_station.__main__ import main as gs_main


def test_settings_become_a_nested_link_table():
    assert nested(["loss=0.3", "delay.base=0.1", "delay.distribution=normal", "policy=extrapolate"]) == {
        "loss": 0.3, "delay": {"base": 0.1, "distribution": "normal"}, "policy": "extrapolate"}
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        nested(["loss"])


def test_status_table_shows_every_known_vehicle_the_world_and_its_events():
    view = FleetView()
    view.states["usv1"] = StateMsg(0, 500, 10.0, (1.0, 2.0), 0.3, 10.0, -9.9, -1.0, 0.06)
    view.alive = {"usv1", "world"}
    view.world = {"t": 10.0, "duration": 250.0, "clock": "realtime", "alive": ["usv1"],
                  "ids": ["usv1", "uav1"], "path_error_max": 0.06, "coord_error_max": 0.5,
                  "events": [FleetEvent.of(9.0, "vehicle_lost", "vehicle uav1 lost", vehicle="uav1")]}
    text = status_table(view)
    lines = text.splitlines()
    assert any(ln.startswith("usv1") and "yes" in ln and "0.060" in ln and "(1.0, 2.0)" in ln for ln in lines)
    assert any(ln.startswith("uav1") and "NO" in ln for ln in lines)  # known from the world, not alive
    assert "world: t = 10.0 / 250 s (realtime), 1/2 vehicles alive" in text
    assert "t = 9.00 s: vehicle uav1 lost  [WARN]" in text


def test_status_table_before_anything_is_heard():
    assert "world: no status yet" in status_table(FleetView())


@pytest.mark.parametrize("argv, says", [
    (["--fleet", "bad/name", "stop"], "--fleet"),
    (["--fleet", "f", "gains", "c=abc"], "c: must be a number > 0"),
    (["--fleet", "f", "gains", "k=-3"], "k: must be a number > 0"),
    (["--fleet", "f", "gains", "k=[1,2]"], "needs --vehicle"),
    (["--fleet", "f", "gains", "x=1"], "gains are k"),
    (["--fleet", "f", "link", "loss=3"], "link.loss"),
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


def test_gains_problem_names_what_does_not_fit_a_vehicle():
    assert gains_problem({"k": [1.0, 2.0]}, 3) == "k must be 3 numbers > 0 for this vehicle, got [1.0, 2.0]"
    assert gains_problem({"k": 2.0, "c": 0}, 2) == "c must be a number > 0, got 0"
    assert gains_problem({"k": True}, 2) is not None and gains_problem({}, 2) is not None
    assert gains_problem({"k": [1.0, 2.0], "c": 3}, 2) is None


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

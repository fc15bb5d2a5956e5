"""`cdus gs formation` and `cdus gs path`: the arguments, checked before anything is sent."""

from __future__ import annotations

import pytest

from cdus.commands.changes import Formation, Path
from cdus.commands.parse import parse_cli
from cdus.scenario.config import ConfigError
from cdus.wire.rejected import Rejected
from ground_station.__main__ import build_parser, main


def test_phases_and_offsets_become_the_commands_fields():
    assert parse_cli("formation", ["phases.usv2=1.5", "phases.uav1=0"]).fields() == {
        "phases": {"usv2": 1.5, "uav1": 0}, "offsets": []}
    assert parse_cli("formation", ["offsets.usv2.usv1=2.0"]).fields() == {
        "phases": {}, "offsets": [{"i": "usv2", "k": "usv1", "delta": 2.0}]}


@pytest.mark.parametrize("settings, field", [
    (["phases.usv2=x"], "phases.usv2"),
    (["phases.usv2=nan"], "phases.usv2"),
    (["phases.usv2=1", "offsets.usv2.usv1=1"], "formation"),
    (["offsets.usv2=1"], "offsets.usv2"),
    (["speed=3"], "speed"),
])
def test_bad_formation_arguments_name_the_field(settings, field):
    got = parse_cli("formation", settings)
    assert isinstance(got, Rejected) and got.field == field


def test_a_path_is_checked_as_the_configs_paths_are():
    assert parse_cli("path", ["family=circle", "center=[0,0,20]", "radius=15"], vehicle="uav1").path_table() == {
        "family": "circle", "center": [0, 0, 20], "radius": 15}
    for settings, field in ((["family=cirle"], "family"), (["family=circle", "center=[0,0]", "radius=-1"], "radius"),
                            (["family=circle", "radius=1"], "center")):
        got = parse_cli("path", settings, vehicle="uav1")
        assert isinstance(got, Rejected) and got.field == field, got  # named as typed (docs/ground_station.md)


def test_the_subcommands_parse_and_bad_arguments_exit_2_before_connecting(capsys):
    args = build_parser().parse_args(["--fleet", "f", "path", "--vehicle", "uav1", "family=circle"])
    assert args.action == "path" and args.vehicle == "uav1"
    assert main(["--fleet", "f", "-e", "tcp/127.0.0.1:9", "formation", "phases.usv2=x"]) == 2
    assert "phases.usv2" in capsys.readouterr().err


def test_a_zenoh_config_that_cannot_be_read_is_a_usage_error_naming_the_file(tmp_path, capsys):
    """A typo in --zenoh-config said "the fleet's router ... is up but refused or closed this
    session, which had the settings of FILE" (exit 4), or "could not reach" (exit 3) with
    nobody there; it is the command line that is wrong (rev18-user)."""
    bad = tmp_path / "bad.json5"
    bad.write_text("{ not json")
    for path, why in ((tmp_path / "missing.json5", "No such file"), (bad, "cannot be read as a Zenoh config")):
        assert main(["--fleet", "f", "-e", "tcp/127.0.0.1:9", "--zenoh-config", str(path), "status"]) == 2
        err = capsys.readouterr().err
        assert f"--zenoh-config {path}" in err and why in err and "ground.json5" in err, err
        assert "nothing was sent" in err and "refused" not in err


def test_a_snapshot_into_a_directory_is_a_usage_error_before_connecting(tmp_path, capsys):
    """It connected, then died with IsADirectoryError's traceback (rev18-user)."""
    assert main(["--fleet", "f", "-e", "tcp/127.0.0.1:9", "snapshot", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "is a directory" in err and "Traceback" not in err


def test_timeout_and_name_are_taken_after_the_action_too():
    """`cdus gs --fleet f kill usv2 --timeout 60` was "unrecognized arguments: --timeout 60"."""
    p = build_parser()
    assert p.parse_args(["--fleet", "f", "kill", "usv2", "--timeout", "60"]).timeout == 60.0
    assert p.parse_args(["--fleet", "f", "--timeout", "7", "kill", "usv2"]).timeout == 7.0
    assert p.parse_args(["--fleet", "f", "kill", "usv2"]).timeout == 10.0  # the default, not lost
    args = p.parse_args(["--fleet", "f", "link", "loss=0.1", "--name", "ops", "--timeout", "3"])
    assert (args.name, args.timeout, args.settings) == ("ops", 3.0, ["loss=0.1"])
    with pytest.raises(SystemExit):  # no abbreviations, after the action as before it
        p.parse_args(["--fleet", "f", "kill", "usv2", "--time", "5"])


def test_a_wait_too_long_for_zenoh_or_sleep_is_a_usage_error(capsys):
    """`--timeout 1e20` passed the parser and Zenoh's query raised ValueError ("negative
    timeout"): a traceback; `status --interval 1e20` would overflow time.sleep."""
    p = build_parser()
    for argv in (["--fleet", "f", "--timeout", "1e20", "kill", "usv2"], ["--fleet", "f", "kill", "usv2", "--timeout",
                                                                          "1e20"],
                 ["--fleet", "f", "status", "--interval", "1e20"], ["--fleet", "f", "kill", "usv2", "--timeout", "nan"]):
        with pytest.raises(SystemExit) as e:
            p.parse_args(argv)
        assert e.value.code == 2, argv
        assert "at most 1e+09" in capsys.readouterr().err
    assert p.parse_args(["--fleet", "f", "kill", "usv2", "--timeout", "1e9"]).timeout == 1e9


@pytest.mark.parametrize("settings, field", [
    (["phases.usv9=1"], "phases.usv9"),
    (["phases.usv2=1", "phases.boat=2"], "phases.boat"),
    (["offsets.usv9.usv1=1"], "offsets.usv9.usv1"),
    (["offsets.usv2.usv9=1"], "offsets.usv2.usv9"),
])
def test_an_unknown_vehicle_in_a_formation_names_the_argument_that_held_it(settings, field):
    """`cdus gs formation phases.usv9=1` said "vehicle: no vehicle 'usv9'", a field the user never typed."""
    from ground_station.__main__ import check_formation_vehicles
    ids = ["usv1", "usv2", "usv3"]
    with pytest.raises(ConfigError) as info:
        check_formation_vehicles(parse_cli("formation", settings), ids)
    assert info.value.problems[0][0] == field
    assert "its vehicles are usv1, usv2, usv3" in info.value.problems[0][1]
    check_formation_vehicles(parse_cli("formation", ["phases.usv2=1", "phases.usv3=2"]), ids)  # known ids pass
    check_formation_vehicles(parse_cli("formation", ["offsets.usv3.usv1=2"]), ids)

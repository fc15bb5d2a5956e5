"""The [[event]] tables: scheduled vehicle faults, checked against the vehicle ids."""

from __future__ import annotations

import tomllib

import pytest

from cdus.core.events import Event
from cdus.scenario.checks import Problems
from cdus.scenario.config import ConfigError, parse_scenario
from cdus.scenario.events import event_section
from tests.scenario.common import MINIMAL

IDS = ("usv1", "usv2")


def events(raw, ids=IDS):
    p = Problems()
    out = event_section(p, raw, ids)
    return out, p.items


def test_events_are_sorted_and_a_pause_with_a_duration_brings_its_resume():
    out, problems = events([
        {"at": 30, "action": "restart", "vehicle": "usv2"},
        {"at": 10.0, "action": "pause", "vehicle": "usv1", "duration": 25},
        {"at": 20.0, "action": "kill", "vehicle": "usv2"},
    ])
    assert problems == []
    assert out == (Event(10.0, "pause", "usv1"), Event(20.0, "kill", "usv2"), Event(30.0, "restart", "usv2"),
                   Event(35.0, "resume", "usv1"))
    assert all(isinstance(e.at, float) for e in out)


def test_events_at_the_same_time_keep_the_files_order():
    out, _ = events([{"at": 5, "action": "kill", "vehicle": "usv2"}, {"at": 5, "action": "kill", "vehicle": "usv1"}])
    assert [e.vehicle for e in out] == ["usv2", "usv1"]


def test_no_events():
    assert events([]) == ((), [])


@pytest.mark.parametrize("raw, field, text", [
    ({"at": -1, "action": "kill", "vehicle": "usv1"}, "event[0].at",
     "must be a number >= 0 and <= 1e+09 (s of simulated time), got -1"),
    ({"at": "soon", "action": "kill", "vehicle": "usv1"}, "event[0].at",
     'must be a number >= 0 and <= 1e+09 (s of simulated time), got the string "soon"'),
    ({"at": 1, "action": "explode", "vehicle": "usv1"}, "event[0].action",
     'unknown action "explode"; choose one of kill, pause, resume, restart, formation, path'),
    ({"at": 1, "action": "kil", "vehicle": "usv1"}, "event[0].action",
     'unknown action "kil" (did you mean "kill"?); choose one of kill, pause, resume, restart, formation, path'),
    ({"at": 1, "action": "kill", "vehicle": "usb1"}, "event[0].vehicle",
     '"usb1" is not a vehicle (did you mean "usv1"?); ids are usv1, usv2'),
    ({"at": 1, "action": "kill", "vehicle": "usv1", "duration": 3}, "event[0].duration",
     'only a pause takes a duration (this event is a "kill"); remove it'),
    ({"at": 1, "action": "pause", "vehicle": "usv1", "duration": 0}, "event[0].duration",
     "must be a number > 0 and <= 1e+09 s (then the vehicle resumes), got 0"),
    ({"at": 1, "action": "kill", "vehicle": "usv1", "when": 3}, "event[0].when",
     "unknown key; valid keys here: at, action, vehicle, duration, phases, offsets, path"),
    ({"action": "kill", "vehicle": "usv1"}, "event[0].at",
     'missing; an event needs at, action and vehicle, e.g. at = 60.0, action = "kill", vehicle = "usv2"'),
])
def test_bad_event_names_the_field_and_what_is_valid(raw, field, text):
    out, problems = events([raw])
    assert out == ()
    assert (field, text) in problems, problems


def test_not_an_array_of_tables():
    assert events({"at": 1}) == ((), [("event", "must be an array of tables ([[event]] sections), got the table "
                                                "{at = 1}")])


def test_without_the_ids_the_vehicle_is_not_judged():
    out, problems = events([{"at": 1, "action": "kill", "vehicle": "anyone"}], ids=None)
    assert problems == [] and out == (Event(1.0, "kill", "anyone"),)


def test_the_scenario_carries_the_validated_events():
    data = tomllib.loads(MINIMAL)
    data["event"] = [{"at": 10.0, "action": "pause", "vehicle": "usv1", "duration": 5.0}]
    s = parse_scenario(data)
    assert s.events == (Event(10.0, "pause", "usv1"), Event(15.0, "resume", "usv1"))
    assert s.raw["event"] == data["event"]  # the file's tables stay in raw
    assert parse_scenario(s.raw) == s


@pytest.mark.parametrize("raw, fragment", [
    ([{"at": 10.0, "action": "explode", "vehicle": "usv1"}], 'event[0].action: unknown action "explode"; choose one '
                                                             "of kill"),
    ([{"at": 10.0, "action": "kill", "vehicle": "nobody"}], 'event[0].vehicle: "nobody" is not a vehicle; ids are '
                                                            "usv1, usv2"),
    ({"t": 1}, "event: must be an array of tables"),
])
def test_a_scenario_with_bad_events_is_rejected(raw, fragment):
    data = tomllib.loads(MINIMAL)
    data["event"] = raw
    with pytest.raises(ConfigError) as e:
        parse_scenario(data, "x.toml")
    assert f"x.toml: {fragment}" in str(e.value)


@pytest.mark.parametrize("raw, field, text", [
    ([{"at": 10, "action": "resume", "vehicle": "usv1"}], "event[0].action", "it is live then, not paused"),
    ([{"at": 10, "action": "kill", "vehicle": "usv1"}, {"at": 5, "action": "kill", "vehicle": "usv1"}],
     "event[0].action", "already gone"),  # sorted by time: the later one, in the file first, is the second kill
    ([{"at": 10, "action": "kill", "vehicle": "usv1"}, {"at": 20, "action": "pause", "vehicle": "usv1"}],
     "event[1].action", "it is killed then"),
    ([{"at": 10, "action": "kill", "vehicle": "usv1"}, {"at": 20, "action": "resume", "vehicle": "usv1"}],
     "event[1].action", "comes back with a restart"),
])
def test_an_event_that_finds_its_vehicle_in_no_state_to_act_on_is_refused(raw, field, text):
    _, problems = events(raw)
    assert [f for f, _ in problems] == [field]
    assert text in problems[0][1]


def test_a_sequence_that_makes_sense_passes():
    _, problems = events([
        {"at": 10, "action": "pause", "vehicle": "usv1", "duration": 5},
        {"at": 20, "action": "kill", "vehicle": "usv1"},
        {"at": 30, "action": "restart", "vehicle": "usv1"},
        {"at": 40, "action": "pause", "vehicle": "usv1"},
        {"at": 45, "action": "kill", "vehicle": "usv1"},  # a paused process can be killed
        {"at": 50, "action": "restart", "vehicle": "usv1"},
        {"at": 55, "action": "restart", "vehicle": "usv2"},  # a live one can be restarted
    ])
    assert problems == []


def test_a_kill_or_restart_during_a_timed_pause_ends_it_without_its_resume():
    out, problems = events([
        {"at": 10, "action": "pause", "vehicle": "usv1", "duration": 5},
        {"at": 12, "action": "restart", "vehicle": "usv1"},
        {"at": 10, "action": "pause", "vehicle": "usv2", "duration": 5},
        {"at": 12, "action": "kill", "vehicle": "usv2"},
    ])
    assert problems == []
    assert [(e.at, e.action, e.vehicle) for e in out] == [
        (10, "pause", "usv1"), (10, "pause", "usv2"), (12, "restart", "usv1"), (12, "kill", "usv2")]


# ------------------------------------------------------------------ formation and path changes (issue 18)

from cdus.core.formation import FormationChange, PathChange  # noqa: E402
from tests.scenario.common import base  # noqa: E402


def with_events(*evs, **graph):
    data = base()
    data["event"] = list(evs)
    if graph:
        data["graph"] = graph
    return data


def test_formation_and_path_events_are_resolved_into_phases_and_path_tables():
    sc = parse_scenario(with_events(
        {"at": 20, "action": "formation", "offsets": [{"i": "uav1", "k": "usv2", "delta": 1.0}]},
        {"at": 10, "action": "formation", "phases": {"usv2": 2.5}},
        {"at": 15, "action": "path", "vehicle": "uav1", "path": {"family": "circle", "center": [5, 5, 10],
                                                                 "radius": 4}},
        {"at": 5, "action": "kill", "vehicle": "usv1"}, topology="chain"))
    assert [e.action for e in sc.events] == ["kill"]
    f1, p, f2 = sc.changes
    assert f1 == FormationChange(10.0, (("usv2", 2.5),))
    assert p == PathChange(15.0, "uav1", (("center", (5, 5, 10)), ("family", "circle"), ("radius", 4)))
    # the offset is resolved against the formation in force then (usv2 at 2.5): θ_uav1 = 2.5 + 1
    assert f2.at == 20.0 and f2.phases == (("uav1", pytest.approx(3.5)),)


def test_offsets_that_do_not_close_around_a_cycle_are_refused_naming_the_field_and_the_fix():
    with pytest.raises(ConfigError) as info:
        parse_scenario(with_events({"at": 1, "action": "formation",
                                    "offsets": [{"i": "usv2", "k": "usv1", "delta": 1.0}]}))  # a ring of 3
    text = str(info.value)
    assert "event[0].offsets: inconsistent formation offsets: with those in force" in text
    assert "give per-vehicle phases instead" in text


@pytest.mark.parametrize("event, field, text", [
    ({"action": "formation", "phases": {"usv9": 1.0}}, "event[0].phases", '"usv9" is not a vehicle'),
    ({"action": "formation", "phases": {"usv1": "x"}}, "event[0].phases.usv1", "must be a finite number"),
    ({"action": "formation", "phases": {"usv1": 1e300}}, "event[0].phases.usv1", "within ±1e+09"),
    ({"action": "formation", "phases": {}}, "event[0].phases", "must be a non-empty table"),
    ({"action": "formation"}, "event[0].phases", "has neither"),
    ({"action": "formation", "phases": {"usv1": 1.0}, "offsets": [{"i": "usv1", "k": "usv2", "delta": 1}]},
     "event[0].phases", "not both"),
    ({"action": "formation", "offsets": [{"i": "usv1", "k": "uav1", "delta": 1}]}, "event[0].offsets[0]",
     "usv1 does not listen to uav1"),
    ({"action": "formation", "offsets": [{"i": "usv1", "k": "usv2"}]}, "event[0].offsets[0].delta", "missing"),
    ({"action": "formation", "offsets": [{"i": "usv2", "k": "usv1", "delta": 1},
                                         {"i": "usv1", "k": "usv2", "delta": -1}]}, "event[0].offsets[1]",
     "given twice"),
    ({"action": "formation", "phases": {"usv1": 1.0}, "vehicle": "usv1"}, "event[0].vehicle", "not vehicle or path"),
    ({"action": "formation", "phases": {"usv1": 1.0}, "duration": 3}, "event[0].duration", "only a pause"),
    ({"action": "path", "vehicle": "uav1"}, "event[0].path", "missing; a path event needs vehicle and path"),
    ({"action": "path", "vehicle": "uav9", "path": {"family": "circle", "center": [0, 0, 0], "radius": 1}},
     "event[0].vehicle", '"uav9" is not a vehicle'),
    ({"action": "path", "vehicle": "uav1", "path": {"family": "cirle", "center": [0, 0, 0], "radius": 1}},
     "event[0].path.family", 'unknown path family "cirle"'),
    ({"action": "path", "vehicle": "uav1", "path": {"family": "circle", "center": [0, 0, 0], "radius": -1}},
     "event[0].path.radius", "must be > 0"),
    ({"action": "path", "vehicle": "uav1", "path": {"family": "circle", "center": [0, 0], "radius": 1}},
     "event[0].path", "a 3-D vehicle needs a 3-D path"),
    ({"action": "path", "vehicle": "uav1", "path": "circle"}, "event[0].path", "must be a table"),
    ({"action": "kill", "vehicle": "uav1", "phases": {"usv1": 1.0}}, "event[0].phases", 'only a "formation" event'),
])
def test_bad_formation_and_path_events_name_the_field(event, field, text):
    with pytest.raises(ConfigError) as info:
        parse_scenario(with_events({"at": 1, **event}, topology="chain"))  # usv1 - usv2 - uav1
    lines = [ln for ln in str(info.value).splitlines() if f": {field}: " in ln]
    assert any(text in ln for ln in lines), str(info.value)


def test_offsets_that_would_put_a_phase_beyond_the_limit_are_refused():
    """Each Δ within ±1e9, but along a chain they add up: every process takes phases within ±1e9 only."""
    with pytest.raises(ConfigError) as info:
        parse_scenario(with_events({"at": 1, "action": "formation", "offsets": [
            {"i": "usv2", "k": "usv1", "delta": 9e8}, {"i": "uav1", "k": "usv2", "delta": 9e8}]}, topology="chain"))
    assert "event[0].offsets: these offsets put the phase of uav1 at 1.8e+09, beyond ±1e+09" in str(info.value)


def test_a_run_time_path_that_retraces_itself_is_refused_as_the_config_refuses_it():
    """A ground station's or an [[event]]'s new path is checked as [[vehicle]] paths are: a
    Lissajous with all phases 0 runs back over itself (vehicles on it meet head-on)."""
    from cdus.scenario.events import check_path
    bad = check_path({"family": "lissajous", "center": [0, 0], "amplitude": [10, 10], "frequency": [1, 2]}, 2)
    assert isinstance(bad, tuple) and bad[0] == "phase" and "runs back over itself" in bad[1]
    good = check_path({"family": "lissajous", "center": [0, 0], "amplitude": [10, 10], "frequency": [1, 2],
                       "phase": [0, 1.5708]}, 2)
    assert not isinstance(good, tuple)


from hypothesis import given, settings, strategies as hst  # noqa: E402

_MAG = hst.one_of(hst.floats(-1e6, 1e6), hst.sampled_from([1e300, -1e308, 1e-308, 1e7, 1e6, -1e6, 0.5, 3.0]))


def _path_table(draw, dim: int) -> dict:
    family = draw(hst.sampled_from(["circle", "ellipse", "lissajous", "line"] + (["trefoil", "self_intersecting"]
                                                                                 if dim == 3 else [])))
    vec = lambda: [draw(_MAG) for _ in range(dim)]  # noqa: E731
    pos = lambda: abs(draw(_MAG)) or 1.0  # noqa: E731
    if family == "circle":
        t = {"center": vec(), "radius": pos(), "speed": pos()}
    elif family == "ellipse":
        t = {"center": vec(), "a": pos(), "b": pos(), "beta": pos()}
    elif family == "lissajous":
        t = {"center": vec(), "amplitude": vec(), "frequency": vec(), "phase": vec()}
    elif family == "line":
        t = {"origin": vec(), "heading": vec(), "speed": pos()}
    elif family == "trefoil":
        t = {"center": vec(), "scale": pos(), "height": pos(), "beta": pos()}
    else:
        t = {"center": vec(), "d": draw(_MAG), "beta": pos()}
    return {"family": family, **t}


@settings(max_examples=40, deadline=None)
@given(data=hst.data())
def test_a_path_event_the_check_takes_is_one_a_vehicle_can_follow_without_overflowing(data):
    """A path change (an [[event]], or a ground station's `gs path`, which the world checks
    with check_path and answers "applied") of a circle of radius 1e308 or a Lissajous of
    amplitude and frequency 1e300 was accepted, and the vehicle that took it ended
    (DivergedError: its numbers overflowed). Now every number is within its bound (cdus.wire.bounds) and
    the path's values are probed: what the check takes, the fleet flies."""
    from cdus.core.node import DivergedError
    from cdus.scenario.events import check_path
    from tests.sim.test_formation import scenario
    from cdus.sim.fleet import InProcessFleet

    vid, dim = data.draw(hst.sampled_from([("usv1", 2), ("uav1", 3)]))
    table = _path_table(data.draw, dim)
    checked = check_path(table, dim)
    if isinstance(checked, tuple):
        assert isinstance(checked[0], str) and checked[1]  # refused, with the key and why
        return
    try:
        InProcessFleet(scenario([{"at": 0.1, "action": "path", "vehicle": vid, "path": table}], duration=0.6)).run()
    except DivergedError as e:
        raise AssertionError(f"check_path took {table}, the vehicle diverged: {e}") from None
    except ConfigError as e:  # the scenario's own check is the same one: it must agree
        raise AssertionError(f"check_path took {table}, the config refused it: {e}") from None


def test_a_path_with_numbers_a_vehicle_cannot_compute_is_refused_with_its_key():
    from cdus.scenario.events import check_path

    for table, key in [({"family": "circle", "center": [1e308, -1e308], "radius": 1e308, "speed": 1e308}, "speed"),
                       ({"family": "lissajous", "center": [0, 0, 0], "amplitude": [1e300] * 3,
                         "frequency": [1e300, 1e-300, 1], "phase": [0, 1, 2]}, "amplitude"),
                       ({"family": "circle", "center": [0, 0], "radius": 1e7}, "radius")]:
        got = check_path(table, len(table["center"]))
        assert isinstance(got, tuple) and got[0] == key and "<= 1e+06" in got[1], got

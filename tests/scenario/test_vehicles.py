"""[[vehicle]] tables and the [defaults] under them."""

from __future__ import annotations

import math

import pytest

from cdus.scenario.config import parse_scenario
from cdus.scenario.vehicles import PRESETS, merge
from tests.scenario.common import base, check_bad, drop, problems, v0, v2, section


def test_full_vehicle_resolves_every_field():
    data = base()
    data["vehicle"][0].update({
        "plant": "usv_3dof", "regulator": "paper", "regulator_gains": {"b3": 2, "b1": 1.0},
        "start": {"position": [1, 2], "heading": 0.5}, "omega0": 3, "gains": {"k": [1, 2], "c": 4},
        "limits": {"speed": 5, "tau_u": 50}, "disturbance": {"constant": [0.1, 0], "gust": 0.2, "gust_tau": 2},
    })
    data["vehicle"][2].update({"plant": "uav_double_integrator", "start": {"position": [0, 0, 5]}})
    s = parse_scenario(data)
    u = s.vehicle("usv1")
    assert (u.plant, u.preset, u.epsilon) == ("usv_3dof", "cybership2", PRESETS["cybership2"])
    assert u.regulator == "paper" and u.regulator_gains == (("b1", 1.0), ("b3", 2.0))
    assert (u.start_position, u.start_heading, u.omega0) == ((1.0, 2.0), 0.5, 3.0)
    assert (u.k, u.c) == ((1.0, 2.0), 4.0)
    assert u.limits == (("speed", 5.0), ("tau_u", 50.0))
    assert u.disturbance == (("constant", (0.1, 0.0)), ("gust", 0.2), ("gust_tau", 2.0))
    a = s.vehicle("uav1")
    assert (a.dim, a.regulator, a.k, a.start_position, a.start_heading) == (3, "pd", (1.5,) * 3, (0, 0, 5), None)
    assert s.vehicle("usv2").start_heading is None


def test_epsilon_replaces_the_preset():
    data = base()
    eps = [-0.5, 1.0, 0.04, -0.2, 0.3, -0.5, -0.7]
    data["vehicle"][0].update({"plant": "usv_3dof", "epsilon": eps})
    v = parse_scenario(data).vehicle("usv1")
    assert v.epsilon == tuple(eps) and v.preset is None


def test_usv_position_start_without_heading_faces_east():
    data = base()
    data["vehicle"][0]["start"] = {"position": [3, 4]}
    assert parse_scenario(data).vehicle("usv1").start_heading == 0.0


def test_omega0_nearest_is_the_default():
    data = base()
    data["vehicle"][0]["omega0"] = "nearest"
    assert parse_scenario(data).vehicle("usv1").omega0 is None


def test_per_axis_k_from_fleet_gains_and_vehicle_override():
    data = base()
    data["gains"] = {"k": 2.0, "c": 3.0}
    data["vehicle"][2]["gains"] = {"k": [1, 1, 0.5]}
    s = parse_scenario(data)
    assert s.vehicle("usv1").k == (2.0, 2.0) and s.vehicle("usv1").c == 3.0
    assert s.vehicle("uav1").k == (1.0, 1.0, 0.5) and s.vehicle("uav1").c == 3.0


def test_defaults_merge_under_every_vehicle_one_level_deep():
    data = {
        "scenario": {"name": "t"},
        "gains": {"k": 1.0},
        "defaults": {
            "kind": "usv", "phase": 0.25, "plant": "usv_3dof", "preset": "cybership2",
            "path": {"family": "circle", "center": [-40, 50], "radius": 10},
            "gains": {"k": 3.0, "c": 5.0}, "limits": {"speed": 2.0},
            "start": {"region_min": [-60, 30], "region_max": [-20, 70]},
        },
        "vehicle": [
            {"id": "usv1"},
            {"id": "usv2", "path": {"radius": 20}, "gains": {"c": 1.0}, "limits": {"tau_r": 10},
             "epsilon": [-0.5, 1.0, 0.04, -0.2, 0.3, -0.5, -0.7], "start": {"position": [0, 0]}},
            {"id": "usv3", "path": {"family": "ellipse", "center": [0, 0], "a": 5, "b": 3}, "phase": 1.0},
            {"id": "uav1", "kind": "uav", "plant": "ideal", "path": {"center": [-40, 50, 20]},
             "start": {"position": [0, 0, 20]}},
        ],
    }
    s = parse_scenario(data)
    u1, u2, u3, a1 = s.vehicles
    assert (u1.kind, u1.phase, u1.plant, u1.preset, u1.k, u1.c) == ("usv", 0.25, "usv_3dof", "cybership2",
                                                                    (3.0, 3.0), 5.0)
    assert dict(u2.path) == {"family": "circle", "center": (-40, 50), "radius": 20}
    assert (u2.k, u2.c, u2.limits) == ((3.0, 3.0), 1.0, (("speed", 2.0), ("tau_r", 10.0)))
    assert u2.preset is None and u2.epsilon[2] == 0.04  # the vehicle's epsilon replaces the default preset
    assert u2.start_position == (0.0, 0.0)  # a position replaces the default random region
    assert dict(u3.path) == {"family": "ellipse", "center": (0, 0), "a": 5, "b": 3}  # another family: no radius
    assert u3.phase == 1.0
    # defaults that do not apply to a vehicle (preset for an ideal plant) are skipped
    assert (a1.kind, a1.plant, a1.preset, a1.regulator, a1.dim) == ("uav", "ideal", None, None, 3)
    assert dict(a1.path)["center"] == (-40, 50, 20)
    assert a1.start_position == (0.0, 0.0, 20.0) and a1.start_heading is None
    assert -60 <= u1.start_position[0] < -20 and 30 <= u1.start_position[1] < 70


def test_merge_records_which_values_came_from_the_defaults():
    merged, origin = merge({"phase": 1.0, "gains": {"k": 2.0, "c": 1.0}, "preset": "cybership2"},
                           {"gains": {"c": 3.0}, "epsilon": [1] * 7})
    assert merged == {"phase": 1.0, "gains": {"k": 2.0, "c": 3.0}, "epsilon": [1] * 7}
    assert origin == {("phase",), ("gains", "k")}


def test_defaults_for_another_regulator_or_plant_are_skipped():
    data = base()
    data["defaults"] = {"regulator": "heading", "regulator_gains": {"b_u": 2.0, "b": 3.0}, "start": {"heading": 1.0}}
    data["vehicle"][0]["plant"] = "usv_3dof"
    data["vehicle"][2]["plant"] = "uav_double_integrator"
    s = parse_scenario(data)
    assert (s.vehicle("usv1").regulator, s.vehicle("usv1").regulator_gains) == ("heading", (("b_u", 2.0),))
    assert (s.vehicle("uav1").regulator, s.vehicle("uav1").regulator_gains) == ("pd", (("b", 3.0),))
    assert s.vehicle("usv2").regulator is None and s.vehicle("uav1").start_heading is None


def test_random_starts_are_seeded_reproducible_and_independent_of_order():
    def scenario(seed, order):
        data = base()
        data["scenario"]["seed"] = seed
        data["defaults"] = {"start": {"region_min": [-60, 30], "region_max": [-20, 70]}}
        data["vehicle"] = [v for v in data["vehicle"] if v["kind"] == "usv"]
        data["vehicle"].append({"id": "uav1", "kind": "uav", "path": {"family": "circle", "center": [0, 0, 20],
                                                                      "radius": 10},
                                "start": {"region_min": [0, 0, 10], "region_max": [1, 1, 30]}})
        data["vehicle"] = [data["vehicle"][j] for j in order]
        return {v.id: (v.start_position, v.start_heading) for v in parse_scenario(data).vehicles}

    a = scenario(7, [0, 1, 2])
    assert a == scenario(7, [0, 1, 2])
    assert a == scenario(7, [2, 1, 0])
    assert a != scenario(8, [0, 1, 2])
    (x, y), psi = a["usv1"]
    assert -60 <= x < -20 and 30 <= y < 70 and -math.pi <= psi < math.pi
    assert a["usv1"] != a["usv2"]
    pos, heading = a["uav1"]
    assert len(pos) == 3 and 10 <= pos[2] < 30 and heading is None


def test_random_start_keeps_a_given_heading():
    data = base()
    data["vehicle"][0]["start"] = {"region_min": [0, 0], "region_max": [1, 1], "heading": 0.3}
    assert parse_scenario(data).vehicle("usv1").start_heading == 0.3


BAD = {
    "unknown vehicle key": (v0(gain={"k": 1}), 'vehicle[0] (id "usv1").gain: unknown key; did you mean "gains"?'),
    "unknown family": (v0(path={"family": "cirle"}),
                       'vehicle[0] (id "usv1").path.family: unknown path family "cirle" (did you mean "circle"?)'),
    "bad radius": (v2(path={"family": "circle", "center": [0, 0, 1], "radius": -1}),
                   'x.toml: vehicle[2] (id "uav1").path.radius: must be > 0, got -1'),
    "path not a table": (v0(path="circle"), 'vehicle[0] (id "usv1").path: must be a table, e.g. { family = '
                                            '"circle", center = [0, 0], radius = 10 }, got the string "circle"'),
    "missing path": (drop("vehicle", 0, "path"), 'vehicle[0] (id "usv1").path: missing; e.g. path = {'),
    "unknown preset": (v0(plant="usv_3dof", preset="cybership3"),
                       'preset: unknown preset "cybership3" (did you mean "cybership2"?); choose one of cybership2'),
    "preset and epsilon": (v0(plant="usv_3dof", preset="cybership2", epsilon=[1] * 7), "preset or epsilon, not both"),
    "epsilon zero": (v0(plant="usv_3dof", epsilon=[1, 1, 0, 1, 1, 1, 1]), "ε3 and ε5 must be non-zero"),
    "epsilon length": (v0(plant="usv_3dof", epsilon=[1, 1]), "epsilon: must be a list of 7 numbers >= -1000 and <= 1000 (ε1..ε7), got 2 "
                                                             "numbers [1, 1]"),
    "preset on ideal": (v0(preset="cybership2"), 'only used by plant = "usv_3dof"'),
    "unknown plant": (v0(plant="usv3dof"), 'unknown plant "usv3dof" (did you mean "usv_3dof"?)'),
    "plant for kind": (v2(plant="usv_3dof"), 'plant "usv_3dof" models a usv, not a uav; a uav takes plant = '
                                             '"ideal" or "uav_double_integrator"'),
    "unknown kind": (v0(kind="boat"), 'kind: unknown kind "boat"; choose one of usv, uav'),
    "unknown regulator": (v0(plant="usv_3dof", regulator="headin"),
                          'unknown regulator "headin" (did you mean "heading"?); choose one of heading, paper (the '
                          'regulators of plant "usv_3dof")'),
    "regulator for plant": (v0(plant="usv_3dof", regulator="pd"), 'regulator "pd" is not one for plant "usv_3dof"; '
                                                                  "choose one of heading, paper"),
    "regulator on ideal": (v0(regulator="heading"), "regulator: the ideal plant has no regulator"),
    "regulator gain": (v0(plant="usv_3dof", regulator_gains={"b1": 1}),
                       "regulator_gains.b1: unknown regulator gain; the heading regulator takes: b_u, b_r, k_psi"),
    # the pd regulator has one gain: k_v was listed (and in docs/config.md) but UAVGains does not take
    # it, so a config giving it crashed the run with a TypeError
    "pd k_v": (v2(plant="uav_double_integrator", regulator_gains={"k_v": 2.0}),
               "regulator_gains.k_v: unknown regulator gain; the pd regulator takes: b"),
    "regulator gain value": (v0(plant="usv_3dof", regulator_gains={"b_u": 0}),
                             "regulator_gains.b_u: must be a number > 0, got 0"),
    "negative c": (v0(gains={"c": -2}), 'vehicle[0] (id "usv1").gains.c: must be a number > 0, got -2'),
    "k per axis length": (v2(gains={"k": [1, 2]}), "gains.k: a list of per-axis gains needs 3 values for a uav"),
    "fleet k per axis": (section("gains", k=[1, 2, 3]), 'vehicle[0] (id "usv1").gains.k: a list of per-axis gains '
                                                        "needs 2 values for a usv (x, y), got 3: [1, 2, 3] (set in "
                                                        "[gains])"),
    "duplicate id": (v2(id="usv1"), 'vehicle[2].id: duplicate id "usv1" (also vehicle[0]); ids must be unique'),
    "bad id": (v0(id="usv 1!"), '"usv 1!" is not a valid id: use 1-32 characters'),
    "id not a string": (v0(id=1), "vehicle[0].id: must be a string of 1-32 letters, digits, _ or -, got the number 1"),
    "missing id": (drop("vehicle", 0, "id"), "vehicle[0].id: missing; every vehicle needs a unique id"),
    "missing kind": (drop("vehicle", 0, "kind"), 'vehicle[0] (id "usv1").kind: missing'),
    "no vehicles": (lambda d: d.update(vehicle=[]), "vehicle: no vehicles"),
    "vehicle table": (lambda d: d.update(vehicle={"id": "a"}), "[[vehicle]] sections, not [vehicle]"),
    "uav on 2-D path": (v2(path={"family": "circle", "center": [0, 0], "radius": 5}),
                        'vehicle[2] (id "uav1").path: a 3-D vehicle needs a 3-D path'),
    "start length": (v0(start={"position": [1, 2, 3]}), "start.position: must be a list of 2 numbers"),
    "start both": (v0(start={"position": [1, 2], "region_min": [0, 0]}), "give either position or region_min/"
                                                                         "region_max, not both"),
    "region order": (v0(start={"region_min": [0, 5], "region_max": [1, 5]}), "must be < region_max on every axis; "
                                                                             "not on y"),
    "region half": (v0(start={"region_min": [0, 5]}), "start.region_max: missing"),
    "uav heading": (v2(start={"heading": 1.0}), "a uav has no heading"),
    "omega0": (v0(omega0="near"), 'omega0: must be a number >= -1e+09 and <= 1e+09 (or "nearest": the ω of the path point nearest the '
                                  'start), got the string "near"'),
    "phase": (v0(phase="pi"), 'phase: must be a number >= -1e+09 and <= 1e+09 (θ_i, in ω units), got the string "pi"'),
    "limits key": (v0(limits={"sped": 1}), 'limits.sped: unknown key; did you mean "speed"?'),
    "limits not a table": (v0(limits=2), "limits: must be a table, e.g. limits = { speed = 2.0 }, got the number 2"),
    "gust": (v0(disturbance={"gust": -0.1}), "disturbance.gust: must be a number >= 0 and <= 1000 m/s (std), got -0.1"),
    "disturbance length": (v2(disturbance={"constant": [1, 0]}), "disturbance.constant: must be a list of 3 numbers"),
    "defaults id": (section("defaults", id="x"), "defaults.id: an id cannot be a default"),
    "defaults key": (section("defaults", phse=1), 'defaults.phse: unknown key; did you mean "phase"?'),
    "defaults table": (section("defaults", gains=2), "defaults.gains: must be a table, e.g. gains = { ... }, got the "
                                                     "number 2"),
    "defaults preset": (section("defaults", preset="x"), 'defaults.preset: unknown preset "x"; choose one of'),
    "defaults regulator": (section("defaults", regulator="pid"), 'defaults.regulator: unknown regulator "pid" (did '
                                                                 'you mean "pd"?); choose one of heading, paper, pd'),
    "defaults regulator gain": (section("defaults", regulator_gains={"kp": 1}),
                                "defaults.regulator_gains.kp: unknown key"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_vehicle_names_the_field_and_what_is_valid(name):
    check_bad(*BAD[name])


def test_defaults_problem_says_where_it_was_set():
    data = base()
    data["defaults"] = {"gains": {"k": [1, 1]}}
    assert '(id "uav1").gains.k: a list of per-axis gains needs 3 values for a uav (x, y, z), got 2: [1, 1] ' \
           "(set in [defaults])" in problems(data)
    data = base()
    data["defaults"] = {"plant": "usv_3dof", "kind": "usv"}
    assert 'vehicle[2] (id "uav1").plant: plant "usv_3dof" models a usv, not a uav (set in [defaults])' \
        in problems(data)


def _liss(**kw) -> dict:
    return {"family": "lissajous", "center": [0, 0], "amplitude": [20, 10], "frequency": [1, 2], **kw}


def test_a_lissajous_path_that_runs_back_over_itself_is_refused_naming_its_phase():
    """Zero phases (the default) make the 1:2 Lissajous a parabola traced back and forth: any
    two vehicles on it meet head-on twice a lap. Refused, with the fix."""
    text = problems(edit_paths(_liss()))
    assert 'vehicle[0] (id "usv1").path.phase: this Lissajous path runs back over itself' in text
    assert "stops at ω = 0" in text and "meet head-on twice a lap" in text and "phase = [0, 1.5708]" in text
    assert 'vehicle[1] (id "usv2").path.phase' in text
    # a 3-D curve that does not retrace, whose x, y (what a boat follows) does
    three = {"family": "lissajous", "center": [0, 0, 10], "amplitude": [20, 10, 2], "frequency": [1, 2, 1],
             "phase": [0, 0, 1.0]}
    data = base()
    data["vehicle"][2]["path"] = three
    parse_scenario(data)  # the drone follows all three axes: fine
    data["vehicle"][0]["path"] = three
    assert "its x, y (what a usv follows) stops at ω = 0" in problems(data)
    # one that moves on no axis a boat follows
    data["vehicle"][0]["path"] = {**three, "amplitude": [0, 0, 2]}
    assert "does not move (every amplitude or frequency is 0)" in problems(data)


def test_the_retrace_message_names_the_vehicle_s_kind():
    """Review of issue 17: a drone's refused Lissajous said "a boat cannot follow it"."""
    from cdus.scenario.events import check_path

    data = base()  # usv1, usv2, uav1
    data["vehicle"][0]["path"] = _liss()
    data["vehicle"][2]["path"] = {"family": "lissajous", "center": [0, 0, 10], "amplitude": [20, 10, 2],
                                  "frequency": [1, 2, 1]}
    lines = problems(data).splitlines()
    boat = next(ln for ln in lines if 'vehicle[0] (id "usv1").path.phase' in ln)
    drone = next(ln for ln in lines if 'vehicle[2] (id "uav1").path.phase' in ln)
    assert "(no tangent: a boat cannot follow it)" in boat and "drone" not in boat
    assert "(no tangent: a drone cannot follow it)" in drone and "boat" not in drone
    # a run-time path (a ground station's or an [[event]]'s) is worded alike, by the vehicle's dimension
    for dim, who, other in ((2, "a boat", "drone"), (3, "a drone", "boat")):
        center = [0, 0, 10][:dim]
        key, message = check_path({**_liss(), "center": center, "amplitude": [20, 10, 2][:dim],
                                   "frequency": [1, 2, 1][:dim]}, dim)
        assert key == "phase" and f"(no tangent: {who} cannot follow it)" in message and other not in message


def test_a_figure_eight_and_the_papers_path_are_accepted():
    s = parse_scenario(edit_paths(_liss(phase=[0, math.pi / 2])))
    assert s.vehicle("usv1").path == s.vehicle("usv2").path
    parse_scenario(edit_paths({"family": "self_intersecting", "d": 7}))


def edit_paths(path: dict) -> dict:
    data = base()
    del data["vehicle"][2]
    for v in data["vehicle"]:
        v["path"] = path
    return data


def test_a_bad_waypoint_from_the_defaults_says_where_it_was_set():
    """The note followed a whole-list refusal (path.waypoints) but not one of a waypoint
    (path.waypoints[1]), so a user hunting a bad [defaults] waypoint looked in [[vehicle]]."""
    data = base()
    data["defaults"] = {"path": {"family": "spline", "waypoints": [[0, 0], [0, "a"], [1, 1]]}}
    for v in data["vehicle"]:
        v["path"] = {"center": v["path"]["center"]}
    text = problems(data)
    assert "(id \"usv1\").path.waypoints[1]: must contain finite numbers, got [0, 'a'] (set in [defaults])" in text
    data["defaults"]["path"]["waypoints"] = [[0, 0], [1, 1, 1], [2, 2]]
    assert '(id "usv1").path.waypoints[1]: has 3 coordinates, waypoint 0 has 2' in problems(data)
    assert problems(data).count("(set in [defaults])") == 3
    own = base()  # a vehicle's own waypoint: no note
    own["vehicle"][0]["path"] = {"family": "spline", "waypoints": [[0, 0], [0, "a"], [1, 1]]}
    assert "path.waypoints[1]: must contain finite numbers, got [0, 'a']\n" in problems(own) + "\n"


def test_a_path_coordinate_out_of_bounds_is_refused_in_its_own_unit():
    """Every list of a path table was refused in "(m, or a rate)", a Lissajous phase (rad, within
    ±1e9) too."""
    data = base()
    data["vehicle"][0]["path"] = {"family": "spline", "waypoints": [[0, 0], [1e9, 0], [2, 2]]}
    assert "path.waypoints[1]: must contain numbers >= -1e+06 and <= 1e+06 m, got 1e+09" in problems(data)
    data["vehicle"][0]["path"] = _liss(phase=[0, 2e9])
    assert "path.phase: must contain numbers >= -1e+09 and <= 1e+09 rad, got 2e+09" in problems(data)

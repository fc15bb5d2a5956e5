import copy
import math
import pathlib
import pickle
import re
import tomllib

import pytest

from cdus.scenario.config import (
    PRESETS, ConfigError, Edge, Rates, Scenario, VehicleSpec, apply_override, load_scenario, parse_scenario,
    parse_value,
)
from cdus.core.paths import make_path

MINIMAL = """
[scenario]
name = "two_boats"

[[vehicle]]
id = "usv1"
kind = "usv"
path = { family = "circle", center = [0, 0], radius = 10 }

[[vehicle]]
id = "usv2"
kind = "usv"
phase = 1.5
path = { family = "circle", center = [0, 0], radius = 10 }
"""


def base() -> dict:
    """Three vehicles (2 USVs, 1 UAV) on circles, every default left unset."""
    return {
        "scenario": {"name": "t"},
        "vehicle": [
            {"id": "usv1", "kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10}},
            {"id": "usv2", "kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10}},
            {"id": "uav1", "kind": "uav", "path": {"family": "circle", "center": [0, 0, 20], "radius": 10}},
        ],
    }


def problems(data: dict, overrides=None) -> str:
    with pytest.raises(ConfigError) as info:
        parse_scenario(data, "x.toml", overrides)
    return str(info.value)


# --------------------------------------------------------------------------- valid


def test_minimal_file_resolves_to_the_dataclasses_with_defaults(tmp_path):
    f = tmp_path / "two.toml"
    f.write_text(MINIMAL)
    s = load_scenario(f)
    assert isinstance(s, Scenario)
    assert (s.name, s.description, s.source, s.duration, s.seed) == ("two_boats", "", str(f), 60.0, 0)
    assert s.rates == Rates(physics=200.0, control=50.0, broadcast=50.0)
    assert (s.path_tol, s.coord_tol, s.topology, s.directed) == (0.1, 0.05, "ring", False)
    assert s.link == {} and s.events == ()
    v1, v2 = s.vehicles
    assert v1 == VehicleSpec(
        id="usv1", index=0, kind="usv", dim=2, plant="ideal", epsilon=None, preset=None, regulator=None,
        regulator_gains=(), path=(("center", (0, 0)), ("family", "circle"), ("radius", 10)), phase=0.0,
        start_position=None, start_heading=None, omega0=None, k=(1.5, 1.5), c=2.0, limits=(), disturbance=(),
    )
    assert make_path(dict(v1.path)).period == pytest.approx(2 * math.pi)
    # undirected ring of two: one pair, both directions, Δ from the phases
    assert s.edges == (Edge("usv1", "usv2", 1.0, -1.5), Edge("usv2", "usv1", 1.0, 1.5))
    assert s.neighbours("usv2") == (Edge("usv2", "usv1", 1.0, 1.5),)
    assert s.metric_edges() == (Edge("usv1", "usv2", 1.0, -1.5),)
    assert s.vehicle("usv2") is v2
    with pytest.raises(KeyError, match="usv9"):
        s.vehicle("usv9")
    assert s.raw["vehicle"][1]["phase"] == 1.5
    hash(v1)  # specs are hashable


def test_raw_round_trips_to_the_same_scenario():
    data = base()
    data["vehicle"][0]["start"] = {"region_min": [-5, -5], "region_max": [5, 5]}
    s = parse_scenario(data)
    assert parse_scenario(s.raw) == s
    assert "start" not in base()["vehicle"][0]  # input not modified


def test_full_vehicle_resolves_every_field():
    data = base()
    data["rates"] = {"physics": 400, "control": 100, "broadcast": 20}
    data["link"] = {"loss": 0.1, "delay": {"base": 0.05}}
    data["event"] = [{"at": 10.0, "action": "kill", "vehicle": "usv1"}]
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
    assert s.rates == Rates(400.0, 100.0, 20.0)
    assert s.link == {"loss": 0.1, "delay": {"base": 0.05}}
    assert s.events == ({"at": 10.0, "action": "kill", "vehicle": "usv1"},)


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


def test_graph_edges_refine_weights_and_deltas_and_mirror_them_when_undirected():
    data = base()
    data["graph"] = {"weight": 2.0, "edge": [{"i": "usv2", "k": "usv1", "weight": 0.5, "delta": 1.0},
                                             {"i": "usv2", "k": "uav1", "delta": -1.0},
                                             {"i": "uav1", "k": "usv1", "delta": 2.0}]}
    s = parse_scenario(data)
    edges = {(e.i, e.k): (e.weight, e.delta) for e in s.edges}
    assert edges == {("usv1", "usv2"): (0.5, -1.0), ("usv1", "uav1"): (2.0, -2.0),
                     ("usv2", "usv1"): (0.5, 1.0), ("usv2", "uav1"): (2.0, -1.0),
                     ("uav1", "usv1"): (2.0, 2.0), ("uav1", "usv2"): (2.0, 1.0)}
    assert [(e.i, e.k) for e in s.metric_edges()] == [("usv1", "usv2"), ("usv1", "uav1"), ("usv2", "uav1")]


def test_explicit_directed_graph():
    data = base()
    data["graph"] = {"topology": "explicit", "directed": True, "edges": [["usv2", "usv1"]],
                     "edge": [{"i": "uav1", "k": "usv2", "delta": 0.5}]}
    s = parse_scenario(data)
    assert s.edges == (Edge("usv2", "usv1", 1.0, 0.0), Edge("uav1", "usv2", 1.0, 0.5))
    assert s.metric_edges() == s.edges
    assert s.neighbours("usv1") == ()


def test_star_hub_and_single_vehicle_without_graph():
    data = base()
    data["graph"] = {"topology": "star", "directed": True, "hub": "uav1"}
    assert [(e.i, e.k) for e in parse_scenario(data).edges] == [("usv1", "uav1"), ("usv2", "uav1")]
    data = base()
    data["vehicle"] = data["vehicle"][:1]
    assert parse_scenario(data).edges == ()


def test_paper_phases_pass():
    data = base()
    for j, v in enumerate(data["vehicle"]):
        v["phase"] = 2 * math.pi * j / 3
    assert len(parse_scenario(data).edges) == 6


# --------------------------------------------------------------------------- overrides


def test_apply_override_sets_dotted_keys_and_creates_tables():
    data = base()
    apply_override(data, "scenario.seed", 4)
    apply_override(data, "rates.control", 20.0)
    apply_override(data, "link.loss", 0.2)
    apply_override(data, "vehicle.usv2.gains.k", [1, 2])
    apply_override(data, "vehicle.uav1.path.radius", 5)
    apply_override(data, "graph.topology", "chain")
    assert data["scenario"]["seed"] == 4 and data["rates"] == {"control": 20.0} and data["link"] == {"loss": 0.2}
    assert data["vehicle"][1]["gains"] == {"k": [1, 2]} and data["vehicle"][2]["path"]["radius"] == 5
    s = parse_scenario(data)
    assert (s.seed, s.rates.control, s.link, s.topology) == (4, 20.0, {"loss": 0.2}, "chain")
    assert s.vehicle("usv2").k == (1.0, 2.0)


def test_unset_rates_follow_the_control_rate():
    s = parse_scenario(edit(section("rates", control=20)))
    assert s.rates == Rates(physics=200.0, control=20.0, broadcast=20.0)
    s = parse_scenario(edit(section("rates", control=500)))
    assert s.rates == Rates(physics=500.0, control=500.0, broadcast=500.0)


def test_overrides_passed_to_load_scenario(tmp_path):
    f = tmp_path / "two.toml"
    f.write_text(MINIMAL)
    s = load_scenario(f, {"scenario.duration": 5.0, "vehicle.usv1.phase": 0.5})
    assert s.duration == 5.0 and s.vehicle("usv1").phase == 0.5
    assert s.raw["scenario"]["duration"] == 5.0


@pytest.mark.parametrize("key, fragment", [
    ("vehicle.usv9.gains.k", 'no vehicle with id "usv9"'),
    ("vehicle.usv1", "vehicle.<id>.<key>"),
    ("scenario..seed", "not a dotted key"),
    ("scenario.name.x", "scenario.name is the string"),
])
def test_bad_override(key, fragment):
    with pytest.raises(ConfigError) as info:
        apply_override(base(), key, 1)
    assert fragment in str(info.value)


def test_override_error_names_the_file():
    assert 'x.toml: override vehicle.usv3.phase: no vehicle with id "usv3"' in problems(
        base(), {"vehicle.usv3.phase": 1.0})


@pytest.mark.parametrize("text, value", [
    ("3", 3), ("2.5", 2.5), ("-1e3", -1000.0), ("true", True), ("False", False), ("[1, 2]", [1, 2]),
    ('"x y"', "x y"), ("ring", "ring"), ("{ k = 1 }", {"k": 1}), ("1979-05-27", "1979-05-27"),
])
def test_parse_value(text, value):
    assert parse_value(text) == value and type(parse_value(text)) is type(value)


# --------------------------------------------------------------------------- bad configs


def edit(fn):
    data = base()
    fn(data)
    return data


def v0(**kw):
    return lambda d: d["vehicle"][0].update(kw)


def v2(**kw):
    return lambda d: d["vehicle"][2].update(kw)


def section(name, **kw):
    return lambda d: d.setdefault(name, {}).update(kw)


def ring6_deltas(d):
    d["vehicle"] = [{"id": f"v{j}", "kind": "usv" if j % 2 else "uav",
                     "path": {"family": "circle", "center": [-40, 50, 20], "radius": 10}} for j in range(1, 7)]
    d["graph"] = {"edge": [{"i": f"v{j}", "k": f"v{j % 6 + 1}", "delta": 2 * math.pi / 3} for j in range(1, 7)]}


def ring3_deltas(d):
    d["graph"] = {"edge": [{"i": "usv1", "k": "usv2", "delta": 0.5}, {"i": "usv2", "k": "uav1", "delta": 0.25},
                           {"i": "uav1", "k": "usv1", "delta": 0.25}]}


def drop(*path):
    def fn(d):
        node = d
        for p in path[:-1]:
            node = node[p]
        del node[path[-1]]
    return fn


BAD = {
    "unknown key": (section("scenario", durration=3), 'scenario.durration: unknown key; did you mean "duration"?'),
    "unknown section": (lambda d: d.update(vehicles=[]), 'vehicles: unknown section; did you mean "vehicle"?'),
    "unknown vehicle key": (v0(gain={"k": 1}), 'vehicle[0] (id "usv1").gain: unknown key; did you mean "gains"?'),
    "string for number": (section("rates", control="fast"),
                          'rates.control: must be a number > 0 Hz, got the string "fast"'),
    "bool for number": (section("scenario", duration=True), "scenario.duration: must be a number > 0 s, "
                                                            "got the boolean true"),
    "missing name": (drop("scenario", "name"), "scenario.name: missing"),
    "seed": (section("scenario", seed=-1), "scenario.seed: must be an integer >= 0, got the number -1"),
    "unknown family": (v0(path={"family": "cirle"}),
                       'vehicle[0] (id "usv1").path.family: unknown path family "cirle" (did you mean "circle"?)'),
    "bad radius": (v2(path={"family": "circle", "center": [0, 0, 1], "radius": -1}),
                   'x.toml: vehicle[2] (id "uav1").path.radius: must be > 0, got -1'),
    "unknown preset": (v0(plant="usv_3dof", preset="cybership3"),
                       'preset: unknown preset "cybership3" (did you mean "cybership2"?)'),
    "preset and epsilon": (v0(plant="usv_3dof", preset="cybership2", epsilon=[1] * 7), "preset or epsilon, not both"),
    "epsilon zero": (v0(plant="usv_3dof", epsilon=[1, 1, 0, 1, 1, 1, 1]), "ε3 and ε5 must be non-zero"),
    "preset on ideal": (v0(preset="cybership2"), 'only used by plant = "usv_3dof"'),
    "unknown plant": (v0(plant="usv3dof"), 'unknown plant "usv3dof" (did you mean "usv_3dof"?)'),
    "plant for kind": (v2(plant="usv_3dof"), 'plant "usv_3dof" models a usv, not a uav; a uav takes plant = '
                                             '"ideal" or "uav_double_integrator"'),
    "unknown regulator": (v0(plant="usv_3dof", regulator="headin"), 'unknown regulator "headin" (did you mean'),
    "regulator for plant": (v0(plant="usv_3dof", regulator="pd"), 'regulator "pd" is not one for plant "usv_3dof"'),
    "regulator on ideal": (v0(regulator="heading"), "regulator: the ideal plant has no regulator"),
    "regulator gain": (v0(plant="usv_3dof", regulator_gains={"b1": 1}),
                       "regulator_gains.b1: unknown regulator gain; the heading regulator takes: b_u, b_r, k_psi"),
    "zero k": (section("gains", k=0), "gains.k: must be > 0, got 0"),
    "negative c": (v0(gains={"c": -2}), 'vehicle[0] (id "usv1").gains.c: must be > 0, got -2'),
    "k per axis length": (v2(gains={"k": [1, 2]}), "gains.k: a list of per-axis gains needs 3 values for a uav"),
    "zero rate": (section("rates", broadcast=0), "rates.broadcast: must be > 0 Hz, got 0"),
    "physics < control": (section("rates", physics=100, control=200), "rates.physics: must be >= rates.control "
                                                                       "(200 Hz)"),
    "broadcast > control": (section("rates", broadcast=100), "rates.broadcast: must be <= rates.control (50 Hz)"),
    "broadcast > given control": (section("rates", control=20, broadcast=50), "rates.broadcast: must be <= "
                                                                               "rates.control (20 Hz)"),
    "zero tolerance": (section("metrics", coord_tol=0.0), "metrics.coord_tol: must be > 0 rad, got 0.0"),
    "negative duration": (section("scenario", duration=-5), "scenario.duration: must be > 0 s, got -5"),
    "duplicate id": (v2(id="usv1"), 'vehicle[2].id: duplicate id "usv1" (also vehicle[0]); ids must be unique'),
    "bad id": (v0(id="usv 1!"), '"usv 1!" is not a valid id: use 1-32 characters'),
    "missing kind": (drop("vehicle", 0, "kind"), 'vehicle[0] (id "usv1").kind: missing'),
    "no vehicles": (lambda d: d.update(vehicle=[]), "vehicle: no vehicles"),
    "vehicle table": (lambda d: d.update(vehicle={"id": "a"}), "[[vehicle]] sections, not [vehicle]"),
    "uav on 2-D path": (v2(path={"family": "circle", "center": [0, 0], "radius": 5}),
                        'vehicle[2] (id "uav1").path: a 3-D vehicle needs a 3-D path'),
    "start length": (v0(start={"position": [1, 2, 3]}), "start.position: must be a list of 2 numbers"),
    "region order": (v0(start={"region_min": [0, 5], "region_max": [1, 5]}), "must be < region_max on every axis; "
                                                                             "not on y"),
    "region half": (v0(start={"region_min": [0, 5]}), "start.region_max: missing"),
    "uav heading": (v2(start={"heading": 1.0}), "a uav has no heading"),
    "omega0": (v0(omega0="near"), 'omega0: must be a number, got the string "near" (or "nearest"'),
    "limits key": (v0(limits={"sped": 1}), 'limits.sped: unknown key; did you mean "speed"?'),
    "gust": (v0(disturbance={"gust": -0.1}), "disturbance.gust: must be >= 0 m/s (std), got -0.1"),
    "disturbance length": (v2(disturbance={"constant": [1, 0]}), "disturbance.constant: must be a list of 3 numbers"),
    "unknown topology": (section("graph", topology="rign"), 'unknown topology "rign" (did you mean "ring"?)'),
    "unknown vehicle in graph": (section("graph", topology="explicit", edges=[["usv1", "usv9"]]),
                                 'graph.edges[0]: "usv9" is not a vehicle'),
    "self loop": (section("graph", edge=[{"i": "usv1", "k": "usv1"}]), "graph.edge[0]: self-loop"),
    "hub": (section("graph", topology="star", hub="uav2"), 'graph.hub: hub "uav2" is not a vehicle'),
    "hub without star": (section("graph", hub="uav1"), 'graph.hub: only used with topology = "star"'),
    "edges without explicit": (section("graph", edges=[["usv1", "usv2"]]),
                               'graph.edges: only used with topology = "explicit" (topology is "ring")'),
    "edge not in topology": (section("graph", topology="chain", directed=True, edge=[{"i": "usv1", "k": "usv2"}]),
                             "graph.edge[0]: usv1 does not listen to usv2 in this directed chain"),
    "edge twice undirected": (section("graph", edge=[{"i": "usv1", "k": "usv2"}, {"i": "usv2", "k": "usv1"}]),
                              "graph.edge[1]: the pair usv2 - usv1 is already set by graph.edge[0]"),
    "not connected": (section("graph", topology="explicit", edges=[["usv1", "usv2"]]),
                      'graph: the graph is not connected: uav1 cannot exchange ω with usv1, usv2; add an edge such '
                      'as ["uav1", "usv1"]'),
    "reversed star": (section("graph", topology="explicit", directed=True, edges=[["usv1", "usv2"], ["usv1", "uav1"]]),
                      "no directed spanning tree: uav1 never hears (even indirectly) from usv2"),
    "inconsistent deltas": (ring3_deltas, "around the cycle usv1 -> usv2 -> uav1 -> usv1 the deltas sum to 1, not 0"),
    "paper 6-ring": (ring6_deltas, "the deltas sum to 12.5664 (4π), not 0"),
    "link not a table": (lambda d: d.update(link=3), "link: must be a table"),
    "event not array": (lambda d: d.update(event={"t": 1}), "event: must be an array of tables"),
    "defaults id": (section("defaults", id="x"), "defaults.id: an id cannot be a default"),
    "defaults key": (section("defaults", phse=1), 'defaults.phse: unknown key; did you mean "phase"?'),
    "ring of one": (lambda d: d.update(vehicle=d["vehicle"][:1], graph={"topology": "ring"}),
                    "a ring needs at least 2 vehicles"),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_config_names_the_field_and_what_is_valid(name):
    fn, fragment = BAD[name]
    message = problems(edit(fn))
    assert fragment in message
    assert all(line.startswith("x.toml: ") for line in message.splitlines())


def test_paper_six_ring_with_two_thirds_pi_deltas_is_rejected_with_the_cycle_and_phases():
    message = problems(edit(ring6_deltas))
    assert message.count("\n") == 0
    assert ("graph.edge: inconsistent formation offsets: around the cycle "
            "v1 -> v2 -> v3 -> v4 -> v5 -> v6 -> v1") in message
    assert "the sum is 2 × 2π, 2 laps of the path: the formation cannot close" in message
    assert 'vehicle "v1" phase = 0.0, vehicle "v2" phase = 4.18879' in message


def test_reversed_directed_chain_suggests_the_direction():
    # uav1 leads (usv2 and usv1 hear it): a valid tree
    parse_scenario(edit(section("graph", topology="explicit", directed=True,
                                edges=[["usv1", "usv2"], ["usv2", "uav1"], ["usv1", "uav1"]])))
    message = problems(edit(section("graph", topology="explicit", directed=True,
                                    edges=[["usv1", "usv2"], ["usv1", "uav1"]])))
    assert 'add a pair such as ["uav1", "usv2"]' in message
    assert "reverse the pairs: written the other way round they form a tree led by usv1" in message


def test_every_problem_is_reported_at_once():
    data = edit(section("rates", control=-1))
    data["scenario"]["duration"] = 0
    data["vehicle"][2]["gains"] = {"k": [1, 2]}
    data["vehicle"][1]["kind"] = "boat"
    with pytest.raises(ConfigError) as info:
        parse_scenario(data, "x.toml")
    fields = [f for f, _ in info.value.problems]
    assert fields == ["scenario.duration", "rates.control", 'vehicle[1] (id "usv2").kind',
                      'vehicle[2] (id "uav1").gains.k']
    assert len(str(info.value).splitlines()) == 4


def test_defaults_problem_says_where_it_was_set():
    data = base()
    data["defaults"] = {"gains": {"k": [1, 1]}}
    assert '(id "uav1").gains.k: a list of per-axis gains needs 3 values for a uav (x, y, z), got 2: [1, 1] ' \
           "(set in [defaults])" in problems(data)


def test_toml_syntax_error_gives_line_and_column(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('[scenario]\nname = "x\n')
    with pytest.raises(ConfigError) as info:
        load_scenario(f)
    assert str(info.value).startswith(f"{f}: line 2, column ")
    assert "TOML syntax error" in str(info.value)


def test_missing_file():
    with pytest.raises(ConfigError, match="not found"):
        load_scenario("/nonexistent/x.toml")


def test_base_is_valid():
    s = parse_scenario(copy.deepcopy(base()))
    assert [v.id for v in s.vehicles] == ["usv1", "usv2", "uav1"]


def test_the_example_in_the_user_reference_is_valid():
    doc = pathlib.Path(__file__).resolve().parents[2] / "docs" / "config.md"
    example = re.search(r"```toml\n(.*?)```", doc.read_text(), re.S).group(1)
    s = parse_scenario(tomllib.loads(example), "docs/config.md")
    assert [v.id for v in s.vehicles] == ["usv1", "uav1"]
    assert s.rates == Rates(200.0, 50.0, 50.0)
    assert s.vehicle("usv1").regulator == "heading" and s.vehicle("uav1").k == (1.5, 1.5, 3.0)


def test_config_error_survives_pickling():
    try:
        parse_scenario(edit(section("rates", control=-1)), "x.toml")
    except ConfigError as e:
        again = pickle.loads(pickle.dumps(e))
        assert str(again) == str(e) and again.problems == e.problems
    else:
        pytest.fail("no ConfigError")


@pytest.mark.parametrize("link,events,fragment", [
    ({"loss": 2.0}, [], "link.loss: must be a probability"),
    ({"partition": [{"from": 5.0, "to": 1.0, "groups": [["usv1"], ["usv2"]]}]}, [], "link.partition[0]"),
    ({}, [{"at": 10.0, "action": "explode", "vehicle": "usv1"}], "event[0].action: must be one of kill"),
    ({}, [{"at": 10.0, "action": "kill", "vehicle": "nobody"}], "event[0].vehicle: no vehicle 'nobody'"),
    ({}, [{"at": 10.0, "action": "kill", "vehicle": "usv1", "duration": 3.0}], "only a pause takes a duration"),
])
def test_link_and_event_tables_are_checked_with_the_vehicle_ids(link, events, fragment):
    data = tomllib.loads(MINIMAL)
    data["link"] = link
    data["event"] = events
    with pytest.raises(ConfigError) as e:
        parse_scenario(data)
    assert fragment in str(e.value)

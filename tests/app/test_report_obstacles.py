"""What a person running a scenario with [[obstacle]]s is told: the summary's obstacles line (the
metrics' ``obstacles`` block at a glance: the closest clearance, the vehicles inside or within
their margin, the filter off) and the notes where the run starts (cdus.sim.reports.obstacle_lines:
the filter off, an obstacle no vehicle sees, a vehicle starting inside one)."""

import pytest

from cdus.app.report import obstacle_lines as summary_obstacle_lines
from cdus.app.report import summary_table
from cdus.scenario.config import parse_scenario
from cdus.scenario.errors import ConfigError
from cdus.sim.fleet import InProcessFleet
from cdus.sim.reports import obstacle_lines as start_notes

ISLAND = {"name": "island", "shape": "circle", "center": [5.0, 0.0], "radius": 1.0, "margin": 0.5}


def _scenario(obstacles, safety=None, start=None, kinds=("usv",)):
    """Boats (and drones at 10 m) sailing east along y = 0 at 1 m/s from x = 0, through the island at x = 5."""
    vehicles = []
    for j, kind in enumerate(kinds):
        origin = [0.0, 0.0] if kind == "usv" else [0.0, 0.0, 10.0]
        heading = [-1.0, 0.0] if kind == "usv" else [-1.0, 0.0, 0.0]  # ω falls: east
        v = {"id": f"{kind}{j}", "kind": kind, "plant": "ideal", "omega0": 0.0,
             "path": {"family": "line", "origin": origin, "heading": heading, "speed": 1.0}}
        if start is not None and kind == "usv":
            v["start"] = {"position": start}
        vehicles.append(v)
    data = {"scenario": {"name": "isle", "duration": 8.0}, "graph": {"topology": "complete"},
            "gains": {"k": 1.5, "c": 0.5}, "vehicle": vehicles, "obstacle": list(obstacles)}
    if safety is not None:
        data["safety"] = safety
    return parse_scenario(data)


SAFETY = {"enabled": True, "radius": 1.0, "range": 5.0, "rate": 10.0, "latency": 0.02}


def test_without_the_filter_the_summary_says_who_went_inside_and_that_the_filter_is_off():
    sc = _scenario([ISLAND])
    m = InProcessFleet(sc).run().metrics
    [line] = summary_obstacle_lines(m)
    clearance = m.obstacles.vehicles["usv0"]["min_clearance_m"]
    assert clearance < -0.9
    assert line.startswith(f"  obstacles (1): closest usv0 {clearance:.3f} m from island at t = ")
    assert line.endswith("(margin 0.5 m)  [INSIDE AN OBSTACLE: usv0; the filter is off: obstacles are only measured]")
    assert line in summary_table(m, sc.vehicles).splitlines()
    [note] = start_notes(sc)
    assert note.startswith("note: [safety] is off: the vehicles do not avoid the 1 [[obstacle]] table(s)")
    assert "set [safety] enabled = true" in note


def test_with_the_filter_the_summary_gives_the_clearance_kept_and_the_time_deflected():
    sc = _scenario([ISLAND], SAFETY)
    m = InProcessFleet(sc).run().metrics
    [line] = summary_obstacle_lines(m)
    r = m.obstacles.vehicles["usv0"]
    assert r["min_clearance_m"] >= 0.5 and r["deflected_s"] > 0.0
    assert f"closest usv0 {r['min_clearance_m']:.3f} m from island" in line
    assert line.endswith(f"deflected {r['deflected_s']:.2f} s (summed over the vehicles) (every vehicle kept its margin)")
    assert start_notes(sc) == []


def test_no_obstacles_no_line_and_no_note():
    sc = parse_scenario({"scenario": {"name": "x", "duration": 1.0}, "graph": {"topology": "complete"},
                         "gains": {"k": 1.5, "c": 0.5},
                         "vehicle": [{"id": "b", "kind": "usv", "plant": "ideal", "omega0": 0.0, "path": {
                             "family": "line", "origin": [0.0, 0.0], "heading": [1.0, 0.0], "speed": 1.0}}]})
    assert summary_obstacle_lines(InProcessFleet(sc).run().metrics) == [] and start_notes(sc) == []


def test_a_shape_in_the_air_with_no_drone_is_said_to_be_seen_by_nobody():
    mast = {"name": "mast", "shape": "cylinder", "center": [5.0, 0.0], "radius": 1.0, "z": [0.0, 20.0]}
    sc = _scenario([mast], SAFETY)
    assert start_notes(sc) == ["note: obstacle mast (cylinder) is seen by drones only and the fleet has no drone: "
                               "nothing avoids or measures it (use a circle or a polygon for boats)"]
    [line] = summary_obstacle_lines(InProcessFleet(sc).run().metrics)
    assert line == ("  obstacles (1): no vehicle shares a medium with them (boats see circles and polygons, "
                    "drones cylinders and boxes)")


def test_a_vehicle_starting_within_an_obstacles_margin_is_named_where_the_run_starts():
    # inside the solid is refused when the scenario is read (tests/scenario/test_obstacles.py)
    with pytest.raises(ConfigError, match=r'vehicle\[0\] \(id "usv0"\).start: vehicle usv0 would start 0.8 m inside'):
        _scenario([ISLAND], SAFETY, start=[5.2, 0.0])
    assert start_notes(_scenario([ISLAND], SAFETY, start=[6.2, 0.0])) == [
        "note: usv0 starts 0.2 m from it, within its margin 0.5 m (obstacle island): the filter pushes it out first"]
    # on its path (no start): the path's point at ω0 = 0, (0, 0), 4 m from the island
    assert start_notes(_scenario([ISLAND], SAFETY)) == []
    # a drone starts at 10 m: a mast up to 5 m is 5 m below it, a mast up to 15 m holds it
    low = {"name": "low", "shape": "cylinder", "center": [0.0, 0.0], "radius": 1.0, "z": [0.0, 5.0], "margin": 0.5}
    assert start_notes(_scenario([low], SAFETY, kinds=("uav",))) == []
    tall = dict(low, name="tall", z=[0.0, 15.0])
    with pytest.raises(ConfigError, match="would start 1 m inside obstacle 'tall'"):
        _scenario([tall], SAFETY, kinds=("uav",))

"""cdus.core.obstacle_metrics: the metrics JSON's ``obstacles`` block on hand-worked tracks (each
figure below is worked out from the shapes' geometry, not read off a run)."""

from __future__ import annotations

from cdus.core.obstacle_metrics import obstacle_block
from cdus.core.obstacles import Circle, Cylinder

ISLAND = Circle((0.0, 0.0), 2.0, 1.0, name="island")
MAST = Cylinder((10.0, 0.0), 1.0, (0.0, 10.0), 1.0, name="mast")


def test_each_vehicle_gets_its_closest_approach_the_first_time_it_happens_and_its_deflected_time():
    t = [0.0, 0.5, 1.0]
    # per tick: usv1 (a boat's z ignored by the water shape), uav1, uav2
    q = [[(5.0, 0.0, 7.0), (10.0, 4.0, 5.0), (10.0, 1.5, 5.0)],
         [(3.25, 0.0, 7.0), (10.0, 2.0, 5.0), (10.0, 1.5, 5.0)],
         [(0.0, 3.25, 0.0), (10.0, 2.5, 5.0), (10.0, 1.5, 5.0)]]  # usv1 as close again at 1.0: t stays 0.5
    got = obstacle_block(t, q, ["usv1", "uav1", "uav2"], ["usv", "uav", "uav"], (ISLAND, MAST), [3, 0, 7], 0.01)
    assert got == {
        "count": 2, "min_clearance_m": 0.5, "below_margin": ["uav2"],  # uav1 exactly at its margin is not below
        "vehicles": {
            "usv1": {"min_clearance_m": 1.25, "obstacle": "island", "t": 0.5, "margin_m": 1.0, "deflected_s": 0.03},
            "uav1": {"min_clearance_m": 1.0, "obstacle": "mast", "t": 0.5, "margin_m": 1.0, "deflected_s": 0.0},
            "uav2": {"min_clearance_m": 0.5, "obstacle": "mast", "t": 0.0, "margin_m": 1.0, "deflected_s": 0.07},
        }}


def test_figures_keep_six_decimals():
    q = [[(2.0 + 1.23456789, 0.0, 0.0)]]
    got = obstacle_block([0.12345678], q, ["usv1"], ["usv"], (ISLAND,), [1], 1 / 3)
    assert got["vehicles"]["usv1"] == {"min_clearance_m": 1.234568, "obstacle": "island", "t": 0.123457,
                                       "margin_m": 1.0, "deflected_s": 0.333333}


def test_a_vehicle_with_no_obstacle_of_its_medium_and_unknown_deflection_reports_nulls():
    q = [[(0.0, 0.0, 10.0)], [(1.0, 0.0, 10.0)]]  # a drone right over the island: water shapes are not its
    got = obstacle_block([0.0, 0.1], q, ["uav1"], ["uav"], (ISLAND,), None, 0.01)
    assert got == {"count": 1, "min_clearance_m": None, "below_margin": [],
                   "vehicles": {"uav1": {"min_clearance_m": None, "obstacle": None, "t": None, "margin_m": None,
                                         "deflected_s": None}}}

"""bench/safety_montecarlo.py's encounters: valid scenarios, the same for a seed, different
across seeds, dangerous by construction (the benchmark itself is never a timed test)."""

from __future__ import annotations

import math

import pytest

from bench import safety_montecarlo as mc
from cdus.scenario.paths import make_path
from cdus.scenario.config import parse_scenario
from cdus.sim.fleet import InProcessFleet


@pytest.mark.parametrize("preset", mc.ALL_PRESETS)
def test_encounters_are_valid_consistent_scenarios_of_their_preset(preset):
    kinds = set()
    for enc in mc.encounters(preset, 8, seed=3):
        kinds.add(enc.kind)
        for on in (True, False):
            sc = parse_scenario(enc.scenario_data(on))  # raises ConfigError on a bad encounter
            assert sc.safety.enabled is on and sc.safety.radius == mc.RADIUS
        assert all(v.phase == 0.0 for v in sc.vehicles)  # one formation: everybody at P together
        plants = {v.plant for v in sc.vehicles}
        if preset == "cross_domain":
            assert [v.kind for v in sc.vehicles] == ["usv", "usv", "uav"]
            assert sc.vehicles[2].start_position[2] == 8.0  # the drone descends
        else:
            assert plants == {mc.PLANTS[preset][1]}
            if mc.PLANTS[preset][0] == "uav":  # drones at one altitude, so they can collide
                assert {make_path(dict(v.path)).eval(0.0)[0][2] for v in sc.vehicles} == {mc.ALTITUDE}
        n = len(sc.vehicles)
        assert {"crossing": 2 <= n <= 3, "head_on": n == 2, "overtaking": n == 2, "converging": 4 <= n <= 8,
                "descent": n == 3}[enc.kind]
        for v in sc.vehicles:  # each on a line through P (within 0.4 R), there at t = omega0
            path = make_path(dict(v.path))
            at_p = path.eval(0.0)[0]
            meet = tuple(enc.data["vehicle"][0]["path"]["origin"][:2])
            assert math.dist(at_p[:2], meet) <= 2 * 0.4 * mc.RADIUS + 1e-9
            assert abs(v.omega0 - enc.meet_time) <= 0.2 + 1e-9
    if preset != "cross_domain":
        assert kinds == set(mc.KINDS)


def test_the_same_seed_gives_the_same_encounters_and_another_seed_others():
    for preset in mc.ALL_PRESETS:
        a, b = mc.encounters(preset, 6, seed=7), mc.encounters(preset, 6, seed=7)
        assert [e.data for e in a] == [e.data for e in b]
        assert [e.data for e in a] != [e.data for e in mc.encounters(preset, 6, seed=8)]
        assert mc.generate(preset, 4, 7).data == a[4].data  # one encounter does not depend on the others


def test_an_unknown_preset_is_refused():
    with pytest.raises(ValueError, match="unknown preset"):
        mc.generate("submarine", 0, 1)


def test_an_encounter_without_the_filter_comes_within_the_radius_and_the_run_reports_it():
    enc = mc.generate("ideal", 1, seed=1)  # a head-on
    row = mc.run_encounter(enc, safety=False)
    assert "error" not in row and row["kind"] == "head_on"
    assert row["worst_separation_m"] < mc.RADIUS and row["interventions"] == 0 and row["filter_calls"] == 0
    sc = parse_scenario(enc.scenario_data(False))
    assert row["min_separation_m"] == InProcessFleet(sc).run().metrics.min_separation_m
    summary = mc.summarize([row, {**row, "worst_separation_m": 3.0}, {"preset": "ideal", "error": "boom"}])
    assert (summary["encounters"], summary["errors"], summary["violations"], summary["strictly_below_radius"]) == (
        3, 1, 1, 1)


@pytest.mark.parametrize("preset", mc.ALL_PRESETS)
def test_every_encounter_starts_with_every_pair_outside_one_and_a_half_radii(preset):
    for enc in mc.encounters(preset, 200, seed=1):  # the benchmark's default draw
        sc = parse_scenario(enc.scenario_data(True))
        starts = [(v.start_position or make_path(dict(v.path)).eval(v.omega0)[0])[:2] for v in sc.vehicles]
        assert all(math.dist(a, b) >= 1.5 * mc.RADIUS for i, a in enumerate(starts) for b in starts[i + 1:]), enc.index

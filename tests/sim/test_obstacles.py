"""configs/island_crossing.toml in process: every vehicle goes round its obstacle, keeps the margin
on every plant with the filter on, rejoins its path and the formation settles; with the filter off
it sails and flies through (so the test can fail)."""

import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet

CONFIG = "configs/island_crossing.toml"
BOATS, DRONES = ("usv_a", "usv_b"), ("uav_a", "uav_b")
DYNAMIC = {**{f"vehicle.{v}.plant": "usv_3dof" for v in BOATS}, **{f"vehicle.{v}.plant": "uav_double_integrator"
                                                                 for v in DRONES},
           **{f"vehicle.{v}.limits": {"preset": True} for v in BOATS + DRONES},
           "rates.physics": 100.0,  # half the config's rate: the test's cost (the margin held at 200 Hz too)
           "scenario.duration": 100.0}  # their detours take longer: settled at about 90 s, next lap's at 105 s


def run(overrides, result=False):
    out = InProcessFleet(load_scenario(CONFIG, overrides)).run()
    return out if result else out.metrics


def rejoined(recorder, tol):
    """Per vehicle: off its path by more than 0.5 m (the detour), then back within ``tol`` of it."""
    e = recorder.view("path_error")
    out = {}
    for j, vid in enumerate(recorder.ids):
        off = [n for n in range(len(e)) if e[n, j] > 0.5]
        out[vid] = bool(off) and min(e[off[0]:, j]) < tol
    return out


def test_ideal_plant_keeps_the_margin_goes_round_and_the_formation_settles():
    m = run({})
    ob = m.obstacles
    assert ob.count == 4 and ob.below_margin == ()
    for vid, row in ob.vehicles.items():
        assert row["min_clearance_m"] >= row["margin_m"] - 1e-6, vid
        assert row["deflected_s"] > 0.5, vid  # every path crosses an obstacle: each was deflected
    assert m.path_settle_s is not None and m.coord_settle_s is not None  # after the detour


def test_usv_3dof_and_double_integrator_keep_the_margin_and_rejoin():
    res = run(DYNAMIC, result=True)
    ob = res.metrics.obstacles
    assert ob.below_margin == ()
    assert all(row["min_clearance_m"] >= row["margin_m"] and row["deflected_s"] > 0.5
               for row in ob.vehicles.values())
    assert all(rejoined(res.recorder, 0.2).values())  # back on the path (a usv_3dof boat sails ~0.1 m off it)
    assert res.metrics.coord_settle_s is not None  # the formation settles after the detour


@pytest.mark.parametrize("overrides", [{}, DYNAMIC], ids=["ideal", "dynamic"])
def test_without_the_filter_every_vehicle_goes_through_its_obstacle(overrides):
    ob = run({**overrides, "safety.enabled": False, "scenario.duration": 80.0}).obstacles
    assert sorted(ob.below_margin) == sorted(BOATS + DRONES)
    assert ob.min_clearance_m < 0.0  # inside an obstacle
    assert all(row["deflected_s"] == 0.0 for row in ob.vehicles.values())


def test_the_obstacles_block_is_typed_and_round_trips():
    from cdus.sim.runmetrics import Metrics

    m = run({"scenario.duration": 2.0}).to_dict()
    typed = Metrics.from_dict(m)
    assert typed.obstacles.count == 4 and typed.to_dict() == m and list(typed.to_dict()) == list(m)
    m["obstacles"]["vehicles"]["usv_a"]["deflected_s"] = "long"
    assert str(Metrics.from_json(m)).startswith("obstacles.vehicles.usv_a.deflected_s: expected a number")


from hypothesis import given, settings, strategies as st  # noqa: E402

_junk = st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=5),
                     lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
                     max_leaves=8)
_BASE = {}


@settings(max_examples=200, deadline=None)
@given(key=st.sampled_from(["count", "min_clearance_m", "below_margin", "vehicles", "usv_a", "t", "obstacle"]),
       value=_junk)
def test_a_hostile_obstacles_block_is_rejected_by_name_never_raised(key, value):
    import copy

    from cdus.sim.runmetrics import Metrics
    from cdus.wire.rejected import Rejected

    if not _BASE:
        _BASE.update(run({"scenario.duration": 0.5}).to_dict())
    m = copy.deepcopy(_BASE)
    block = m["obstacles"]
    if key in ("usv_a",):
        block["vehicles"]["usv_a"] = value
    elif key in ("t", "obstacle"):
        block["vehicles"]["usv_a"][key] = value
    else:
        block[key] = value
    got = Metrics.from_json(m)
    assert isinstance(got, (Metrics, Rejected))
    if isinstance(got, Rejected):
        assert "obstacles" in str(got)
    else:
        assert got.to_dict() == m

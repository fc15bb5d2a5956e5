"""A vehicle on a plant whose preset has limits (usv_3dof, uav_double_integrator) given no limit
at all runs with unbounded actuators: accepted, and said once where the run starts
(cdus.sim.reports.limit_lines), never silent (a usv_3dof boat switched on with --set reached
870 m/s with no word)."""

import re
import subprocess
import sys

from cdus.scenario.config import load_scenario
from cdus.sim.reports import limit_lines


def test_the_shipped_scenarios_with_dynamic_plants_have_limits_and_no_note():
    for name in ("lake_circle", "lake_circle_dynamic", "lake_windy", "crossing_dynamic"):
        assert limit_lines(load_scenario(f"configs/{name}.toml")) == [], name


def test_a_plant_switched_on_without_limits_is_named_by_plant():
    one = limit_lines(load_scenario("configs/lake_circle.toml", {"vehicle.usv1.plant": "usv_3dof"}))
    assert len(one) == 1 and one[0].startswith("note: usv1 (usv_3dof) has no limits") and "preset = true" in one[0]
    both = limit_lines(load_scenario("configs/lake_circle.toml", {
        "vehicle.usv1.plant": "usv_3dof", "vehicle.usv2.plant": "usv_3dof",
        "vehicle.uav3.plant": "uav_double_integrator"}))
    assert [line.split(" no limits")[0] for line in both] == [
        "note: usv1, usv2 (usv_3dof) have", "note: uav3 (uav_double_integrator) has"]


def test_the_set_the_note_names_gives_the_presets_limits_and_silences_it():
    """A newcomer switches a plant on with --set: the note names the --set that fixes it (it named
    only a table to edit), and that --set, as printed, takes the preset's limits."""
    for plants in ({"vehicle.usv1.plant": "usv_3dof"},
                   {"vehicle.usv1.plant": "usv_3dof", "vehicle.uav2.plant": "uav_double_integrator",
                    "vehicle.uav3.plant": "uav_double_integrator"}):
        notes = limit_lines(load_scenario("configs/lake_circle.toml", plants))
        named = [re.search(r"--set (\S+)\)", n) for n in notes]
        assert notes and all(named), notes  # each note says the --set that fixes it
        sets = dict(m.group(1).split("=", 1) for m in named)
        sc = load_scenario("configs/lake_circle.toml", {**plants, **{k: _table(v) for k, v in sets.items()}})
        assert limit_lines(sc) == [], sets
        switched = {k.split(".")[1] for k in plants}
        preset = load_scenario("configs/lake_circle.toml", {**plants, **{
            f"vehicle.{vid}.limits": _table("{ preset = true }") for vid in switched}})
        assert [v.limits for v in sc.vehicles if v.id in switched] == [
            v.limits for v in preset.vehicles if v.id in switched], sets
        assert all(v.limits for v in sc.vehicles if v.id in switched)


def test_any_limit_given_is_a_choice_and_no_note():
    for limits in ("{ preset = true }", "{ speed = 2.0 }"):
        sc = load_scenario("configs/lake_circle.toml", {"vehicle.usv1.plant": "usv_3dof",
                                                        "vehicle.usv1.limits": _table(limits)})
        assert limit_lines(sc) == [], limits


def test_cdus_sim_says_it_where_the_run_starts(tmp_path):
    out = subprocess.run([sys.executable, "-m", "cdus", "sim", "configs/lake_circle.toml", "--duration", "0.2",
                          "--set", "vehicle.usv1.plant=usv_3dof", "--runs-dir", str(tmp_path / "runs"), "-q"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stderr.count("note: usv1 (usv_3dof) has no limits") == 1, out.stderr


def _table(text: str):
    from cdus.scenario.config import parse_value
    return parse_value(text)

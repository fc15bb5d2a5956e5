import pytest

from cdus.scenario.config import ConfigError
from ground_station.__main__ import nested
from ground_station.console import FleetView, status_table
from cdus.wire.messages import StateMsg
from cdus.wire.schemas import FleetEvent


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

"""A restarted vehicle rejoins once, as its new process does (vehicle_agent: Agent._rejoin), in
cdus sim too. The in-process fleet rejoined it from the last telemetry with ω near its
neighbours' consensus, then, the vehicle having been gone, a second time from its own ω as a
resumed one; the second projection can move ω by an ulp, and lockstep != cdus sim at the
restart tick (rev-radio: lake_circle, usv2 paused at 0 s, uav3 killed at 1.5 s and restarted at
2.5 s: uav3's ω at tick 125 differed by 4e-16)."""

from __future__ import annotations

from cdus.core.node import VehicleNode
from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet

EVENTS = """
[[event]]
at = 1.5
action = "kill"
vehicle = "uav3"

[[event]]
at = 2.5
action = "restart"
vehicle = "uav3"
"""


def test_a_restarted_vehicle_rejoins_once_near_its_neighbours_consensus(tmp_path, monkeypatch):
    cfg = tmp_path / "restart.toml"
    cfg.write_text(open("configs/lake_circle.toml").read() + EVENTS)
    calls = []
    real = VehicleNode.rejoin

    def spy(self, n, q, heading, omega_hint, neighbour_omegas=None):
        calls.append((self.index, n, neighbour_omegas))
        return real(self, n, q, heading, omega_hint, neighbour_omegas)

    monkeypatch.setattr(VehicleNode, "rejoin", spy)
    InProcessFleet(load_scenario(cfg, {"scenario.duration": 3.0})).run()
    j = 5  # uav3
    assert [(n, bool(omegas)) for i, n, omegas in calls if i == j] == [(125, True)]

"""A restarted vehicle rejoins once, in process as in a fleet of processes (rev-gs).

Found with a lockstep run of a scheduled phase change at t = 0, an offsets change at 1 s and a
kill/restart of usv2 at 1.5/2 s (tests/e2e/test_formation's scenario): the process fleet's
trace differed from `cdus sim`'s in the last bit of usv2's ω at its restart tick 40
(10.624946795149123 vs ...121), and every row after differed. The in-process fleet rejoined the
new node twice at that tick: its restart (at the last telemetry, near the neighbours'
consensus), then again as a vehicle 'resumed' (it had not been live), re-projecting ω from the
ω the first one chose; a restarted agent rejoins once."""

from __future__ import annotations

import math

import cdus.core.node as node_mod
from cdus.scenario.config import parse_scenario
from cdus.sim.fleet import InProcessFleet

BETA = 0.2
TABLE = {
    "scenario": {"name": "restart_once", "duration": 3.0},
    "rates": {"control": 20.0},
    "graph": {"topology": "ring"},
    "vehicle": [
        {"id": "usv1", "kind": "usv", "path": {"family": "circle", "center": [0, 0], "radius": 10, "speed": 2.0}},
        {"id": "usv2", "kind": "usv", "phase": 2 * math.pi / 3 / BETA,
         "path": {"family": "circle", "center": [0, 0], "radius": 10, "speed": 2.0}},
        {"id": "uav1", "kind": "uav", "phase": 4 * math.pi / 3 / BETA,
         "path": {"family": "circle", "center": [0, 0, 20], "radius": 10, "speed": 2.0}},
    ],
    "event": [
        {"at": 0.0, "action": "formation", "phases": {"usv2": math.pi / BETA}},
        {"at": 1.0, "action": "formation", "offsets": [{"i": "uav1", "k": "usv2", "delta": -3.5},
                                                       {"i": "usv2", "k": "usv1", "delta": 1e-9},
                                                       {"i": "usv1", "k": "uav1", "delta": 3.5 - 1e-9}]},
        {"at": 1.5, "action": "kill", "vehicle": "usv2"},
        {"at": 2.0, "action": "restart", "vehicle": "usv2"},
    ],
}


def test_a_restarted_vehicle_is_rejoined_once_at_its_restart_tick(monkeypatch):
    calls = []
    orig = node_mod.VehicleNode.rejoin

    def spy(self, n, q, heading, hint, omegas=None):
        calls.append((self.index, n, omegas))
        return orig(self, n, q, heading, hint, omegas)

    monkeypatch.setattr(node_mod.VehicleNode, "rejoin", spy)
    InProcessFleet(parse_scenario(TABLE, "test")).run()
    assert [(j, n) for j, n, _ in calls] == [(1, 40)], calls
    assert calls[0][2]  # near the neighbours' consensus, as an agent's rejoin

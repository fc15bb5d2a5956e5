"""A vehicle paused (or killed) by a scheduled fault at t = 0 never reports a row until it is
back: the lockstep world recorded nothing, its recorder waited for ever while the agents ran to
the end, and the run ended 'vehicles_lost' after 30 s with no trace (rev-radio, lake_circle with
a pause of usv2 at 0 s). It is recorded where it starts, as cdus sim records it."""

from __future__ import annotations

import numpy as np

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.wire import keys
from cdus.wire.messages import encode_control
from tests.fakes import Payload, Sample

from .test_world import FLEET, row, send_rows, started, world

EVENTS = """
[[event]]
at = 0.0
action = "pause"
vehicle = "usv2"

[[event]]
at = 1.0
action = "resume"
vehicle = "usv2"
"""


def test_a_vehicle_paused_from_tick_0_is_recorded_where_it_starts(tmp_path):
    w = started(world(tmp_path, events=EVENTS))
    w._handle(Sample(keys.world_cmd(FLEET, keys.LAUNCHER), Payload(encode_control("fault_done", vehicle="usv2"))))
    w._act(w.lockstep.poll())
    g = w.lockstep.granted
    assert g >= 10
    for j, vid in enumerate(w.ids):
        if vid != "usv2":
            send_rows(w, vid, [row(j, n) for n in range(g + 1)])
    w._record_complete()
    assert w.next_tick == g + 1
    ref = InProcessFleet(load_scenario(tmp_path / "ev.toml", {"scenario.duration": 3.0})).run()
    j = w.ids.index("usv2")
    for name in ("q", "omega", "heading", "path_error", "omega_rate"):
        got, want = w.recorder.view(name)[: g + 1, j], ref.recorder.view(name)[: g + 1, j]
        assert np.array_equal(got, want, equal_nan=True), name
    assert not w.recorder.view("live")[: g + 1, j].any()

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
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("fault_done", vehicle="usv2"))
    w.clock.act(w.lockstep.poll())
    g = w.lockstep.granted
    assert g >= 10
    for j, vid in enumerate(w.ids):
        if vid != "usv2":
            send_rows(w, vid, [row(j, n) for n in range(g + 1)])
    w.clock.record_complete()
    assert w.next_tick == g + 1
    ref = InProcessFleet(load_scenario(tmp_path / "ev.toml", {"scenario.duration": 3.0})).run()
    j = w.ids.index("usv2")
    for name in ("q", "omega", "heading", "path_error", "omega_rate"):
        got, want = w.recorder.view(name)[: g + 1, j], ref.recorder.view(name)[: g + 1, j]
        assert np.array_equal(got, want, equal_nan=True), name
    assert not w.recorder.view("live")[: g + 1, j].any()


def test_realtime_a_vehicle_paused_from_the_start_does_not_hold_the_recording_for_ever():
    """Realtime, the same pause at t = 0: the world recorded nothing for the whole run (the
    agents were done at 4 s; it went on until the launcher was interrupted at 117 s). A vehicle
    not heard from yet still holds tick n back, unless a fault stopped it or it has reported a
    later tick (its rows come in order: it never will report n)."""
    w = world(clock="realtime")
    j = w.ids.index("usv2")
    for k, vid in enumerate(w.ids):
        if vid != "usv2":
            send_rows(w, vid, [row(k, n) for n in range(40)])
    assert not w._record(0)  # usv2 not heard from yet: waited for, as before
    w._faulted["usv2"] = "paused"
    assert w._record(0) and w._recorded[j] == w._initial_row(j)
    del w._faulted["usv2"]  # resumed: from its first row on, its own rows
    send_rows(w, "usv2", [row(j, n) for n in range(20, 40)])
    for n in range(1, 40):
        assert w._record(n)
    assert w.next_tick == 40 and w._recorded[j].tick == 39

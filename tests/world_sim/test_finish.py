"""world_sim.finish: what the run leaves behind: each tick's record, the metrics' counters summed
over every process, and the trace (or why not). No network (tests/world_sim/test_world.py's fakes)."""

from __future__ import annotations

import errno
import json

from cdus.sim.runmetrics import RejectedByReason
from cdus.wire import keys

from .test_world import FLEET, row, send_rows, started, stats_payload, world


def test_a_tick_is_recorded_with_each_vehicles_own_row_and_one_that_did_not_step_repeats_its_last():
    w = started(world())
    for j, vid in enumerate(w.ids):
        send_rows(w, vid, [row(j, 0)])
    assert w._record(0) and w.next_tick == 1 and len(w.recorder) == 1
    for j, vid in enumerate(w.ids[:-1]):  # the last vehicle does not step tick 1
        send_rows(w, vid, [row(j, 1)])
    assert w._record(1) and len(w.recorder) == 2
    last = len(w.ids) - 1
    assert w._recorded[last] == row(last, 0) and w._recorded[0] == row(0, 1)


def test_a_tick_is_not_recorded_while_a_vehicle_never_reported():
    w = started(world())
    for j, vid in enumerate(w.ids[1:], start=1):
        send_rows(w, vid, [row(j, 0)])
    assert not w._record(0) and len(w.recorder) == 0 and w.next_tick == 0


def test_the_drops_are_said_by_reason_for_the_world_and_summed_over_the_vehicles():
    w = started(world())
    send_rows(w, "stranger", [row(0, 0)])
    w.feed(keys.stats(FLEET, "usv1"), stats_payload(id="usv1", tick=3, rejected_by_reason={"stale": 2}))
    w.feed(keys.stats(FLEET, "usv2"), stats_payload(id="usv2", tick=3, rejected_by_reason={"stale": 1, "future": 4}))
    assert w.rejects_by_reason() == RejectedByReason(world={"unknown_sender": 1}, vehicles={"future": 4, "stale": 3})


def test_the_link_block_sums_every_processs_counters(tmp_path):
    w = started(world())
    w.feed(keys.stats(FLEET, "usv1"), stats_payload(id="usv1", tick=3, sent_to_me=10, delivered=8, dropped=2))
    w.feed(keys.stats(FLEET, "usv2"), stats_payload(id="usv2", tick=3, sent_to_me=5, delivered=5, dropped=0))
    b = w.link_metrics()
    assert (b.sent, b.delivered, b.dropped) == (15, 13, 2)


def test_a_trace_that_cannot_be_written_is_said_removed_and_the_metrics_are_kept(tmp_path):
    out, trace = tmp_path / "m.json", tmp_path / "t.npz"
    lines: list[str] = []
    w = started(world(metrics_out=str(out), trace_out=str(trace)))
    w.log = lines.append
    w.session = None
    for j, vid in enumerate(w.ids):
        send_rows(w, vid, [row(j, 0)])
    w._record(0)

    def full_disk(path):
        open(path, "wb").write(b"half a trace")
        raise OSError(errno.ENOSPC, "No space left on device")

    w.recorder.save_trace = full_disk
    m = w.finish()
    assert json.loads(out.read_text()) == m.to_dict()
    assert w.not_written == ["the trace"] and not trace.exists()  # no half a trace that looks like one
    assert f"error: could not write the trace to {trace}: No space left on device" in lines, lines

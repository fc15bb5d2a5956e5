"""world_sim.finish: what the run leaves behind: each tick's record, the metrics' counters summed
over every process, and the trace (or why not). No network (tests/world_sim/test_world.py's fakes)."""

from __future__ import annotations

import errno
import json

import pytest
from hypothesis import given, settings, strategies as hs

from cdus.sim.runmetrics import RejectedByReason
from cdus.wire import keys
from tests.fakes import Payload, Sample

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


class _Agents:
    """The inbox of a world whose vehicles answer its stop with their last report (final), each
    with ``sent_to_me`` 100 + its index; those in ``silent`` (frozen, cut off) send one report
    more that is not their last, with ``sent_to_me`` 50."""

    def __init__(self, w, silent=()):
        from cdus.wire.messages import CTL_OPS, decode_control
        self.w, self.silent, self.queue, self.decode = w, set(silent), [], lambda p: decode_control(p, CTL_OPS)

    def try_recv(self):
        ops = [self.decode(p).op for p in self.w.pub_ctl.puts]
        if "stop" in ops and not self.queue and not getattr(self, "_said", False):
            self._said = True
            from tests.fakes import Payload, Sample
            for j, vid in enumerate(self.w.ids):
                last = vid not in self.silent
                self.queue.append(Sample(keys.stats(FLEET, vid), Payload(stats_payload(
                    id=vid, tick=50, sent_to_me=100 + j if last else 50, final=last))))
        return self.queue.pop(0) if self.queue else None


def _finish_on_a_fake_clock(w, monkeypatch):
    """``w.finish()`` on a clock that advances 0.01 s at each sleep; returns (metrics, sleeps)."""
    import world_sim.finish as finish
    now = [0.0]
    sleeps = []
    monkeypatch.setattr(finish.time, "monotonic", lambda: now[0])
    monkeypatch.setattr(finish.time, "sleep", lambda s: (sleeps.append(s), now.__setitem__(0, now[0] + 0.01)))
    return w.finish(), sleeps


def test_the_world_ends_its_wait_when_every_vehicle_up_sent_its_last_report(monkeypatch):
    """The stop's wait for the agents' last counters ends as soon as each vehicle up said its
    last report (AgentStats.final; it was a fixed third of a second of every run), and the
    metrics hold those reports' counters."""
    from world_sim.limits import FINAL_WAIT_S
    w = started(world())
    w.inbox = _Agents(w)
    w.feed(keys.stats(FLEET, "usv1"), stats_payload(id="usv1", tick=10, final=True))  # before the stop: not its last
    m, sleeps = _finish_on_a_fake_clock(w, monkeypatch)
    assert len(sleeps) <= 1 < FINAL_WAIT_S / 0.01
    assert m.link.sent == sum(100 + j for j in range(len(w.ids)))


def test_a_vehicle_that_sends_no_last_report_after_the_stop_is_waited_for_the_whole_wait_and_no_longer(monkeypatch):
    """usv1 said a report marked final before the stop (a forgery, or an old process's) and, after
    the stop, one not marked final and nothing more, as a vehicle frozen then would: the world
    waits FINAL_WAIT_S, then goes on with what it has."""
    from world_sim.limits import FINAL_WAIT_S
    w = started(world())
    w.inbox = _Agents(w, silent={"usv1"})
    w.feed(keys.stats(FLEET, "usv1"), stats_payload(id="usv1", tick=10, final=True))
    m, sleeps = _finish_on_a_fake_clock(w, monkeypatch)
    assert abs(len(sleeps) * 0.01 - FINAL_WAIT_S) < 0.015
    assert m.link.sent == 50 + sum(100 + j for j, v in enumerate(w.ids) if v != "usv1")



class _After:
    """An inbox that holds ``samples`` until the world said stop, then gives them in order."""

    def __init__(self, w, samples):
        from cdus.wire.messages import CTL_OPS, decode_control
        self.w, self.samples, self.decode = w, list(samples), lambda p: decode_control(p, CTL_OPS)

    def try_recv(self):
        stopped = any(self.decode(p).op == "stop" for p in self.w.pub_ctl.puts)
        return self.samples.pop(0) if stopped and self.samples else None


_FINALS = [True, False, 1, 0, "true", None, 1.0, {"a": 1}, [True]]


@settings(max_examples=150, deadline=None)
@given(hs.data())
def test_the_wait_ends_early_exactly_when_every_vehicle_up_sent_an_accepted_final_after_the_stop(data):
    """Whatever reports come, before and after the stop, with any ``final`` value (a forger's
    non-bool, a bool) and the process's incarnation or another's (a forgery while its token is
    up): the wait ends before FINAL_WAIT_S only if every vehicle up sent, after the stop, a report
    the world took that is marked final (one before the stop does not count); the rest are
    counted by reason, and the metrics hold each vehicle's last report taken."""
    from world_sim.limits import FINAL_WAIT_S
    w = started(world())
    post = []  # (vid, final, incarnation, sent_to_me)
    quiet = data.draw(hs.sampled_from([None, *w.ids]))  # the others also send their genuine last report
    for j, vid in enumerate(w.ids):
        w.feed(keys.stats(FLEET, vid), stats_payload(id=vid, tick=10, final=data.draw(hs.booleans()), sent_to_me=1))
        drawn = data.draw(hs.lists(hs.tuples(hs.sampled_from(_FINALS), hs.sampled_from([0, 7])), max_size=3))
        drawn += [] if vid == quiet else [(True, 0)]
        post += [(vid, final, inc, 100 * (j + 1) + k) for k, (final, inc) in enumerate(drawn)]
    post = data.draw(hs.permutations(post))
    taken = [(vid, final, n) for vid, final, inc, n in post if type(final) is bool and inc == 0]
    last = {vid: n for vid, _, n in taken}
    finals = {vid for vid, final, _ in taken if final}
    w.inbox = _After(w, [Sample(keys.stats(FLEET, vid), Payload(stats_payload(
        id=vid, tick=11, final=final, incarnation=inc, sent_to_me=n))) for vid, final, inc, n in post])
    with pytest.MonkeyPatch.context() as mp:
        m, sleeps = _finish_on_a_fake_clock(w, mp)
    if finals == set(w.ids):
        assert len(sleeps) <= 1, len(sleeps)
    else:
        assert abs(len(sleeps) * 0.01 - FINAL_WAIT_S) < 0.015, (finals, len(sleeps))
    assert w.st.rejects["type"] == sum(type(f) is not bool for _, f, _, _ in post), w.st.rejects
    assert w.st.rejects["incarnation"] == sum(type(f) is bool and inc != 0 for _, f, inc, _ in post), w.st.rejects
    assert m.link.sent == sum(last.get(vid, 1) for vid in w.ids)


class _Flood:
    """An inbox a flood never lets empty: a malformed stats report for usv1 at each call, each
    taking 1 ms of the fake clock ``now``; after ``cap`` of them it gives up (so that a world that
    would drain it for ever fails the test instead of hanging it)."""

    def __init__(self, now, cap=5000):
        self.now, self.n, self.cap = now, 0, cap

    def try_recv(self):
        self.n += 1
        if self.n > self.cap:
            raise AssertionError(f"the world was still draining the flood after {self.cap} messages")
        self.now[0] += 0.001
        return Sample(keys.stats(FLEET, "usv1"), Payload(stats_payload(id="usv1", final="yes")))


def test_a_flood_that_never_lets_the_inbox_empty_does_not_hold_the_end_of_the_run_past_its_wait(monkeypatch):
    """An outsider on an open fleet floods the world's stats keys through its stop: the world
    drained its inbox until it was empty, within and after the wait for the last reports, so a
    flood faster than the world reads held the metrics (and the run's end) as long as it lasted.
    Now it takes no more than the wait allows, counts what it took, and writes the metrics."""
    import world_sim.finish as finish
    from world_sim.limits import FINAL_WAIT_S
    now = [0.0]
    monkeypatch.setattr(finish.time, "monotonic", lambda: now[0])
    monkeypatch.setattr(finish.time, "sleep", lambda s: now.__setitem__(0, now[0] + s))
    w = started(world())
    w.inbox = _Flood(now)
    m = w.finish()
    assert now[0] <= FINAL_WAIT_S + 0.02 and w.inbox.n > 0
    assert w.st.rejects["type"] == w.inbox.n == m.link.rejected, (w.st.rejects, w.inbox.n)

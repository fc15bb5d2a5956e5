"""The world process's shell logic without a network: publishers and a session that record
what the world sends, samples handed to it as its inbox would."""

from __future__ import annotations

import json

from cdus.core.events import RosterChange
from cdus.scenario.config import load_scenario
from cdus.sim.lockstep import CatchUp, Grant, Join, Roster
from cdus.sim.runmetrics import RejectedByReason
from cdus.wire import keys
from cdus.wire.messages import (
    CTL_OPS, LAUNCHER_OPS, StateMsg, decode_control, encode_control, encode_states,
)
from cdus.wire.schemas import AgentStats, FleetEvent, decode_event, encode_stats
from cdus.wire.transport import Transport
from tests.fakes import Payload, Sample
from world_sim.clocks import RealtimeClock
from world_sim.world import World

FLEET = "tfake"
EVENTS = """
[[event]]
at = 1.0
action = "kill"
vehicle = "usv2"

[[event]]
at = 2.0
action = "pause"
vehicle = "uav1"
"""


class Pub:
    def __init__(self) -> None:
        self.puts: list[bytes] = []

    def put(self, payload) -> None:
        self.puts.append(bytes(payload))


class Session:
    def __init__(self) -> None:
        self.puts: list[tuple[str, bytes]] = []

    def put(self, key, payload, **kw) -> None:
        self.puts.append((key, bytes(payload)))


def world(tmp_path=None, clock: str = "lockstep", events: str = "", **kw) -> World:
    path = "configs/lake_circle.toml"
    if events and tmp_path is not None:
        cfg = tmp_path / "ev.toml"
        cfg.write_text(open(path).read() + events)
        path = str(cfg)
    w = World(load_scenario(path), FLEET, Transport(), clock=clock, log=lambda s: None, **kw)
    w.session = Session()
    w.pub_ctl, w.pub_launcher, w.pub_status, w.pub_events = Pub(), Pub(), Pub(), Pub()
    w._wake = lambda payload=b"": None
    return w


def ctl_ops(w: World) -> list:
    return [decode_control(p, CTL_OPS) for p in w.pub_ctl.puts]


def row(j: int, n: int, T: float = 0.02) -> StateMsg:
    return StateMsg(j, n, n * T, (0.0, 0.0) if j < 3 else (0.0, 0.0, 20.0), 0.0, 1.0, -n * T, -1.0, 0.5)


def started(w: World) -> World:
    """Every vehicle up, the lockstep run started and its first grant out."""
    for vid in w.ids:
        w.alive(vid, True)
    w.started = True
    w.lockstep.start()
    w.clock.act(w.lockstep.poll())
    return w


def send_rows(w: World, vid: str, rows: list[StateMsg]) -> None:
    w.feed(keys.state(FLEET, vid), encode_states(rows))


def test_telemetry_reports_ticks_and_a_complete_tick_is_recorded():
    w = started(world())
    for j, vid in enumerate(w.ids):
        w.feed(keys.state(FLEET, vid), encode_states([row(j, 0), row(j, 1)]))
        if j < 5:
            assert not w.lockstep.recordable(0)
    assert w.lockstep.acked == {j: 1 for j in range(6)}
    w.clock.record_complete()
    assert w.next_tick == 2 and len(w.recorder) == 2


def test_telemetry_from_the_wrong_key_or_malformed_is_rejected():
    w = world()
    w.feed(keys.state(FLEET, "usv2"), encode_states([row(0, 0)]))  # usv1's rows on usv2's key
    w.feed(keys.state(FLEET, "usv1"), b"\x00")
    w.feed(keys.stats(FLEET, "usv1"), encode_stats(AgentStats(id="usv3", tick=1)))
    w.feed(f"cdus/{FLEET}/to/+world+/telepathy/usv1", b"")
    assert w.st.rejected == 4 and w.lockstep.acked == {}
    assert w.st.rejects == {"sender_mismatch": 2, "malformed": 1, "key": 1}


def test_stats_feed_the_link_block_and_bursts_become_events():
    w = world()
    burst = FleetEvent.of(3.0, "link_burst", "link usv2->usv1: 12 messages dropped in a row (2.70-3.00 s)",
                          link="usv2->usv1").as_dict()
    s = AgentStats(id="usv1", tick=100, sent_to_me=200, delivered=190, dropped=10, rejected=2,
                   latencies_ms=(1.0, 3.0), missed_deadlines=1, bursts=(burst,))
    w.feed(keys.stats(FLEET, "usv1"), encode_stats(s))
    block = w.link_metrics()
    assert (block.sent, block.delivered, block.dropped, block.rejected) == (200, 190, 10, 2)
    assert block.missed_deadlines == 1 and block.latency_ms_p50 == 2.0
    assert [(e.kind, e.link, e.origin) for e in w.events] == [("link_burst", "usv2->usv1", "usv1")]
    assert decode_event(w.pub_events.puts[-1]).kind == "link_burst"


def test_every_stats_messages_latencies_count_and_a_restarted_process_adds_to_the_last_ones():
    """Each stats message carries the latency samples since the previous one; a restart's new
    process starts its counters at zero: the run's totals are the sum over processes."""
    w = world()
    send = lambda s: w.feed(keys.stats(FLEET, s.id), encode_stats(s))  # noqa: E731
    send(AgentStats(id="usv1", tick=50, sent_to_me=100, delivered=100, latencies_ms=(1.0, 1.0), interventions=2))
    send(AgentStats(id="usv1", tick=100, sent_to_me=200, delivered=200, latencies_ms=(5.0, 5.0, 5.0),
                    interventions=3))
    w.alive("usv1", False)  # the old process's token goes: the next incarnation is a restart
    send(AgentStats(id="usv1", tick=150, sent_to_me=20, delivered=20, joined_at=120, latencies_ms=(), interventions=1,
                    incarnation=7))
    block = w.link_metrics()
    assert (block.sent, block.delivered) == (220, 220)
    assert block.latency_ms_p50 == 5.0 and block.latency_ms_p99 == 5.0
    assert sorted(w.st.latencies.latencies) == [0.001, 0.001, 0.005, 0.005, 0.005]
    assert block.faults is None  # lake_circle's link is ideal and nobody changed it
    w.session = None  # nothing left to hear
    assert w.finish().interventions == 4


def test_stats_with_ever_new_incarnations_are_a_restart_only_after_the_token_went():
    """Before, each new incarnation retired the last stats and was added to the run's counters:
    143,677 stats in 5 s from usv1's own credentials (secured realtime lake_circle), each with
    a new incarnation, made link.sent 22,664,085 (7,186 without) in metrics that said completed,
    and the retired list grew by one a message. A new process is believed only once the old
    one's liveliness token went (the world hears that from the router, nobody can forge it)."""
    w = world()
    send = lambda s: w.feed(keys.stats(FLEET, s.id), encode_stats(s))  # noqa: E731
    send(AgentStats(id="usv1", tick=50, sent_to_me=100, delivered=100, incarnation=1))
    for n in range(2, 200):  # forged: the genuine process never went away
        send(AgentStats(id="usv1", tick=50, sent_to_me=1000, delivered=1000, incarnation=n))
    assert w.link_metrics().sent == 100 and w.st.retired == [] and w.st.rejects["incarnation"] == 198
    send(AgentStats(id="usv1", tick=60, sent_to_me=120, delivered=120, incarnation=1))  # the genuine one goes on
    w.alive("usv1", False)  # killed; then restarted
    send(AgentStats(id="usv1", tick=90, sent_to_me=30, delivered=30, incarnation=77))
    send(AgentStats(id="usv1", tick=90, sent_to_me=9999, delivered=9999, incarnation=78))  # one restart, one new process
    assert w.link_metrics().sent == 150 and len(w.st.retired) == 1


def test_a_ground_stations_kill_waits_for_its_tick_in_lockstep_and_goes_straight_to_the_launcher_in_realtime():
    w = world()
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("kill", vehicle="usv3"))
    assert w.pub_launcher.puts == [] and w.lockstep._queue[0].vehicle == 2
    rt = world(clock="realtime")
    rt.feed(keys.world_cmd(FLEET, "gs1"), encode_control("kill", vehicle="usv3"))
    c = decode_control(rt.pub_launcher.puts[0], LAUNCHER_OPS)
    assert (c.op, c.fields["vehicle"]) == ("kill", "usv3")
    assert [(e.kind, e.vehicle) for e in rt.events] == [("fault", "usv3")]


def test_commands_are_relayed_with_the_tick_or_time_they_apply_from():
    w = world()
    w.lockstep.granted = 40
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("set_gains", gains={"c": 3.0}, vehicle=""))
    key, payload = w.session.puts[-1]
    assert key == keys.ctl(FLEET, w.ids)
    c = decode_control(payload, CTL_OPS)
    assert c.op == "gains" and c.fields["tick"] == 41
    w.next_tick = 101
    # no --at: from the effect tick, the first nobody was granted, as gains (it was 0.5 s after the
    # newest tick recorded, 100 * period + 0.5, in lockstep only)
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("link", link={"loss": 0.1}, at=-1.0))
    c = ctl_ops(w)[-1]
    assert c.op == "link" and c.fields["at"] == 41 * w.period
    assert [e.kind for e in w.events] == ["gains_changed", "link_changed"]
    # a time in the past applies from the first tick nobody has been granted: every receiver alike
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("link", link={"loss": 0.2}, at=0.1))
    assert ctl_ops(w)[-1].fields["at"] == 41 * w.period
    assert "from t = 0.82 s by gs1" in w.events[-1].text
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("pause"))
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("pause"))  # already: not news
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("stop"))
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("resume"))  # after the stop: refused
    assert [e.text for e in w.events[-2:]] == ["fleet paused by gs1", "fleet stopped by gs1"]
    assert w.lockstep.paused


def test_a_rejoining_process_is_sent_the_link_and_gains_commands_it_missed():
    """A restarted process starts from the scenario file; a resumed one missed what was sent
    while its session was closed. The world sends it every run-time command again, in order."""
    w = world()
    w.lockstep.granted = 40
    cmd = lambda op, **f: w.feed(keys.world_cmd(FLEET, "gs1"), encode_control(op, **f))  # noqa: E731
    cmd("link", link={"loss": 0.3}, at=-1.0)
    cmd("set_gains", gains={"c": 3.0}, vehicle="uav1")
    cmd("set_gains", gains={"k": 2.0}, vehicle="")
    cmd("link", link={"delay": {"base": 0.1}}, at=-1.0)
    before = len(w.session.puts)
    w.clock.act([CatchUp(w.ids.index("usv2"))])
    sent = w.session.puts[before:]
    assert {key for key, _ in sent} == {keys.ctl(FLEET, ["usv2"])}
    ops = [decode_control(p, CTL_OPS) for _, p in sent]
    assert [(c.op, c.fields.get("link") or c.fields.get("gains")) for c in ops] == [
        ("link", {"loss": 0.3}), ("gains", {"k": 2.0}), ("link", {"delay": {"base": 0.1}})]  # not uav1's gains
    w.clock, w.started = RealtimeClock(w), True
    w.clock.t0, w.clock.paused_at = 0.0, 2.0
    before = len(w.session.puts)
    w.alive("uav1", True)  # realtime: a (re)started process's token
    replayed = [decode_control(p, CTL_OPS) for key, p in w.session.puts[before:] if key == keys.ctl(FLEET, ["uav1"])]
    # both gains changes apply at tick 41, before the first uav1 can step: it applies them together,
    # the later last, so the later alone is sent (it would fill c from the scenario's either way)
    assert [(c.op, c.fields.get("gains")) for c in replayed] == [
        ("link", None), ("gains", {"k": 2.0}), ("link", None)]


def test_a_gains_command_that_does_not_fit_every_target_is_refused_whole():
    """k = [1, 2] for every vehicle is refused whole (the gains rule, cdus.commands.gains: one
    value per axis needs one vehicle named); for a boat it is taken."""
    w = world()
    before = len(w.session.puts)
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("set_gains", gains={"k": [1.0, 2.0]},
                                                                           vehicle=""))
    assert len(w.session.puts) == before and w.st.rejected == 1
    assert [(e.kind, e.severity) for e in w.events] == [("rejected", "warn")]
    assert "k: one value per axis needs one vehicle named" in w.events[0].text
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("set_gains", gains={"k": [1.0, 2.0]},
                                                                           vehicle="usv1"))
    assert w.session.puts[-1][0] == keys.ctl(FLEET, ["usv1"]) and w.events[-1].kind == "gains_changed"


def test_bad_commands_are_counted_not_raised():
    w = world()
    for payload in (b"\xc1", encode_control("explode"), encode_control("kill", vehicle="nobody"),
                    encode_control("set_gains", gains={"c": 1.0}, vehicle="nobody")):
        w.feed(keys.world_cmd(FLEET, "gs1"), payload)
    assert w.st.rejected == 4 and w.session.puts == [] and w.pub_launcher.puts == []


def test_a_fleet_pause_in_lockstep_holds_the_grants():
    w = world()
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("pause"))
    assert w.lockstep.paused and w.events[-1].kind == "fleet"
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("resume"))
    assert not w.lockstep.paused


def test_lockstep_actions_go_out_on_their_keys():
    w = world()
    w.clock.act([Roster(RosterChange(5, 1, "gone")), Roster(RosterChange(5, 0, "live"), to=2), Grant(9), Join(3, 0)])
    (k1, p1), (k2, p2), (k3, p3) = w.session.puts
    assert k1 == keys.ctl(FLEET, w.ids) and decode_control(p1, CTL_OPS).fields == {
        "vehicle": "usv2", "tick": 5, "state": "gone", "fresh": False}
    assert k2 == keys.ctl(FLEET, ["usv3"]) and decode_control(p2, CTL_OPS).fields["vehicle"] == "usv1"
    assert k3 == keys.ctl(FLEET, ["uav1"]) and decode_control(p3, CTL_OPS).op == "join"
    assert [(c.op, c.fields) for c in ctl_ops(w)] == [("grant", {"until": 9})]


def test_realtime_liveliness_changes_become_roster_changes_and_events():
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    w.started = True
    w.clock.t0 = 0.0
    w.clock.paused_at = 2.0  # a fixed "now": tick 100
    w.alive("usv2", False)
    key, payload = w.session.puts[-1]
    assert decode_control(payload, CTL_OPS).fields == {"vehicle": "usv2", "tick": 100, "state": "gone",
                                                       "fresh": False}
    assert [(e.kind, e.vehicle) for e in w.events][:1] == [("vehicle_lost", "usv2")]
    assert w.events[-1].kind == "graph"
    w.alive("usv2", True)
    assert decode_control(w.session.puts[-1][1], CTL_OPS).fields["fresh"] is True
    assert ("vehicle_back", "usv2") in [(e.kind, e.vehicle) for e in w.events]


def test_realtime_a_fault_we_asked_for_is_not_reported_again_as_a_lost_vehicle():
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    w.started, w.clock.t0, w.clock.paused_at = True, 0.0, 2.0
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("kill", vehicle="usv2"))
    w.alive("usv2", False)
    w.alive("uav1", False)  # nobody asked for that one
    kinds = [(e.kind, e.vehicle) for e in w.events if e.kind != "graph"]
    assert kinds == [("fault", "usv2"), ("vehicle_lost", "uav1")]


def test_realtime_scheduled_faults_go_to_the_launcher_when_their_time_comes(tmp_path):
    w = world(tmp_path, clock="realtime", events=EVENTS)
    w.clock.scheduled_faults(0.98)
    assert w.pub_launcher.puts == []
    w.clock.scheduled_faults(1.0)
    w.clock.scheduled_faults(1.5)
    assert [decode_control(p, LAUNCHER_OPS).op for p in w.pub_launcher.puts] == ["kill"]
    w.clock.scheduled_faults(10.0)
    ops = [decode_control(p, LAUNCHER_OPS) for p in w.pub_launcher.puts]
    assert [(c.op, c.fields["vehicle"]) for c in ops] == [("kill", "usv2"), ("pause_vehicle", "uav1")]
    assert [(e.kind, e.vehicle) for e in w.events] == [("fault", "usv2"), ("fault", "uav1")]


def test_an_empty_run_still_writes_its_metrics(tmp_path):
    out = tmp_path / "metrics.json"
    w = world(metrics_out=str(out))
    w.session = None
    m = w.finish()
    assert json.loads(out.read_text()) == m.to_dict()
    assert m.completed is False and m.path_settle_s is None and m.events == ()
    assert m.mode == "lockstep" and m.link.sent == 0


def test_the_launchers_acknowledgement_reaches_the_lockstep_decisions():
    w = world()
    for j in range(6):
        w.lockstep.on_alive(j, True)
    w.lockstep.start()
    w.clock.act(w.lockstep.poll())  # joins and the first grant
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("kill", vehicle="usv2"))
    for j in range(6):
        for n in range(w.lockstep.granted + 1):
            w.lockstep.on_report(j, n)
    w.clock.act(w.lockstep.poll())
    c = decode_control(w.pub_launcher.puts[-1], LAUNCHER_OPS)
    assert (c.op, c.fields["vehicle"]) == ("kill", "usv2")
    assert w.lockstep._current.stage == "asked"
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("fault_done", vehicle="usv2"))
    assert w.lockstep._current.stage == "done"


# ---------------------------------------------------------------------- hostile input, honest completion

import math  # noqa: E402

import msgpack  # noqa: E402
from hypothesis import given, settings, strategies as hs  # noqa: E402

from cdus.wire.schemas import SCHEMA_VERSION  # noqa: E402


def test_telemetry_for_ticks_not_granted_is_rejected_and_never_recorded():
    """Six forged rows at tick 6000 (|Φ| = 0) ended a run at once with completed true."""
    w = started(world())
    granted = w.lockstep.granted
    for j, vid in enumerate(w.ids):
        forged = StateMsg(j, 6000, 120.0, (0.0, 0.0) if j < 3 else (0.0, 0.0, 20.0), 0.0, 1.0, 0.0, -1.0, 0.0)
        send_rows(w, vid, [forged])
    assert w.st.rejects == {"future": 6} and w.lockstep.acked == {} and w.st.latest == {}
    w.clock.record_complete()
    assert len(w.recorder) == 0
    for j, vid in enumerate(w.ids):  # the genuine rows still count
        for first in range(0, granted + 1, 50):  # in batches (at most MAX_STATE_ROWS a message)
            send_rows(w, vid, [row(j, n) for n in range(first, min(first + 50, granted + 1))])
    w.clock.record_complete()
    assert w.next_tick == granted + 1 and (w.recorder.view("path_error") == 0.5).all()


def test_realtime_telemetry_beyond_the_clock_and_its_slack_is_rejected():
    w = world(clock="realtime")
    w.clock.t0 = 1e12  # not started: the clock's tick is 0
    send_rows(w, "usv1", [row(0, 0), row(0, 5)])
    send_rows(w, "usv2", [row(1, 10_000)])
    assert w.st.rejects == {"future": 1} and w.lockstep.acked == {0: 5}


def test_a_second_different_row_for_a_tick_does_not_replace_the_first():
    w = started(world())
    send_rows(w, "usv1", [row(0, 0)])
    send_rows(w, "usv1", [StateMsg(0, 0, 0.0, (9.0, 9.0), 0.0, 1.0, 0.0, -1.0, 0.0)])
    assert w.st.rows[0][0] == row(0, 0) and w.st.rejects == {"conflict": 1}


def stats_payload(**over) -> bytes:
    d = {"v": SCHEMA_VERSION, **AgentStats(id="usv1", tick=10).as_dict(), **over}
    return msgpack.packb(d, use_bin_type=True)


def test_malformed_nested_stats_are_counted_by_reason_not_raised():
    w = world()
    for bad, reason in [({"bursts": [{"t": "x"}]}, "bursts"), ({"faults": {"state_changes": 5}}, "faults"),
                        ({"id": "usv2"}, "sender_mismatch"), ({"latencies_ms": [-1.0]}, "latencies")]:
        w.feed(keys.stats(FLEET, "usv1"), stats_payload(**bad))
        assert w.st.rejects[reason] == 1, reason
    assert w.st.stats == {} and w.events == []


def test_a_forged_deflected_counter_is_counted_by_reason_and_leaves_the_genuine_stats():
    """A hostile ``deflected`` on a vehicle's stats key (negative, float, text, above its
    interventions, or under another vehicle's id): each dropped by reason, the genuine report kept."""
    w = world()
    w.feed(keys.stats(FLEET, "usv1"), stats_payload(interventions=5, deflected=2))
    for bad, reason in [({"deflected": -1}, "type"), ({"deflected": 2.0}, "type"), ({"deflected": "9"}, "type"),
                        ({"deflected": 2**53}, "range"), ({"deflected": 6, "interventions": 5}, "deflected"),
                        ({"deflected": 10**6}, "deflected"), ({"id": "usv2", "interventions": 9, "deflected": 9}, "sender_mismatch")]:
        w.feed(keys.stats(FLEET, "usv1"), stats_payload(**bad))
        assert w.st.rejects[reason] >= 1, reason
    assert sum(w.st.rejects.values()) == 7
    assert (w.st.stats["usv1"].interventions, w.st.stats["usv1"].deflected) == (5, 2)


def test_new_suspect_counts_in_a_vehicles_stats_make_one_event_per_vehicle_and_reason_for_a_while():
    w = world()
    for n, future in enumerate([0, 3, 5, 9]):
        w.feed(keys.stats(FLEET, "usv2"), stats_payload(
            id="usv2", tick=n, rejected_by_reason={"future": future, "stale": 7, "conflict": n // 3}))
    got = [(e.kind, e.vehicle, e.origin, e.severity) for e in w.events]
    assert got == [("suspect", "usv2", "usv2", "warn")] * 2
    assert "'future'" in w.events[0].text and "'conflict'" in w.events[1].text
    w._suspect_seen = {k: t - 10.0 for k, t in w._suspect_seen.items()}  # a while later
    w.feed(keys.stats(FLEET, "usv2"), stats_payload(id="usv2", tick=9,
                                                                       rejected_by_reason={"future": 12}))
    assert len(w.events) == 3


def test_a_vehicle_counting_radio_geometry_that_is_not_the_worlds_makes_a_suspect_event():
    w = world()
    for n, conflicts in enumerate([0, 0, 4]):
        w.feed(keys.stats(FLEET, "usv1"), stats_payload(
            id="usv1", tick=n, rejected_by_reason={"radio_stale": 3 * n, "radio_conflict": conflicts}))
    got = [(e.kind, e.vehicle, e.severity) for e in w.events]
    assert got == [("suspect", "usv1", "warn")]
    assert "radio geometry" in w.events[0].text and "'radio_conflict'" in w.events[0].text


def test_the_worlds_events_are_marked_as_its_own_and_wire_text_is_escaped():
    w = world()
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("set_gains", gains={"k\x1b[31m": 1.0}, vehicle=""))
    e = w.events[-1]
    assert e.origin == "world" and "\x1b" not in e.text and decode_event(w.pub_events.puts[-1]).origin == "world"


def test_liveliness_cannot_be_faked_through_the_worlds_wake_key():
    w = started(world())
    w.feed(f"cdus/{FLEET}/to/+world+/wake/alive", b"-usv1")
    assert "usv1" in w.st.alive and w.lockstep.pending == set()


def test_a_crash_not_back_by_the_end_means_the_run_did_not_complete(tmp_path):
    w = started(world(metrics_out=str(tmp_path / "m.json")))
    w.session = None
    w.alive("usv2", False)
    w.alive("uav3", False)
    assert w.lockstep.decide_drops() == "lost"
    w.next_tick = w.last_tick + 1  # as if the others stepped to the end
    m = w.finish()
    assert m.completed is False and m.completion == "vehicles_lost"


def test_a_run_that_reached_its_end_with_the_live_fleet_completed_and_a_stop_did_not():
    w = started(world())
    w.session = None
    w.next_tick = w.last_tick + 1
    m = w.finish()
    assert (m.completed, m.completion) == (True, "completed")
    assert m.rejected_by_reason == RejectedByReason(world={}, vehicles={})
    w = started(world())
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("stop"))
    w.session = None
    assert (lambda m: (m.completed, m.completion))(w.finish()) == (False, "stopped")


def test_a_fleet_that_drops_all_at_once_is_waited_for_then_given_up(monkeypatch):
    w = started(world())
    for vid in w.ids:
        w.alive(vid, False)
    t = w.clock.drops_since
    assert w.lockstep.pending == set(range(6)) and t is not None
    assert not w.clock.supervise_outage(t + 0.1)  # the losses of the moment may still be coming in
    assert not w.clock.supervise_outage(t + 1.0) and w.lockstep.outage == set(range(6))
    assert not w.clock.supervise_outage(t + 1.0 + w.outage_grace / 2)  # waiting
    w.alive("usv1", True)
    assert w.clock.supervise_outage(t + 2.0 + w.outage_grace)
    assert w.completion == "vehicles_lost" and w.lockstep.lost == set(range(1, 6))


def test_a_fleet_back_within_the_grace_goes_on_with_no_roster_change():
    w = started(world())
    sent = len(w.session.puts)
    for vid in w.ids:
        w.alive(vid, False)
    w.clock.supervise_outage(w.clock.drops_since + 1.0)
    for vid in w.ids:
        w.alive(vid, True)
    assert w.clock.drops_since is None and not w.clock.supervise_outage(1e12)
    assert w.lockstep.outage == set() and w.lockstep.lost == set() and w.lockstep.changes == []
    rosters = [k for k, _ in w.session.puts[sent:] if k.endswith("/ctl")]
    assert rosters == []  # nothing told the vehicles anyone was gone


_ints = hs.integers(-2**63, 2**64 - 1)
_keys = hs.one_of(
    hs.sampled_from([keys.state(FLEET, "usv1"), keys.stats(FLEET, "uav2"), keys.world_cmd(FLEET, "gs1"),
                     keys.world_cmd(FLEET, keys.LAUNCHER), f"cdus/{FLEET}/to/+world+/wake/alive",
                     f"cdus/{FLEET}/to/+world+/state/ghost", f"cdus/{FLEET}/to/+world+/state/usv1/x"]),
    hs.text(max_size=60))
_payloads = hs.one_of(
    hs.binary(max_size=200),
    hs.builds(lambda j, n, x: encode_states([StateMsg(j, n, x, (x, x), x, x, x, x, x)]),
              hs.integers(0, 7), hs.integers(0, 2**40), hs.floats(allow_nan=False, allow_infinity=False)),
    hs.dictionaries(hs.sampled_from(["v", "id", "tick", "bursts", "faults", "latencies_ms", "rejected_by_reason",
                                     "op", "vehicle", "gains", "link", "at"]),
                    hs.one_of(_ints, hs.floats(), hs.text(max_size=8), hs.lists(_ints, max_size=3),
                              hs.dictionaries(hs.text(max_size=5), _ints, max_size=3)), max_size=6)
    .map(lambda d: msgpack.packb(d, use_bin_type=True)),
)


@settings(max_examples=300, deadline=None)
@given(hs.lists(hs.tuples(_keys, _payloads), max_size=8), hs.sampled_from(["lockstep", "realtime"]))
def test_the_world_handles_any_key_and_payload_without_raising_and_counts_what_it_drops(samples, clock):
    w = world(clock=clock)
    if clock == "lockstep":
        started(w)
    for key, payload in samples:
        before = w.st.rejected + len(w.lockstep.acked) + len(w.st.stats) + len(w.events)
        w.feed(key, payload)
        assert w.st.rejects["internal"] == 0
        if not key.split("/")[-1] == "alive":
            assert w.st.rejected + len(w.lockstep.acked) + len(w.st.stats) + len(w.events) >= before
    assert all(m.tick <= w.clock.tick_limit() for m in w.st.latest.values())
    assert all(math.isfinite(e.t) for e in w.events)


def test_gains_past_what_the_controller_takes_at_its_rate_are_refused():
    """gs gains k=1e300 diverged the fleet; the world refuses gains beyond cdus.core.gain_bounds."""
    w = world()
    for gains in ({"k": 1e300}, {"k": 2 * w.scenario.rates.control}, {"c": 1e6}):
        before = len(w.session.puts)
        w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("set_gains", gains=gains, vehicle=""))
        assert len(w.session.puts) == before, gains
        assert w.events[-1].kind == "rejected" and "too large" in w.events[-1].text
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("set_gains", gains={"k": 3.0}, vehicle=""))
    assert w.events[-1].kind == "gains_changed"


def test_a_stop_from_the_interrupted_launcher_is_an_interruption_and_an_operators_is_a_stop():
    w = world()
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("stop"))
    assert w.stop_requested and w.completion == "interrupted"
    assert w.events[-1].text == "fleet stopped: the launcher was interrupted"
    w = world()
    w.feed(keys.world_cmd(FLEET, "gs"), encode_control("stop"))
    assert w.completion == "stopped"


def test_a_link_command_the_agents_would_refuse_is_rejected_not_relayed_or_reported_as_a_change():
    w = world()
    before = len(w.session.puts)
    for bad in ({"a": {"b": {"c": {"d": {}}}}}, {"loss": 2.0}):
        w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("link", link=bad, at=-1.0))
        assert len(w.session.puts) == before and w.events[-1].kind == "rejected", w.events
    assert not [e for e in w.events if e.kind == "link_changed"]
    w.feed(keys.world_cmd(FLEET, "gs1"), encode_control("link", link={"loss": 0.2}, at=-1.0))
    assert w.events[-1].kind == "link_changed"


def test_the_graph_event_of_a_scheduled_kill_carries_the_kills_tick_as_in_process(tmp_path):
    """A kill at 1.0 s (tick 50) is carried out once tick 49 is recorded; its liveliness news
    used to be stamped with that newest tick (0.98 s). The in-process fleet says 1.00 s."""
    from cdus.sim.fleet import InProcessFleet

    w = started(world(tmp_path, events=EVENTS))
    for j, vid in enumerate(w.ids):
        send_rows(w, vid, [row(j, n) for n in range(w.lockstep.granted + 1)])
    w.clock.record_complete()
    w.clock.act(w.lockstep.poll())
    assert w.next_tick == 50 and w._sim_now() == 0.98
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("fault_done", vehicle="usv2"))
    w.alive("usv2", False)
    got = [(e.kind, e.t) for e in w.events if e.kind in ("fault", "graph")]
    assert got == [("fault", 1.0), ("graph", 1.0)]
    ref = InProcessFleet(load_scenario(tmp_path / "ev.toml", {"scenario.duration": 1.5})).run().metrics
    assert [(e.kind, e.t) for e in ref.events if e.kind in ("fault", "graph")] == got


def test_a_run_given_up_before_its_start_names_the_vehicles_that_never_came_up():
    """The launcher gave up waiting for two vehicles (--remote ones nobody started) and asked
    the world to stop: not started (it said "interrupted"), and who never came up."""
    w = world()
    for vid in ("usv2", "usv3", "uav1", "uav3"):
        w.alive(vid, True)
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("stop"))
    w.session = None
    m = w.finish()
    assert m.completion == "not_started" and m.never_up == ("usv1", "uav2")
    w = started(world())
    w.session = None
    assert "never_up" not in w.finish().to_dict()  # a run that started has no such field


def test_a_stop_that_overtakes_the_last_liveliness_tokens_is_an_interruption_not_a_run_never_started():
    """`cdus launch` says "fleet up" once it has every token, and a SIGTERM right then makes it
    ask for a stop, which can reach the world before the world's own copies of the last tokens:
    the run was interrupted (every vehicle was up), not "not_started" (seen in a loaded suite)."""
    w = world()
    for vid in w.ids[:-1]:
        w.alive(vid, True)
    w.feed(keys.world_cmd(FLEET, keys.LAUNCHER), encode_control("stop"))
    w._alive_news.append((keys.alive(w.fleet, w.ids[-1], "a3"), True))  # the last token, heard after the stop
    w.session = None
    m = w.run()
    assert m.completion == "interrupted" and m.never_up is None, (m.completion, m.never_up)


def test_a_caught_up_process_that_reports_nothing_hears_the_catch_up_again_until_it_reports():
    """A resumed process whose session lapsed reconnects; the world saw its token back and sent its
    catch-up before the router had its subscriptions again (seen in CI: the process waited for its
    roster for ever, its neighbours for its ω). Said again every CATCHUP_RESEND s until it reports."""
    import time  # noqa: PLC0415

    from world_sim.world import CATCHUP_RESEND  # noqa: PLC0415

    w = started(world())
    j = w.ids.index("uav1")
    w.lockstep.changes.append(RosterChange(50, j, "live"))
    w.lockstep.acked[j] = 49
    w.clock.act([CatchUp(j), Join(j, 50)])
    to_uav1 = lambda: [decode_control(p, CTL_OPS) for k, p in w.session.puts  # noqa: E731
                       if k == keys.ctl(FLEET, ["uav1"])]
    first, grants = len(to_uav1()), len(w.pub_ctl.puts)
    now = time.monotonic()
    w.clock.catch_up_again(now)  # not due yet
    assert len(to_uav1()) == first
    w.clock.catch_up_again(now + CATCHUP_RESEND + 0.1)
    again = to_uav1()[first:]
    assert [c.op for c in again].count("roster") == len(w.lockstep.changes) and again[-1].op == "join"
    assert again[-1].fields["tick"] == 50 and ctl_ops(w)[grants:][-1].op == "grant"
    assert any(c.op == "roster" and c.fields == {"vehicle": "uav1", "tick": 50, "state": "live", "fresh": False}
               for c in again)
    send_rows(w, "uav1", [row(j, 50)])  # it reports: caught up
    assert w.lockstep.acked[j] == 50
    n = len(w.session.puts)
    w.clock.catch_up_again(now + 10 * CATCHUP_RESEND)
    assert len(w.session.puts) == n and not w.clock.catching


def test_a_catch_up_said_again_gives_the_join_tick_after_the_commands_as_the_first_one_does():
    """A restarted process starts stepping when it hears its join tick; the commands in force
    (gains from a tick before it) must be in its inbox by then. The catch-up said again sent
    the join before them: a process that had missed the first stepped its join tick with the
    scenario's gains when the grant broadcast every 0.5 s came before the replayed commands."""
    import time  # noqa: PLC0415

    from world_sim.world import CATCHUP_RESEND  # noqa: PLC0415

    w = started(world())
    w.carry_out("gains", {"gains": {"c": 2.0}, "vehicle": ""}, "gs1")
    j = w.ids.index("uav1")
    w.lockstep.changes.append(RosterChange(50, j, "live"))
    w.lockstep.acked[j] = 49
    ops = lambda: [decode_control(p, CTL_OPS).op for k, p in w.session.puts  # noqa: E731
                   if k == keys.ctl(FLEET, ["uav1"])]
    before = len(ops())  # its start's join
    w.clock.act([CatchUp(j), Join(j, 50)])
    first = ops()[before:]
    assert first.index("gains") < first.index("join"), first
    w.clock.catch_up_again(time.monotonic() + CATCHUP_RESEND + 0.1)
    again = ops()[before + len(first):]
    assert again.index("gains") < again.index("join"), again


def test_a_catch_up_that_went_to_a_process_not_yet_up_is_said_when_its_token_comes():
    """A restart's fault_done can come before the old process's token goes: the world saw the
    vehicle alive, caught it up and sent its join while the new process was still starting, then
    the old token went (which ended the catch-up's resends) and the new one came as expected news:
    the new process waited for its join for ever, and the fleet for it (seen in the suite)."""
    import time  # noqa: PLC0415

    from world_sim.world import CATCHUP_RESEND  # noqa: PLC0415

    w = started(world())
    j = w.ids.index("uav2")
    w.lockstep.acked[j] = 49
    w.clock.act([CatchUp(j), Join(j, 50)])
    joins = lambda: [c for k, p in w.session.puts if k == keys.ctl(FLEET, ["uav2"])  # noqa: E731
                     for c in [decode_control(p, CTL_OPS)] if c.op == "join"]
    first = len(joins())
    w.alive("uav2", False)  # the old process's token goes
    now = time.monotonic()
    w.clock.catch_up_again(now + 5 * CATCHUP_RESEND)
    assert len(joins()) == first and w.clock.catching  # nobody to tell: kept, not dropped
    w.alive("uav2", True)  # the new process's token
    w.clock.catch_up_again(now + 5 * CATCHUP_RESEND)
    assert len(joins()) == first + 1 and joins()[-1].fields["tick"] == 50
    w.clock.catch_up_again(now + 5.5 * CATCHUP_RESEND)  # then less and less often: 1, 2, 4, 8 s apart
    assert len(joins()) == first + 1
    w.clock.catch_up_again(now + 7.1 * CATCHUP_RESEND)
    assert len(joins()) == first + 2


from tests.fullfs import full_fs  # noqa: E402,F401  (the fixture)


def test_a_full_disk_at_the_end_keeps_the_metrics_and_tells_the_launcher(full_fs, tmp_path, monkeypatch):
    """Issue 27, broken 2: the world died in write_json (ENOSPC) at the end of a completed run,
    the launcher took that for a lost world. Now the world says which file and why, keeps the
    metrics in the run directory, and exits METRICS_ELSEWHERE_EXIT, not with a traceback."""
    import world_sim.world as ww
    from cdus.files import METRICS_ELSEWHERE_EXIT

    lines: list[str] = []
    run = tmp_path / "run"
    w = world(metrics_out=str(full_fs / "metrics.json"), run_dir=str(run))
    w.session = None
    w.log = lines.append
    monkeypatch.setattr(w, "open", lambda: None)
    monkeypatch.setattr(w, "run", w.finish)
    monkeypatch.setattr(w, "close", lambda: None)
    assert ww.run_world(w) == METRICS_ELSEWHERE_EXIT
    kept = json.loads((run / "metrics.json").read_text())
    assert kept["completion"] == "not_started" and kept["mode"] == "lockstep"
    assert f"error: could not write the metrics to {full_fs / 'metrics.json'}: No space left on device" in lines
    assert f"the metrics were kept in {run / 'metrics.json'} instead of {full_fs / 'metrics.json'}" in lines
    assert w.not_written == ["the metrics"]


def test_a_recording_that_stops_is_an_event_while_the_run_goes_on():
    """Issue 27, broken 2: a disk that filled while recording was said in world.log only. The
    sink's on_stop is an event (the launcher's console and ground stations show it, the metrics
    keep it)."""
    from cdus.sim.sink import NullSink

    class FileSink(NullSink):
        on_stop = None

        def update(self, recorder) -> None:
            self.on_stop("the Rerun recording into /x.rrd stopped: No space left on device; the run goes on")

    w = world(sink=FileSink())
    w.sink.update(w.recorder)
    (e,) = w.events
    assert (e.kind, e.severity) == ("recording_stopped", "warn") and "No space left on device" in e.text
    assert decode_event(w.pub_events.puts[-1]).text == e.text


def test_the_world_signs_its_statuses_with_the_launchers_key(monkeypatch):
    """Issue 27: the launcher believes only statuses signed with the key it handed its world."""
    from cdus.wire.schemas import STATUS_KEY_ENV, signed_by

    class SigningPub(Pub):
        def put(self, payload, attachment=None) -> None:
            self.puts.append((bytes(payload), attachment))

    monkeypatch.setenv(STATUS_KEY_ENV, "ab" * 16)
    w = world()
    w.pub_status = SigningPub()
    w._publish_status()
    (payload, attachment), = w.pub_status.puts
    assert signed_by(bytes.fromhex("ab" * 16), payload, attachment)
    monkeypatch.delenv(STATUS_KEY_ENV)  # started by hand: unsigned, as before
    w = world()
    w.pub_status = SigningPub()
    w._publish_status()
    assert w.pub_status.puts[0][1] is None


def test_metrics_written_where_asked_are_not_said_to_be_elsewhere(tmp_path, monkeypatch):
    """A relative --metrics-out ("./metrics.json", as written) is where they were written: exit 0."""
    import world_sim.world as ww

    w = world(metrics_out="./metrics.json", run_dir=str(tmp_path / "run"))
    w.session = None
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(w, "open", lambda: None)
    monkeypatch.setattr(w, "run", w.finish)
    monkeypatch.setattr(w, "close", lambda: None)
    assert ww.run_world(w) == 0 and w.not_written == []
    assert (tmp_path / "metrics.json").is_file() and not (tmp_path / "run").exists()

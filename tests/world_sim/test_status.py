"""What the world's status carries for the live console (cdus.wire.schemas.STATUS_EXTRA),
from the world's own state: no network."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings, strategies as hs

from cdus.wire import keys
from cdus.wire.messages import StateMsg, encode_control, encode_states
from cdus.wire.schemas import AgentStats, FleetEvent, decode_status, encode_stats
from tests.fakes import Payload, Sample
from tests.world_sim.test_world import EVENTS, FLEET, started, world
from world_sim.world import closest_live_pair


def at(j: int, n: int, q: tuple, omega: float, path_error: float) -> StateMsg:
    return StateMsg(j, n, n * 0.02, q, 0.0, 1.0, omega, -1.0, path_error)


def test_the_status_carries_kinds_states_edges_links_radius_and_the_closest_pair():
    w = started(world())
    # lake_circle: usv1..3 then uav1..3, a ring; usv1 and usv3 1 m apart, the drones far
    qs = [(0.0, 0.0), (30.0, 0.0), (0.0, 1.0), (0.0, 0.0, 20.0), (50.0, 0.0, 20.0), (0.0, 50.0, 20.0)]
    for j, vid in enumerate(w.ids):
        w.feed(keys.state(FLEET, vid), encode_states([at(j, 0, qs[j], 0.1 * j, 0.01 * (j + 1))]))
    w.clock.record_complete()
    s = AgentStats(id="usv1", tick=1, sent_to_me=20, dropped=3)
    w.feed(keys.stats(FLEET, "usv1"), encode_stats(s))
    w._publish_status()
    st = decode_status(w.pub_status.puts[-1])
    assert st.kinds == ["usv"] * 3 + ["uav"] * 3 and st.states == ["live"] * 6
    assert st.safety_radius == w.scenario.safety.radius and st.directed is False
    assert st.closest[:2] == ("usv1", "usv3") and st.closest[2] == 1.0
    assert st.rx[0] == (20, 3) and st.rx[1:] == [None] * 5
    assert st.path_errors == [0.01 * (j + 1) for j in range(6)]
    edges = {(a, b): e for a, b, e in st.edges}
    omega = dict(zip(w.ids, (0.1 * j for j in range(6))))
    for e in w.recorder.edges:
        a, b = w.ids[e.i], w.ids[e.k]
        assert math.isclose(edges[(a, b)], abs(omega[a] - omega[b] - e.delta), abs_tol=1e-12)
    assert len(edges) == len(w.recorder.edges)


def test_a_vehicle_gone_in_the_roster_is_gone_in_the_status_and_its_edges_have_no_error(tmp_path):
    w = started(world(tmp_path, events=EVENTS))  # usv2 killed at 1 s (tick 50), uav1 paused at 2 s
    rows = [at(j, 60, (float(j), 0.0) if j < 3 else (float(j), 0.0, 20.0), 0.1 * j, 0.2) for j in range(6)]
    live = [vid != "usv2" for vid in w.ids]
    w.recorder.record(60 * w.period, rows, live)
    w.next_tick = 61
    w._publish_status()
    st = decode_status(w.pub_status.puts[-1])
    assert st.states == ["live", "gone", "live", "live", "live", "live"]
    assert [a + b for a, b, e in st.edges if e is None] == [a + b for a, b, _ in st.edges if "usv2" in (a, b)]
    assert st.path_errors[1] is None and st.path_errors[0] == 0.2
    assert "usv2" not in st.closest[:2]
    w.next_tick = 160  # past the pause of uav1 (and its lease)
    w._publish_status()
    assert decode_status(w.pub_status.puts[-1]).states[3] in ("paused", "gone")


@settings(max_examples=200, deadline=None)
@given(hs.lists(hs.tuples(hs.sampled_from(["usv", "uav"]), hs.booleans(),
                          hs.tuples(*[hs.floats(-1e6, 1e6) | hs.just(math.nan) | hs.just(math.inf)] * 3)),
                min_size=0, max_size=8))
def test_the_closest_live_pair_is_min_separation_over_the_live_vehicles(vehicles):
    kinds = [k for k, _, _ in vehicles]
    live = np.array([x for _, x, _ in vehicles], dtype=bool)
    q = np.array([p for _, _, p in vehicles], dtype=float).reshape(len(vehicles), 3)
    ids = [f"v{j}" for j in range(len(vehicles))]
    got = closest_live_pair(q, live, kinds, ids)
    want = None
    for a in range(len(vehicles)):
        for b in range(a + 1, len(vehicles)):
            if live[a] and live[b] and kinds[a] == kinds[b]:
                axes = 2 if kinds[a] == "usv" else 3
                d = math.dist(q[a][:axes], q[b][:axes])
                if math.isfinite(d) and (want is None or d < want):
                    want = d
    if want is None:
        assert got is None
    else:
        assert got is not None and math.isclose(got[2], want, rel_tol=1e-9, abs_tol=1e-9)
        a, b = ids.index(got[0]), ids.index(got[1])
        assert live[a] and live[b] and kinds[a] == kinds[b] and a < b


def test_realtime_a_vehicle_paused_by_a_ground_station_is_paused_until_resumed_even_once_its_token_lapses():
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    w.started = True
    w.clock.t0 = 0.0
    w.clock.paused_at = 2.0

    def states() -> list[str]:
        w._publish_status()
        return decode_status(w.pub_status.puts[-1]).states

    assert states() == ["live"] * 6
    w.feed(keys.world_cmd(FLEET, "gs"), encode_control("pause_vehicle", vehicle="uav1"))
    assert states()[3] == "paused"
    w.alive("uav1", False)  # SIGSTOPped: its token lapses with the lease
    assert states()[3] == "paused"
    w.feed(keys.world_cmd(FLEET, "gs"), encode_control("resume_vehicle", vehicle="uav1"))
    assert states()[3] == "gone"  # resumed, its token not back yet
    w.alive("uav1", True)
    assert states()[3] == "live"
    w.alive("usv2", False)  # nobody asked: lost
    assert states()[1] == "gone"


def test_the_last_status_says_how_the_run_ended_before_the_vehicles_are_told_to_stop(tmp_path):
    """A console read the vehicles leaving at a run's end as vehicles lost: the world's last
    status now says the run is over (its completion, as the metrics'), sent before the stop."""
    w = started(world(tmp_path))
    order = []
    status_put, ctl_put = w.pub_status.put, w.pub_ctl.put
    w.pub_status.put = lambda p: (order.append(("status", decode_status(p).completion)), status_put(p))
    w.pub_ctl.put = lambda p: (order.append(("ctl", p)), ctl_put(p))
    w.stop_requested, w.completion = True, "stopped"
    w._drain = lambda block=False, until=None: None  # no inbox here: the agents' last counters do not come
    m = w.finish()
    assert order[0] == ("status", "stopped") and order[1] == ("ctl", encode_control("stop"))
    assert m.completion == "stopped"
    assert all(decode_status(p).completion is None for p in w.pub_status.puts[:-1])  # only the last says it


def test_after_a_formation_change_the_status_edges_are_measured_against_the_new_offsets():
    # A ground station's `formation phases.usv2=15.7` on a realtime lake_radio fleet: the
    # console's header (the status's coord_error_max) went to 0.76 rad while its edge table
    # and the vehicles' `edge err` still said 14.15 rad (the scenario's Δ), and the console
    # raised `edge usv2-usv3 growing` for an edge that was converging to its new offset.
    w = started(world())
    w.lockstep.granted = 40
    assert w.carry_out("formation", {"phases": {"usv2": 15.7}, "offsets": []}, "gs1").applied  # from tick 41
    theta = dict(zip(w.ids, w.recorder.formation.phases_at(41)))
    qs = [(0.0, 0.0)] * 3 + [(0.0, 0.0, 20.0)] * 3
    for n in (40, 41):
        # every vehicle exactly at its new phase: ω_i = θ_i - t (the formation reached)
        rows = [at(j, n, qs[j], theta[vid] - n * w.period, 0.01) for j, vid in enumerate(w.ids)]
        w.recorder.record(n * w.period, rows)
        w.next_tick = n + 1
        w._publish_status()
        st = decode_status(w.pub_status.puts[-1])
        edges = {(a, b): e for a, b, e in st.edges}
        touches = [(a, b) for a, b in edges if "usv2" in (a, b)]
        assert touches
        if n == 40:  # before the change: measured against the scenario's Δ (usv2 is 13.6 rad off it)
            assert all(edges[ab] > 10 for ab in touches)
        else:  # from the change on: against the new offsets, as the header's coord_error_max
            assert all(e < 1e-9 for e in edges.values()), edges
            assert st.coord_error_max < 1e-9


def _lossy_from(t: float, links: list[str]) -> dict:
    """An agent's link fault summary (as LinkEmulator.counters_summary) with ``links`` lossy from ``t``."""
    block = {"sent": 0, "dropped": 0, "dropped_by": {"loss": 0, "burst": 0, "down": 0, "partition": 0},
             "duplicated": 0, "delayed": 0}
    return {"total": block, "links": {ln: block for ln in links},
            "state_changes": [{"t": t, "link": ln, "state": "lossy"} for ln in links]}


def test_the_status_says_a_link_change_of_twelve_links_whole_not_the_newest_ten_events():
    """Issue 27: the status carried the newest 10 events, so `gs status` said "6 links lossy ...
    and 2 more" of a change of 12 links (two more events came after it). Now each change is whole."""
    w = started(world())
    w._note(FleetEvent.of(10.0, "link_changed", "link loss=0.1 by gs:alice"))
    listening = {vid: [] for vid in w.ids}
    for e in w.recorder.edges:  # each agent reports the links it decides, its incoming ones (a ring: both ways)
        a, b = w.ids[e.i], w.ids[e.k]
        listening[a].append(f"{b}->{a}")
        listening[b].append(f"{a}->{b}")
    for vid in w.ids:
        s = AgentStats(id=vid, tick=520, faults=_lossy_from(10.02, listening[vid]))
        w.feed(keys.stats(FLEET, vid), encode_stats(s))
    w._note(FleetEvent.of(10.5, "fleet", "fleet paused by gs:alice"))
    w._note(FleetEvent.of(11.0, "fleet", "fleet resumed by gs:alice"))
    assert sum(e.kind == "link_state" for e in w.events) == 12
    w._publish_status()
    texts = [e.text for e in decode_status(w.pub_status.puts[-1]).events]
    assert texts[0] == "link loss=0.1 by gs:alice" and texts[2:] == ["fleet paused by gs:alice",
                                                                    "fleet resumed by gs:alice"], texts
    assert texts[1].startswith("12 links lossy (from t = 10.02 s): "), texts


def test_a_restarted_vehicles_links_and_receipts_in_the_status_count_its_earlier_processes():
    """Issue 27: the status's per-link counters (the console's and gs status's link table) were
    the newest process's only, from zero after a restart, while the metrics add them up."""
    w = started(world())

    def report(incarnation: int, sent: int, dropped: int, state: str) -> None:
        block = {"sent": sent, "dropped": dropped,
                 "dropped_by": {"loss": dropped, "burst": 0, "down": 0, "partition": 0}, "duplicated": 0, "delayed": 0}
        faults = {"total": block, "links": {"usv2->usv1": block},
                  "state_changes": [{"t": 0.0, "link": "usv2->usv1", "state": state}]}
        s = AgentStats(id="usv1", tick=sent, sent_to_me=sent, delivered=sent - dropped, dropped=dropped,
                       faults=faults, incarnation=incarnation)
        w.feed(keys.stats(FLEET, "usv1"), encode_stats(s))

    report(1, 100, 10, "lossy")
    report(1, 120, 12, "lossy")  # the same process, later: its counts replace its earlier ones
    w.alive("usv1", False)  # killed: its token goes
    report(2, 30, 3, "down")  # restarted: counting from zero
    w._publish_status()
    st = decode_status(w.pub_status.puts[-1])
    assert st.links == [("usv2", "usv1", 150, 15, "down")]
    assert st.rx[0] == (150, 15) and st.rx[1:] == [None] * 5

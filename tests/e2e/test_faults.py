"""End to end: link faults, vehicle faults and hostile payloads on a running fleet."""

from __future__ import annotations

import math
import queue
import random

import msgpack
import numpy as np
import zenoh

from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.scenario.config import load_scenario
from cdus.wire.transport import Transport, free_tcp_port, open_session
from cdus.sim.build import listeners_of
from cdus.wire.messages import encode_control
from cdus.wire.schemas import decode_event
from cdus.sim.fleet import InProcessFleet
from cdus.wire.rejected import Rejected

from .conftest import fleet_processes, unique_fleet


def test_lake_circle_settles_with_30_percent_loss_and_100_ms_delay_in_lockstep(tmp_path, launches):
    fleet = unique_fleet()
    run = tmp_path / "run"
    # 140 s, not the scenario's 250 (it was 170): it settles at 125.28 s and stays settled to the
    # end (final error 0.034 at 140 s; in process, deterministic, and lockstep is the same run)
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "140", "--set", "link.loss=0.3",
                   "--set", "link.delay.base=0.1", "--logs", str(run), "-q"], fleet)
    assert la.wait(timeout=300) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.coord_settle_s is not None and m.final_coord_error_max < 0.05, m
    faults = m.link.faults.total
    assert 0.27 < faults.dropped_by.loss / faults.sent < 0.33
    # the same decisions as the in-process run: the emulator decides from (seed, src, dst, seq)
    ref = InProcessFleet(load_scenario("configs/lake_circle.toml", {"scenario.duration": 140.0, "link.loss": 0.3,
                                                                    "link.delay.base": 0.1})).run().metrics
    assert m.coord_settle_s == ref.coord_settle_s
    assert faults.dropped == ref.link.faults.total.dropped
    assert not fleet_processes(fleet)


def partition_scenario(tmp_path):
    text = open("configs/lake_circle.toml").read()
    text += """
[[link.partition]]
from = 130.0
to = 145.0
groups = [["usv1", "usv2", "usv3"], ["uav1", "uav2", "uav3"]]
"""
    path = tmp_path / "partition.toml"
    # it settles at 124.04 s, splits at 130 s (the error grows to 1.8), heals at 145 s and settles
    # again at 190.04 s (in process; final error 0.025): 200 s shows it (it was 220 s)
    path.write_text(text.replace("duration = 250.0", "duration = 200.0"))
    return path


def test_a_partition_that_splits_the_ring_and_heals_reconverges(tmp_path, launches):
    cfg = partition_scenario(tmp_path)
    # during the split each half is a chain that still coordinates inside itself; after
    # healing the halves' offsets close again
    ref = InProcessFleet(load_scenario(cfg)).run()
    t = ref.recorder.view("t")
    err = ref.recorder.edge_error().max(axis=1)
    assert err[(t > 125) & (t < 130)].max() < 0.05  # settled before the split
    assert ref.metrics.coord_settle_s > 145.0  # disturbed by the split...
    assert ref.metrics.final_coord_error_max < 0.05  # ...and back after healing
    fleet = unique_fleet()
    run = tmp_path / "run"
    # over direct links: the restarted process (--rejoin) re-links to its neighbours' sockets
    la = launches([str(cfg), "--clock", "lockstep", "--logs", str(run), "-q", "--links", "direct", "--insecure"], fleet)
    assert la.wait(timeout=300) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.coord_settle_s == ref.metrics.coord_settle_s
    assert m.final_coord_error_max < 0.05
    changes = m.link.faults.state_changes
    assert any(c.state == "down" and abs(c.t - 130.0) < 0.1 for c in changes)
    assert any(c.state == "up" and abs(c.t - 145.0) < 0.1 for c in changes)


def test_a_killed_and_restarted_vehicle_rejoins_and_the_fleet_reconverges(tmp_path, launches):
    # concentric_circles (4 vehicles) for 30 s, not lake_circle for 250 s: the same claim in an eighth
    # of the simulated time. Settled at 8.38 s; usv2 killed at 12 s, restarted at 15 s, the coordination
    # error grows (3.0 at most) and settles again at 20.64 s (in process)
    text = open("configs/concentric_circles.toml").read().replace("duration = 250.0", "duration = 30.0")
    text += """
[[event]]
at = 12.0
action = "kill"
vehicle = "usv2"

[[event]]
at = 15.0
action = "restart"
vehicle = "usv2"
"""
    cfg = tmp_path / "kill.toml"
    cfg.write_text(text)
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([str(cfg), "--clock", "lockstep", "--logs", str(run), "-q"], fleet)
    assert la.wait(timeout=300) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    seen = [(e.kind, e.vehicle) for e in m.events]
    assert ("fault", "usv2") in seen and ("vehicle_back", "usv2") in seen, m.events
    # the same vehicle events as `cdus sim` reports for the scenario (cdus.sim.reports)
    ref_run = InProcessFleet(load_scenario(cfg)).run()
    ref = ref_run.metrics
    news = ("fault", "vehicle_lost", "vehicle_back")
    assert [e for e in seen if e[0] in news] == [(e.kind, e.vehicle) for e in ref.events
                                                 if e.kind in news]
    # at the same times: vehicle_back and the graph events of the scheduled changes carry their ticks
    # (they said the newest tick recorded, a tick early: 134.98 s for a restart at 135 s)
    timed = ("fault", "vehicle_back")
    assert [(e.kind, e.t) for e in m.events if e.kind in timed] == \
        [(e.kind, e.t) for e in ref.events if e.kind in timed] == \
        [("fault", 12.0), ("fault", 15.0), ("vehicle_back", 15.0)]
    assert {e.t for e in m.events if e.kind == "graph"} == {e.t for e in ref.events
                                                                      if e.kind == "graph"} == {12.0, 15.0}
    log = (run / "logs" / "usv2.log").read_text()
    assert "rejoining at tick 750" in log, log[-2000:]  # t = 15 s exactly: the fleet waited for it
    # settled before the kill, disturbed by it, and settled again after the restart
    t, err = ref_run.recorder.view("t"), ref_run.recorder.edge_error().max(axis=1)
    assert err[(t > 10.0) & (t < 12.0)].max() < 0.05 and err[(t > 12.0) & (t < 18.0)].max() > 0.5
    assert m.coord_settle_s is not None and m.coord_settle_s > 15.0, m
    assert m.final_coord_error_max < 0.05
    assert not fleet_processes(fleet)


def _lake_lockstep(tmp_path, launches, duration: float, extra: str) -> tuple:
    """lake_circle for ``duration`` s with ``extra`` TOML appended, launched in lockstep (no
    Rerun): (its config, its metrics), once every process of the fleet has gone."""
    cfg = tmp_path / "lake.toml"
    cfg.write_text(open("configs/lake_circle.toml").read().replace("duration = 250.0", f"duration = {duration}")
                   + extra)
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([str(cfg), "--clock", "lockstep", "--logs", str(run), "-q", "--rerun", "off"], fleet)
    assert la.wait(timeout=120) == 0, la.output()
    assert not fleet_processes(fleet)
    return cfg, Metrics.read(run / "metrics.json")


def test_per_link_counters_are_whole_after_a_kill_and_restarts_in_lockstep(tmp_path, launches):
    """Issue 27: after a restart the per-link counters counted the new process only (per-link sums
    65,000 against total.sent 70,898; `cdus sim` 70,998): the world kept each link of the newest
    process, and a killed process's counters since its last once-a-second report were lost (in a
    fast run, all of them). Now the links add up over a vehicle's processes, and an agent waiting
    for the world reports its counters with its rows, so they equal the in-process run's, link by
    link: a scheduled kill (usv2 at 3 s, restarted at 5 s) and a restart of a live vehicle (usv3
    at 6 s), on lossy links."""
    cfg, m = _lake_lockstep(tmp_path, launches, 8.0, """
[link]
loss = 0.2

[[event]]
at = 3.0
action = "kill"
vehicle = "usv2"

[[event]]
at = 5.0
action = "restart"
vehicle = "usv2"

[[event]]
at = 6.0
action = "restart"
vehicle = "usv3"
""")
    faults = m.link.faults
    ref = InProcessFleet(load_scenario(cfg)).run().metrics.link.faults
    assert faults.links == ref.links
    assert faults.total == ref.total
    assert sum(c.sent for c in faults.links.values()) == faults.total.sent == 4396


def test_a_kill_between_two_telemetry_batches_does_not_hold_the_lockstep_fleet(tmp_path, launches):
    """A kill at 0.5 s (tick 25): the killed agent has stepped ticks 20-24, still in its
    telemetry batch of 10, and then waits to be killed. It sends those rows first: the world
    carries out a kill only once every live vehicle has reported the tick before it. It used
    to wait with them unsent, and the fleet hung at tick 25 for good (the test above kills at
    tick 6500, a batch boundary, and a restart made it flush)."""
    _, m = _lake_lockstep(tmp_path, launches, 3.0, """
[[event]]
at = 0.5
action = "kill"
vehicle = "usv2"
""")
    assert m.completed and m.duration_s == 3.0, (m.completion, m.duration_s)
    assert "usv2" not in m.live_final and "usv1" in m.live_final


def hostile_omega_payloads(rng: random.Random, n: int) -> list[bytes]:
    """Payloads no receiver may accept: every kind of wrong, none accidentally valid."""
    good = [1, 0, 5, 1.0, -3.0, -1.0]
    out = []
    for j in range(n):
        kind = j % 8
        if kind == 0:  # random bytes that do not start like a 6-element array
            b = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 40)))
            out.append(b if not b.startswith(b"\x96") else b"\xc1" + b[1:])
        elif kind == 1:  # truncated valid message
            full = msgpack.packb(good)
            out.append(full[: rng.randrange(0, len(full))])
        elif kind == 2:  # oversized
            out.append(msgpack.packb([1, 0, 5, 1.0, -3.0, -1.0, "x" * rng.randrange(40, 400)]))
        elif kind == 3:  # wrong version
            out.append(msgpack.packb([rng.choice([0, 2, 7, 255]), 0, 5, 1.0, -3.0, -1.0]))
        elif kind == 4:  # NaN / inf in a float
            bad = list(good)
            bad[rng.choice([3, 4, 5])] = rng.choice([math.nan, math.inf, -math.inf])
            out.append(msgpack.packb(bad))
        elif kind == 5:  # wrong types
            bad = list(good)
            bad[rng.randrange(6)] = rng.choice(["s", None, True, [1], {"a": 1}, 1 << 40])
            if bad[0] == 1 and all(type(x) is type(y) for x, y in zip(bad, good)):
                bad[0] = "v"
            out.append(msgpack.packb(bad))
        elif kind == 6:  # a map instead of an array
            out.append(msgpack.packb({"v": 1, "omega": 1.0}))
        else:  # wrong sender index for the key
            out.append(msgpack.packb([1, 99, 5, 1.0, -3.0, -1.0]))
    return out


def hostile_commands(rng: random.Random, n: int) -> list[bytes]:
    out = []
    for j in range(n):
        kind = j % 5
        if kind == 0:
            b = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 60)))
            out.append(b"\xc1" + b)  # 0xc1 is never valid msgpack
        elif kind == 1:
            out.append(msgpack.packb({"v": 9, "op": "stop"}))
        elif kind == 2:
            out.append(msgpack.packb({"v": 1, "op": "self_destruct"}))
        elif kind == 3:
            out.append(msgpack.packb({"v": 1, "op": "link", "link": "not a table", "at": 0.0}))
        else:
            out.append(encode_control("set_gains", gains={"k": -1.0}).replace(b"\xa9set_gains", b"\xa9set_gainz"))
    return out


def test_fuzzed_payloads_are_counted_and_never_reach_a_controller(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    # 60 s: the fleet is paused while the fuzz goes in, so any run longer than the pause's way in
    # shows the claim (it was 150 s)
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "60",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run),
                   "--trace-out", str(tmp_path / "trace.npz"), "-q", "--insecure"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    sc = load_scenario("configs/lake_circle.toml", {"scenario.duration": 60.0})
    listeners = {v.id: sum(1 for e in sc.edges if e.k == v.id) for v in sc.vehicles}
    rng = random.Random(1234)
    omega_payloads = hostile_omega_payloads(rng, 8000)
    command_payloads = hostile_commands(rng, 2000)
    ctl_payloads = hostile_commands(rng, 500)
    expected = 0
    session = open_session(Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",)))
    heard = queue.Queue()
    session.declare_subscriber(keys.world_events(fleet), lambda s: heard.put(decode_event(s.payload.to_bytes())))
    try:
        block = zenoh.CongestionControl.BLOCK
        # hold the fleet while the fuzz goes in, so that the run cannot end before every piece is counted
        session.put(keys.world_cmd(fleet, "test"), encode_control("pause"), congestion_control=block)
        while True:
            e = heard.get(timeout=60)
            if not isinstance(e, Rejected) and e.kind == "fleet" and "paused" in e.text:
                break
        pubs = {vid: session.declare_publisher(keys.omega(fleet, vid, listeners_of(sc, vid)), congestion_control=block)
                for vid in sc.ids}
        cmd = session.declare_publisher(keys.world_cmd(fleet, "fuzzer"), congestion_control=block)
        ctl = session.declare_publisher(keys.ctl(fleet, sc.ids), congestion_control=block)
        for j, p in enumerate(omega_payloads):
            vid = sc.ids[j % len(sc.ids)]
            pubs[vid].put(p)
            expected += listeners[vid]
        for p in command_payloads:  # to the world
            cmd.put(p)
            expected += 1
        for p in ctl_payloads:  # as if from the world, to every vehicle
            ctl.put(p)
            expected += len(sc.vehicles)
        session.put(keys.world_cmd(fleet, "test"), encode_control("resume"), congestion_control=block)
    finally:
        session.close()
    assert la.wait(timeout=300) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True
    # no agent died: every one reported to the end, and all the fuzz was counted as rejected
    assert m.link.rejected == expected, (m.link, expected)
    # nothing reached a controller: the run equals the clean in-process one, bit for bit
    ref = InProcessFleet(sc).run()
    trace = np.load(tmp_path / "trace.npz")
    assert np.array_equal(trace["omega"], ref.recorder.view("omega"))
    assert np.array_equal(trace["q"], ref.recorder.view("q"))
    logs = "".join(p.read_text() for p in (run / "logs").glob("*.log"))
    assert "Traceback" not in logs
    assert not fleet_processes(fleet)

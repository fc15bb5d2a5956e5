"""End to end: [[obstacle]]s in a lockstep fleet of processes reproduce the in-process run bit
for bit, the obstacles block of the metrics included, also with an outsider forging the agents'
deflected counters."""

from __future__ import annotations

import threading

import msgpack
import zenoh

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.wire.schemas import SCHEMA_VERSION, AgentStats
from cdus.wire.transport import Transport, free_tcp_port, open_session

from .conftest import assert_same_trace, fleet_processes, unique_fleet

CONFIG = "configs/island_crossing.toml"
# every vehicle 27 s further back along its path, the formation kept: the boats reach the island
# and the pier within 3 s (the filter's obstacle rows act from then on), 8 s is enough
LEAD = 27.0
PHASES = {"usv_a": 0.0, "usv_b": 31.41592653589793, "uav_a": 15.707963267948966, "uav_b": 47.12388980384689}
STARTS = {f"vehicle.{v}.omega0": th - LEAD for v, th in PHASES.items()}


def test_lockstep_with_obstacles_reproduces_the_in_process_run(tmp_path, launches):
    fleet = unique_fleet()
    run = tmp_path / "run"
    sets = [a for k, v in STARTS.items() for a in ("--set", f"{k}={v!r}")]
    la = launches([CONFIG, "--clock", "lockstep", "--duration", "8", "--logs", str(run), "--rerun", "off",
                   "--trace-out", str(tmp_path / "trace.npz"), "-q", *sets], fleet)
    assert la.wait() == 0, la.output()
    ref = InProcessFleet(load_scenario(CONFIG, {**STARTS, "scenario.duration": 8.0})).run()
    ob = ref.metrics.obstacles
    assert ob.vehicles["usv_a"]["deflected_s"] > 0 and ob.vehicles["usv_b"]["deflected_s"] > 0
    assert_same_trace(tmp_path / "trace.npz", ref)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.completed is True
    assert metrics.obstacles == ob  # clearances from the same positions, deflected steps from the agents' stats
    assert not fleet_processes(fleet)


def _forged_stats(vid: str, **over) -> bytes:
    d = {"v": SCHEMA_VERSION, **AgentStats(id=vid, tick=1).as_dict(), **over}
    return msgpack.packb(d, use_bin_type=True)


#: what an outsider puts on usv_a's stats key (reason the world counts it under)
FORGED = [({"deflected": 10**6}, "deflected"), ({"deflected": -5}, "type"), ({"deflected": 3.5}, "type"),
          ({"deflected": "999"}, "type"), ({"deflected": 2**60, "interventions": 2**60}, "range"),
          ({"id": "usv_b", "interventions": 9, "deflected": 9}, "sender_mismatch")]


def test_forged_deflected_counters_on_an_open_lockstep_fleet_change_nothing(tmp_path, launches):
    """An outsider on an --insecure fleet (client mode to the launcher's loopback router) puts
    deflected counters no agent can have counted on usv_a's stats key, from before the run to its
    end: each is dropped and counted by reason, and the run (the obstacles block with its
    deflected_s included) is still the in-process run's, bit for bit."""
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    sets = [a for k, v in STARTS.items() for a in ("--set", f"{k}={v!r}")]
    la = launches([CONFIG, "--clock", "lockstep", "--duration", "8", "--logs", str(run), "--rerun", "off",
                   "--listen", f"tcp/127.0.0.1:{port}", "--insecure", "--trace-out", str(tmp_path / "trace.npz"),
                   "-q", *sets], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    session = open_session(Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",)))
    done = threading.Event()
    sent = [0]

    def attack() -> None:
        pub = session.declare_publisher(keys.stats(fleet, "usv_a"), congestion_control=zenoh.CongestionControl.BLOCK)
        while not done.is_set():
            for over, _ in FORGED:
                pub.put(_forged_stats("usv_a", **over))
                sent[0] += 1
            done.wait(0.05)

    t = threading.Thread(target=attack, daemon=True)
    t.start()
    try:
        code = la.wait()
    finally:
        done.set()
        t.join(5)
        session.close()
    assert code == 0, la.output()
    assert sent[0] >= len(FORGED)
    ref = InProcessFleet(load_scenario(CONFIG, {**STARTS, "scenario.duration": 8.0})).run()
    assert_same_trace(tmp_path / "trace.npz", ref)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.completed is True
    assert metrics.obstacles == ref.metrics.obstacles and metrics.obstacles.vehicles["usv_a"]["deflected_s"] > 0
    world = metrics.rejected_by_reason.world
    assert all(world.get(reason, 0) >= 1 for _, reason in FORGED), world
    assert not fleet_processes(fleet)

"""How fast does the world notice a vehicle process dying? SIGKILL -> the world's vehicle_lost event.

    python bench/failure_detection.py                # 8 kills, lake_circle in realtime
    python bench/failure_detection.py --kills 12

A `cdus launch CONFIG --clock realtime --restart on-failure` run on a router whose port
this bench chooses; a client session of the bench listens to the fleet's events
(cdus.wire.keys.world_events). One vehicle at a time (in turn), the bench SIGKILLs its
process group and stamps the moment; the world's ``vehicle_lost`` event for that vehicle
is stamped on arrival. The launcher restarts the vehicle by the policy; the bench waits
for its ``vehicle_back`` before the next kill. Both stamps are time.monotonic of this
process, so the figure includes the event's trip from the world to the bench (one Zenoh
hop through the router). A killed process's TCP connection closes at once, so the
router drops its liveliness token without waiting for the lease (the launcher's lease,
cdus.wire.transport.DEFAULT_LEASE_MS, bounds a hung process, not a dead one).

Prints each kill's delay and the median / p95 / max. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import os
import queue
import signal
import statistics
import sys
import tempfile
import time
from pathlib import Path

from _fleet import REPO, Launch, load_line, role

from cdus.scenario.config import load_scenario
from cdus.wire import keys
from cdus.wire.schemas import FleetEvent, decode_event
from cdus.wire.transport import Transport, free_tcp_port, open_session


def pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def wait_event(events: "queue.Queue[tuple[float, FleetEvent]]", kind: str, vid: str,
               timeout: float) -> float | None:
    """Arrival time of the next event of ``kind`` about ``vid`` (others are skipped), None on timeout."""
    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0:
        try:
            t, e = events.get(timeout=left)
        except queue.Empty:
            return None
        if e.kind == kind and e.vehicle == vid:
            return t
    return None


def agent_pid(la: Launch, vid: str) -> int | None:
    for p in la.processes():
        if role(p) == f"agent:{vid}":
            return p.pid
    return None


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--kills", type=int, default=8)
    args = ap.parse_args()
    config = str((REPO / args.config).resolve()) if not os.path.isabs(args.config) else args.config
    port = free_tcp_port()
    ep = f"tcp/127.0.0.1:{port}"
    fleet = f"bench_fd_{os.getpid()}"
    duration = 30.0 + 8.0 * args.kills
    events: queue.Queue = queue.Queue()

    def on_event(sample) -> None:
        t = time.monotonic()
        e = decode_event(sample.payload.to_bytes())
        if isinstance(e, FleetEvent):
            events.put((t, e))

    print(load_line(), flush=True)
    delays: list[float] = []
    with tempfile.TemporaryDirectory(prefix="cdus-fd-") as tmp:
        cli = ["launch", config, "--clock", "realtime", "--duration", f"{duration:g}", "-q", "--fleet", fleet,
               "--logs", str(Path(tmp) / "run"), "--listen", ep, "--restart", "on-failure", "--rerun", "off",
               "--set", f"supervision.max_restarts={args.kills}",
               "--insecure"]  # an open fleet: this bench's own client watches it without credentials
        session = None
        with Launch(cli, fleet=fleet) as la:
            try:
                session = open_session(Transport(mode="client", connect=(ep,)))
                sub = session.declare_subscriber(keys.world_events(fleet), on_event)
                la.up.wait(timeout=120)
                if la.proc.poll() is not None:
                    print("the launcher exited:\n" + "\n".join(la.lines[-20:]))
                    return 1
                ids = load_scenario(config).ids
                time.sleep(3.0)  # into the run: the world's clock starts 0.5 s after everyone is up
                for i in range(args.kills):
                    vid = ids[i % len(ids)]
                    pid = agent_pid(la, vid)
                    if pid is None:
                        print(f"kill {i + 1}: no process for {vid}")
                        return 1
                    while not events.empty():
                        events.get_nowait()
                    t_kill = time.monotonic()
                    os.killpg(pid, signal.SIGKILL)
                    t_lost = wait_event(events, "vehicle_lost", vid, 20.0)
                    if t_lost is None:
                        print(f"kill {i + 1}: {vid}: no vehicle_lost within 20 s")
                        return 1
                    delays.append(t_lost - t_kill)
                    print(f"kill {i + 1:2d}: {vid}  SIGKILL -> vehicle_lost {1000 * delays[-1]:7.1f} ms", flush=True)
                    if wait_event(events, "vehicle_back", vid, 30.0) is None:
                        print(f"  {vid} did not come back within 30 s; stopping")
                        break
                    time.sleep(1.0)
                del sub
            finally:
                if session is not None:
                    session.close()
    ms = [1000 * d for d in delays]
    print(f"\n{len(ms)} kills, SIGKILL -> the world's vehicle_lost event (realtime, loopback TCP): "
          f"median {statistics.median(ms):.1f} ms, p95 {pct(ms, 0.95):.1f} ms, max {max(ms):.1f} ms")
    print(load_line())
    return 0


if __name__ == "__main__":
    sys.exit(main())

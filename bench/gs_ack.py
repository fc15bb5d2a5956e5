"""How long a ground station waits for the world's answer to a command (docs/ground_station.md).

    python bench/gs_ack.py                    # concentric_circles, lockstep, secured, 20 rounds
    python bench/gs_ack.py --clock realtime -n 50

A fleet is launched (secured, as by default); this process is a ground station with the run's
ground credentials (ground_station.console.GroundStation, one session for every command).
Each round times, from the query to the answer: a no-op gains change (the configured gains,
every vehicle), a pause and a resume of the fleet, and, in lockstep, a pause-vehicle and a
resume-vehicle of one vehicle (answered once the fault lands on its tick). Prints p50 / max per
command in ms, and the load average. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

from _fleet import Launch, load_line

from cdus.wire.transport import Transport, free_tcp_port
from ground_station.console import GroundStation


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/concentric_circles.toml")
    ap.add_argument("--clock", choices=("lockstep", "realtime"), default="lockstep")
    ap.add_argument("-n", type=int, default=20, help="rounds")
    a = ap.parse_args()
    print(load_line())
    work = Path(tempfile.mkdtemp(prefix="gs_ack_"))
    fleet = f"bench_gs_{os.getpid()}"
    port = free_tcp_port()
    args = ["launch", a.config, "--clock", a.clock, "--duration", "100000", "-q", "--rerun", "off",
            "--fleet", fleet, "--logs", str(work), "--listen", f"tcp/127.0.0.1:{port}"]
    times: dict[str, list[float]] = {}
    with Launch(args, fleet=fleet) as la:
        la.up.wait(120)
        gs = GroundStation(fleet, Transport(mode="client", config_file=str(work / "secure" / "ground.json5")),
                           name="bench")
        gs.open()
        try:
            gs.wait_for_status(10)
            commands = [("gains", "set_gains", {"gains": {"k": 1.5, "c": 2.0}, "vehicle": ""}),
                        ("pause", "pause", {}), ("resume", "resume", {})]
            if a.clock == "lockstep":
                commands += [("pause-vehicle", "pause_vehicle", {"vehicle": "uav1"}),
                             ("resume-vehicle", "resume_vehicle", {"vehicle": "uav1"})]
            for _ in range(a.n):
                for name, op, fields in commands:
                    t0 = time.perf_counter()
                    ans = gs.command(op, timeout=30.0, **fields)
                    dt = (time.perf_counter() - t0) * 1000
                    if ans.outcome != "applied":
                        print(f"  {name}: {ans.outcome} {ans.reply.reason if ans.reply else ans.detail}")
                    times.setdefault(name, []).append(dt)
        finally:
            gs.close()
    print(f"{a.config}, {a.clock}, secured, {a.n} rounds: query -> answer (ms)")
    for name, xs in times.items():
        print(f"  {name:<15} p50 {statistics.median(xs):7.1f}   max {max(xs):7.1f}")
    print(load_line())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

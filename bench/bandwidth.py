"""What does exchanging ω cost on the wire, beside exchanging positions? Bytes per second per vehicle.

    python bench/bandwidth.py                            # lake_circle, 12 s realtime run
    python bench/bandwidth.py --config configs/lissajous_5x5.toml --duration 20

Computed: the ω payload (cdus.wire.messages.encode_omega, over the run's sequence
numbers) x the broadcast rate, once into the router and once per listener out of it; the
same for what a position-based coordination would exchange at the same rate, a msgpack
array [version, id, seq, t, x, y, z, vx, vy, vz] with float64 values; and the telemetry
(state) batches each vehicle sends the world (encode_states, the agent's batch size).

Measured: a `cdus launch CONFIG --clock realtime` run on a router this bench chooses the
port of; a client session of the bench subscribes to the fleet's ω, telemetry and counter
keys (cdus.wire.keys any_omega, any_state, any_stats) and counts payload bytes per vehicle over the middle of the run, and `ss` reads each
agent's TCP byte counters (everything it sends and receives, Zenoh framing and
keep-alives included). Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import threading
import time
from collections import defaultdict
from pathlib import Path

import msgpack
from _fleet import REPO, Launch, load_line, role

from cdus.wire import keys
from cdus.scenario.config import load_scenario
from cdus.wire.transport import Transport, free_tcp_port, open_session
from vehicle_agent.clocks import STRATEGIES
from cdus.wire.messages import OmegaMsg, StateMsg, encode_omega, encode_states
from cdus.core.schedule import broadcast_every, total_ticks


def omega_bytes(sc, duration: float) -> float:
    """Mean ω payload over a run's broadcasts (msgpack ints grow with seq)."""
    every = broadcast_every(sc.rates)
    n = total_ticks(duration, 1.0 / sc.rates.control) // every + 1
    sizes = [len(encode_omega(OmegaMsg(0, seq, seq * every / sc.rates.control, -seq * 0.02, -1.0)))
             for seq in range(n)]
    return sum(sizes) / len(sizes)


def position_bytes(seq: int = 5000) -> int:
    return len(msgpack.packb([1, 0, seq, 100.02, -41.2, 57.9, 20.0, 0.61, -9.98, 0.0], use_single_float=False))


def state_bytes(sc, clock: str) -> float:
    """Mean telemetry payload per control tick of one vehicle (its batch / rows)."""
    per_tick = []
    batch = STRATEGIES[clock].state_batch
    for v in sc.vehicles:
        q = tuple([1.234567] * v.dim)
        rows = [StateMsg(v.index, 5000 + r, 100.0 + r * 0.02, q, 1.2, 9.9, -100.0, -1.0, 0.01) for r in range(batch)]
        per_tick.append(len(encode_states(rows)) / batch)
    return sum(per_tick) / len(per_tick)


def listeners(sc) -> dict[str, int]:
    """How many vehicles subscribe to each vehicle's ω (edges (i, k): i listens to k)."""
    out = {v.id: 0 for v in sc.vehicles}
    for e in sc.edges:
        out[e.k] += 1
    return out


SS_BYTES = re.compile(r"bytes_(sent|received):(\d+)")
SS_PID = re.compile(r"pid=(\d+)")


def tcp_counters(port: int) -> dict[int, dict[str, int]]:
    """Per pid, the TCP bytes sent/received on its connections to 127.0.0.1:port (client side)."""
    text = subprocess.run(["ss", "-tinpH", "state", "established", f"( dport = :{port} )"],
                          capture_output=True, text=True, timeout=10).stdout
    out: dict[int, dict[str, int]] = {}
    pid = None
    for line in text.splitlines():
        m = SS_PID.search(line)
        if m:
            pid = int(m.group(1))
            continue
        if pid is not None:
            c = out.setdefault(pid, {"sent": 0, "received": 0})
            for k, v in SS_BYTES.findall(line):
                c[k] += int(v)
            pid = None
    return out


def measure(config: str, sc, duration: float, work: Path) -> dict:
    port = free_tcp_port()
    ep = f"tcp/127.0.0.1:{port}"
    fleet = f"bench_bw_{os.getpid()}"
    seen: dict[str, list[tuple[float, str, int]]] = defaultdict(list)  # leaf -> (time, vid, bytes)
    lock = threading.Lock()

    def counter(leaf: str):
        def cb(sample) -> None:
            t = time.monotonic()
            n = len(sample.payload.to_bytes())
            with lock:
                seen[leaf].append((t, keys.leaf(str(sample.key_expr))[1], n))
        return cb

    args = ["launch", config, "--clock", "realtime", "--duration", f"{duration:g}", "-q", "--fleet", fleet,
            "--logs", str(work / "run"), "--listen", ep,
            "--insecure"]  # an open fleet: this bench's own client listens without credentials
    session = None
    with Launch(args, fleet=fleet) as la:
        try:
            session = open_session(Transport(mode="client", connect=(ep,)))
            subs = [session.declare_subscriber(key(fleet), counter(leaf))
                    for leaf, key in (("omega", keys.any_omega), ("state", keys.any_state), ("stats", keys.any_stats))]
            la.up.wait(timeout=120)
            time.sleep(0.5 + 2.0)  # the world starts the clock 0.5 s after everyone is up
            agents = {p.pid: role(p)[6:] for p in la.processes() if role(p).startswith("agent:")}
            c0, t0 = tcp_counters(port), time.monotonic()
            time.sleep(max(2.0, duration - 5.0))
            c1, t1 = tcp_counters(port), time.monotonic()
            la.wait(timeout=duration + 60)
            del subs
        finally:
            if session is not None:
                session.close()
    tcp = {}
    for pid, vid in agents.items():
        if pid in c0 and pid in c1:
            tcp[vid] = {k: (c1[pid][k] - c0[pid][k]) / (t1 - t0) for k in ("sent", "received")}
    rates = {}
    for leaf, rows in seen.items():
        rows = [r for r in rows if t0 <= r[0] <= t1]
        per = defaultdict(lambda: [0, 0])
        for _, vid, n in rows:
            per[vid][0] += 1
            per[vid][1] += n
        rates[leaf] = {vid: (m / (t1 - t0), b / (t1 - t0)) for vid, (m, b) in per.items()}
    return {"tcp": tcp, "payload": rates, "window": t1 - t0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--duration", type=float, default=12.0, help="seconds of the measured realtime run")
    args = ap.parse_args()
    config = str((REPO / args.config).resolve()) if not os.path.isabs(args.config) else args.config
    sc = load_scenario(config)
    rate = sc.rates.control / broadcast_every(sc.rates)
    lis = listeners(sc)
    mean_lis = sum(lis.values()) / len(lis)
    w = omega_bytes(sc, sc.duration)
    p = position_bytes()
    st = state_bytes(sc, "realtime")
    print(load_line())
    print(f"{sc.name}: {len(sc.vehicles)} vehicles, {sc.topology} graph, {mean_lis:g} listeners per vehicle "
          f"(mean), broadcast {rate:g} Hz, control {sc.rates.control:g} Hz")
    print("computed payload bytes per vehicle (router in, and out to the listeners):")
    print(f"  {'stream':<46} {'B/msg':>6} {'msg/s':>6} {'B/s in':>8} {'B/s out':>8}")
    print(f"  {'ω: [v, id, seq, t, ω, ω̇f32]':<46} {w:6.1f} {rate:6g} {w * rate:8.0f} {w * rate * mean_lis:8.0f}")
    print(f"  {'positions: [v, id, seq, t, x,y,z, vx,vy,vz]':<46} {p:6d} {rate:6g} {p * rate:8.0f} "
          f"{p * rate * mean_lis:8.0f}")
    print(f"  positions / ω: {p / w:.2f}x the bytes ({p * rate * (1 + mean_lis) - w * rate * (1 + mean_lis):.0f} "
          f"B/s more per vehicle through the router)")
    print(f"  {'telemetry to the world (state, batch ' + str(STRATEGIES['realtime'].state_batch) + ')':<46} "
          f"{st * STRATEGIES['realtime'].state_batch:6.0f} {sc.rates.control / STRATEGIES['realtime'].state_batch:6g} "
          f"{st * sc.rates.control:8.0f} {st * sc.rates.control:8.0f}  (to the world only)")

    with tempfile.TemporaryDirectory(prefix="cdus-bw-") as tmp:
        m = measure(config, sc, args.duration, Path(tmp))
    print(f"measured in a {args.duration:g} s `cdus launch --clock realtime` run, "
          f"over {m['window']:.1f} s of its middle:")
    print(f"  {'vehicle':<8} {'ω msg/s':>8} {'ω B/s':>7} {'state B/s':>10} {'stats B/s':>10} {'payload B/s':>12} "
          f"{'TCP B/s sent':>13} {'TCP B/s recv':>13}")
    tot = defaultdict(float)
    for v in sc.vehicles:
        om = m["payload"].get("omega", {}).get(v.id, (0, 0))
        sb = m["payload"].get("state", {}).get(v.id, (0, 0))[1]
        xb = m["payload"].get("stats", {}).get(v.id, (0, 0))[1]
        tcp = m["tcp"].get(v.id, {"sent": float("nan"), "received": float("nan")})
        print(f"  {v.id:<8} {om[0]:8.1f} {om[1]:7.0f} {sb:10.0f} {xb:10.0f} {om[1] + sb + xb:12.0f} "
              f"{tcp['sent']:13.0f} {tcp['received']:13.0f}")
        for k, x in (("om", om[1]), ("omm", om[0]), ("st", sb), ("sx", xb),
                     ("ts", tcp["sent"]), ("tr", tcp["received"])):
            tot[k] += x
    n = len(sc.vehicles)
    print(f"  {'mean':<8} {tot['omm'] / n:8.1f} {tot['om'] / n:7.0f} {tot['st'] / n:10.0f} {tot['sx'] / n:10.0f} "
          f"{(tot['om'] + tot['st'] + tot['sx']) / n:12.0f} {tot['ts'] / n:13.0f} {tot['tr'] / n:13.0f}")
    print(f"  measured ω payload per vehicle: {tot['om'] / n:.0f} B/s into the router, "
          f"{tot['om'] / n * mean_lis:.0f} B/s out to its {mean_lis:g} listeners; positions at the same rate would be "
          f"{p * tot['omm'] / n:.0f} and {p * tot['omm'] / n * mean_lis:.0f} B/s ({p / w:.2f}x)")
    msgs_out = sum(sum(m["payload"].get(leaf, {}).get(v.id, (0, 0))[0] for leaf in ("omega", "state", "stats"))
                   for v in sc.vehicles)
    omega = m["payload"].get("omega", {})
    omega_in = sum(omega.get(e.k, (0, 0))[0] for e in sc.edges)  # edge (i, k): i receives k's ω
    omega_in_bytes = sum(omega.get(e.k, (0, 0))[1] for e in sc.edges)
    if msgs_out and omega_in:
        print(f"  on the wire, bytes per message beyond its payload: "
              f"{(tot['ts'] - tot['om'] - tot['st'] - tot['sx']) / msgs_out:.1f} agent -> router "
              f"({msgs_out / n:.0f} msg/s per agent), {(tot['tr'] - omega_in_bytes) / omega_in:.1f} router -> agent "
              f"(its neighbours' ω, {omega_in / n:.0f} msg/s per agent; clock and keep-alives counted in)")
    print("  TCP sent = everything an agent writes to the router (ω, telemetry, counters, Zenoh framing, keep-alives);"
          " TCP recv = its neighbours' ω, the clock and keep-alives.")


if __name__ == "__main__":
    sys.exit(main())

"""The ceiling for lockstep: raw Zenoh processes in a ring exchanging one message per tick.

    python bench/raw_ring.py                      # 6 processes, 3000 ticks, router and peer links
    python bench/raw_ring.py -n 6 --ticks 5000 --topology peer

Each process i publishes tick n's 32-byte payload once it holds tick n-1's payload from
both ring neighbours, exactly the dependency of a lockstep fleet with an ideal link and a
broadcast every tick, with no control law and no Python work besides the loop. It waits
on a FifoChannel as the agent does. Topologies:

  router: every process a client of one router (this process), as `cdus launch` runs;
  peer:   every process a peer listening on its own unix socket and connected directly to
          its ring neighbours' sockets (no router hop), plus the router for discovery.

Prints ticks per second and what that is in real time at 50 Hz control ("x real time"),
with the CPU per process per tick during the loop. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import zenoh

BENCH = Path(__file__).resolve().parent
RUNTIME = "(app: (worker_threads: 1), acc: (handover: app), rx: (handover: app), tx: (handover: app))"


def config(mode: str, connect: list[str], listen: list[str]) -> zenoh.Config:
    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(mode))
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("scouting/gossip/enabled", "false" if mode == "peer" else "true")
    c.insert_json5("connect/endpoints", json.dumps(connect))
    c.insert_json5("listen/endpoints", json.dumps(listen))
    return c


def member(i: int, n: int, ticks: int, mode: str, router: str, socks: list[str]) -> None:
    left, right = (i - 1) % n, (i + 1) % n
    if mode == "peer":
        connect = [router] + [socks[j] for j in (left, right) if j < i]  # one link per pair
        s = zenoh.open(config("peer", connect, [socks[i]]))
    else:
        s = zenoh.open(config("client", [router], []))
    # one put per tick to both neighbours, as the agent's addressed ω key does
    inbox = s.declare_subscriber(f"ring/to/$*+{i}+$*/*", zenoh.handlers.FifoChannel(4096))
    pub = s.declare_publisher(f"ring/to/+{min(left, right)}+{max(left, right)}+/{i}",
                              congestion_control=zenoh.CongestionControl.BLOCK)
    token = s.liveliness().declare_token(f"ring/alive/{i}")
    have = {left: -1, right: -1}
    # wait until both neighbours are subscribed (their tokens), then a start message
    start = s.declare_subscriber("ring/start", zenoh.handlers.FifoChannel(8))
    start.recv()
    t0, c0 = time.perf_counter(), time.process_time()
    for t in range(ticks):
        while min(have.values()) < t - 1:
            sample = inbox.recv()
            src, seq = struct.unpack_from("<ii", sample.payload.to_bytes())
            have[src] = max(have[src], seq)
        payload = struct.pack("<ii24x", i, t)
        pub.put(payload)
    while min(have.values()) < ticks - 1:
        src, seq = struct.unpack_from("<ii", inbox.recv().payload.to_bytes())
        have[src] = max(have[src], seq)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(json.dumps({"i": i, "wall": wall, "cpu": cpu}), flush=True)
    token.undeclare()
    s.close()


def run(n: int, ticks: int, mode: str) -> dict:
    work = Path(tempfile.mkdtemp(prefix="cdus_ring_"))
    port = _free_port()
    router = f"tcp/127.0.0.1:{port}"
    socks = [f"unixsock-stream/{work}/p{i}.sock" for i in range(n)]
    env = {**os.environ, "ZENOH_RUNTIME": RUNTIME}
    r = zenoh.open(config("router", [], [router]))
    alive = r.liveliness().declare_subscriber("ring/alive/*", zenoh.handlers.FifoChannel(64))
    procs = [subprocess.Popen([sys.executable, __file__, "--member", str(i), "-n", str(n), "--ticks", str(ticks),
                               "--topology", mode, "--router", router, "--socks", ",".join(socks)],
                              stdout=subprocess.PIPE, text=True, env=env, start_new_session=True)
             for i in range(n)]
    try:
        seen = set()
        while len(seen) < n:
            seen.add(str(alive.recv().key_expr))
        time.sleep(0.5)  # routes settle (peer links, subscriptions)
        r.put("ring/start", b"go")
        out = [json.loads(p.stdout.readline()) for p in procs]
        for p in procs:
            p.wait(timeout=30)
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
        r.close()
    wall = max(o["wall"] for o in out)
    return {"ticks_per_s": ticks / wall, "cpu_per_tick_us": sum(o["cpu"] for o in out) / n / ticks * 1e6}


def _free_port() -> int:
    import socket
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-n", type=int, default=6)
    ap.add_argument("--ticks", type=int, default=3000)
    ap.add_argument("--topology", choices=("router", "peer", "both"), default="both")
    ap.add_argument("--member", type=int, help=argparse.SUPPRESS)
    ap.add_argument("--router", help=argparse.SUPPRESS)
    ap.add_argument("--socks", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.member is not None:
        return member(args.member, args.n, args.ticks, args.topology, args.router, args.socks.split(","))
    print(f"{args.n} processes in a ring, {args.ticks} ticks, one 32-byte message to each neighbour per tick")
    for mode in (("router", "peer") if args.topology == "both" else (args.topology,)):
        r = run(args.n, args.ticks, mode)
        print(f"  {mode:<6}: {r['ticks_per_s']:7.0f} ticks/s = {r['ticks_per_s'] / 50:5.1f}x real time at 50 Hz; "
              f"CPU per process per tick {r['cpu_per_tick_us']:.0f} µs (the loop only)")


if __name__ == "__main__":
    main()

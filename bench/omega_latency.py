"""ω one-way latency through the agents' link layer, beside raw Zenoh pub/sub, in one run.

    python bench/omega_latency.py                 # 2000 messages of each kind at 200 Hz
    python bench/omega_latency.py -n 5000 --hz 100

Topology as in `cdus launch`: this process is the router (tcp/127.0.0.1:<free port>, as the
launcher opens it); a sender and a receiver process connect to it as clients, with the
launcher's ZENOH_RUNTIME. Every 1/hz s the sender puts

  raw:  a payload of the ω message's size on cdus/<fleet>/bench/raw, its first 8 bytes the
        send time (time.time_ns); the receiver's plain callback stamps the arrival;
  ours: the ω its own node (vehicle 0 of a 2-vehicle ring) steps to, stamped just before
        encode_omega and put on vehicle 0's ω key from a publisher declared as the agent
        declares it (congestion control BLOCK),

half a period apart (the raw payload also carries its index, for the warm-up). The
receiver is a real vehicle_agent Agent (vehicle 1) opened on the router, in lockstep
(granted the whole run): its main thread blocks on the agent's inbox channel as the
agent's lockstep loop does (a realtime agent takes ω once per tick, from per-neighbour
rings: its latency is the tick's) and hands each sample to the agent's own `feed`,
which decodes and validates it and gives it to the node, which takes it (genuine ω:
nothing rejected, so the node's checks all run). The bench stamps when recv() returns
and when the node has taken the message (a one-line wrapper), by seq, and joins them with
the sender's stamps. Clocks: time.time in both processes (one machine, one clock). For
the breakdown the sender also records stamp -> put() of each kind.
Figures are printed, never asserted: they depend on what else the machine runs.
Target (issue 20): our layer adds <= 50 µs at p50.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

BENCH = Path(__file__).resolve().parent
sys.path.insert(0, str(BENCH.parent))

from cdus.sim.build import listeners_of  # noqa: E402
from cdus.wire import keys  # noqa: E402
from cdus.wire.transport import (  # noqa: E402
    ROUTER_RUNTIME, Transport, client_of, local_router, open_session, use_runtime,
)
from vehicle_agent.agent import OMEGA_EXPRESS as AGENT_EXPRESS  # noqa: E402

WARMUP = 50  # messages of each kind not counted (declarations settling, caches warming)


def raw_key(fleet: str) -> str:
    return f"{keys.prefix(fleet)}/bench/raw"


def done_key(fleet: str) -> str:
    return f"{keys.prefix(fleet)}/bench/done"


def ready_key(fleet: str) -> str:
    return f"{keys.prefix(fleet)}/bench/ready"


def scenario():
    from sim_speed import ring

    return ring(2, 3600.0)  # long enough for any -n at 200 Hz: seqs past the run's end are 'future'


# --------------------------------------------------------------------------- sender
def run_sender(args) -> int:
    import zenoh

    from cdus.core.schedule import total_ticks
    from cdus.sim.build import build_node, link_emulator_for
    from cdus.wire.messages import encode_omega

    sc = scenario()
    sender = sc.vehicles[0]
    s = open_session(Transport(mode="client", connect=(args.connect,), lease_ms=1000))
    try:
        # readiness: a token the receiver declares once the agent and the raw subscriber are up
        ready = threading.Event()
        ls = s.liveliness().declare_subscriber(ready_key(args.fleet), lambda smp: ready.set(), history=True)
        if not ready.wait(30):
            print("sender: the receiving agent never came up", file=sys.stderr)
            return 1
        raw_cc = zenoh.CongestionControl.BLOCK if args.raw_block else zenoh.CongestionControl.DEFAULT
        raw_pub = s.declare_publisher(raw_key(args.fleet), congestion_control=raw_cc)
        block = zenoh.CongestionControl.BLOCK  # as Agent.open declares its ω publisher
        our_key = keys.omega(args.fleet, sender.id, listeners_of(sc, sender.id))
        our_pub = s.declare_publisher(our_key, congestion_control=block, express=AGENT_EXPRESS)
        # odd seqs through a publisher with the other express setting: both, interleaved, same load
        other_pub = s.declare_publisher(our_key, congestion_control=block, express=not AGENT_EXPRESS)
        # genuine ω: the sender's own node steps each tick (not timed), so the receiver's node
        # takes every message (consistent send time, plausible ω) and does its full work
        node = build_node(sc, sender.id, link_emulator_for(sc), last_tick=total_ticks(sc.duration, 1 / sc.rates.control))
        size = len(encode_omega(node.step(0).omega))
        node = build_node(sc, sender.id, link_emulator_for(sc), last_tick=total_ticks(sc.duration, 1 / sc.rates.control))
        pad = b"\0" * (size - 12)
        period = 1.0 / args.hz
        t_next = time.perf_counter() + 0.1
        prep_raw, prep_ours = [], []  # stamp -> put(): what the sender does before Zenoh has the message
        sent_ours: list[int] = []  # by seq: the wall time (ns) just before encode_omega
        for i in range(args.n + WARMUP):
            _sleep_until(t_next)
            t = time.time_ns()
            payload = struct.pack("<qI", t, i) + pad
            t_put = time.time_ns()
            raw_pub.put(payload)
            prep_raw.append(t_put - t)
            out = node.step(i)
            _sleep_until(t_next + period / 2)
            t = time.time_ns()
            payload = encode_omega(out.omega)
            t_put = time.time_ns()
            (other_pub if i % 2 else our_pub).put(payload)
            prep_ours.append(t_put - t)
            sent_ours.append(t)
            t_next += period
        time.sleep(0.05)
        s.put(done_key(args.fleet), b"done")
        ls.undeclare()
    finally:
        s.close()
    json.dump({"prep_raw": prep_raw[WARMUP:], "prep_ours": prep_ours[WARMUP:], "sent_ours": sent_ours}, sys.stdout)
    return 0


def _sleep_until(t: float) -> None:
    d = t - time.perf_counter()
    if d > 0:
        time.sleep(d)


# --------------------------------------------------------------------------- receiver
def run_receiver(args) -> int:
    from vehicle_agent.agent import Agent

    sc = scenario()
    me = sc.vehicles[1].id
    transport = Transport(mode="client", connect=(args.connect,), lease_ms=1000)
    # lockstep: every sample through the one FIFO inbox the main thread blocks on (a realtime
    # agent takes ω from per-neighbour rings once per tick instead: its latency is the tick's)
    agent = Agent(sc, me, args.fleet, transport, clock="lockstep", log=lambda s: None)
    agent.clock.granted = agent.last_tick  # as if the world had granted the run: seqs within it are not 'future'
    raw_lat: list[int] = []
    node_lat: list[tuple[int, int]] = []  # (seq, when the node has taken the decoded message)
    wake_lat: list[tuple[int, int]] = []  # (seq, when the main loop's recv() returned the sample)
    inside: list[int] = []  # recv() return -> the node takes it (the agent's decode and validation)
    woke = [0]
    done = threading.Event()

    def on_raw(sample) -> None:
        t = time.time_ns()
        t0, i = struct.unpack_from("<qI", sample.payload.to_bytes())
        if i >= WARMUP:
            raw_lat.append(t - t0)

    agent.listeners = []  # the sender is a bare session, not an agent: nobody answers the link check
    agent.open()  # the agent's own inbox subscription, publishers and liveliness token
    on_message = agent.node.on_message

    def timed_on_message(msg, arrival=None):  # what Agent.feed calls once the ω is decoded
        reason = on_message(msg, arrival)
        t = time.time_ns()  # the node has taken it (or rejected it: counted below)
        if msg.seq >= WARMUP:
            node_lat.append((msg.seq, t))
            wake_lat.append((msg.seq, woke[0]))
            inside.append(t - woke[0])
        return reason

    agent.node.on_message = timed_on_message
    wake = lambda: agent.session.put(keys.wake(args.fleet, me), b"")  # noqa: E731 (unblocks recv)
    try:
        subs = [agent.session.declare_subscriber(raw_key(args.fleet), on_raw),
                agent.session.declare_subscriber(done_key(args.fleet), lambda s: (done.set(), wake()))]
        token = agent.session.liveliness().declare_token(ready_key(args.fleet))
        deadline = time.monotonic() + args.n / args.hz + 60
        while not done.is_set() and time.monotonic() < deadline:  # as the agent's main loop waits
            sample = agent.inbox.recv()
            woke[0] = time.time_ns()
            agent.feed(str(sample.key_expr), sample.payload.to_bytes())
        rejected = dict(agent.rejected)
        token.undeclare()
        del subs
    finally:
        agent.close()
    json.dump({"raw": raw_lat, "node": node_lat, "wake": wake_lat, "inside": inside, "rejected": rejected},
              sys.stdout)
    return 0


# --------------------------------------------------------------------------- the bench
def pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))] if xs else float("nan")


def run_bench(args) -> int:
    from cdus.app.launcher import ZENOH_RUNTIME
    from cdus.wire.messages import OmegaMsg, encode_omega

    from _fleet import load_line

    print(load_line())
    if args.zenoh_runtime == "launcher":
        if ROUTER_RUNTIME != "default":
            use_runtime(ROUTER_RUNTIME)  # this process is the router, on the launcher's runtime
    router = local_router()
    session = open_session(router)
    connect = client_of(router).connect[0]
    fleet = f"bench_lat_{os.getpid()}"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    if args.zenoh_runtime == "launcher":
        env.setdefault("ZENOH_RUNTIME", ZENOH_RUNTIME)
    common = ["--connect", connect, "--fleet", fleet, "-n", str(args.n), "--hz", str(args.hz)]
    if args.raw_block:
        common.append("--raw-block")
    me = [sys.executable, str(Path(__file__).resolve())]
    procs: list[subprocess.Popen] = []
    try:
        recv = subprocess.Popen(me + ["--role", "receiver", *common], stdout=subprocess.PIPE, env=env,
                                start_new_session=True, text=True)
        procs.append(recv)
        send = subprocess.Popen(me + ["--role", "sender", *common], stdout=subprocess.PIPE, env=env,
                                start_new_session=True, text=True)
        procs.append(send)
        budget = args.n / args.hz + 90
        sent = threading.Thread(target=lambda: setattr(send, "out", send.communicate(timeout=budget)[0]))
        sent.start()
        out, _ = recv.communicate(timeout=budget)
        sent.join(budget)
        if recv.returncode or send.returncode:
            print(f"receiver exited {recv.returncode}, sender {send.returncode}")
            return 1
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        session.close()
    res = json.loads(out)
    res.update(json.loads(send.out))
    sent = res["sent_ours"]
    other = {"node": [t - sent[seq] for seq, t in res["node"] if seq % 2],
             "wake": [t - sent[seq] for seq, t in res["wake"] if seq % 2]}
    res["node"] = [t - sent[seq] for seq, t in res["node"] if not seq % 2]  # the agent's publisher: even seqs
    res["wake"] = [t - sent[seq] for seq, t in res["wake"] if not seq % 2]
    size = len(encode_omega(OmegaMsg(0, args.n + WARMUP, time.time(), 1.0, -1.0)))
    rows = [("raw zenoh: put -> plain callback", res["raw"]),
            ("ours: encode -> inbox channel -> recv()", res["wake"]),
            ("ours: ... -> decoded, taken by the node", res["node"])]
    print(f"ω one-way latency, {args.hz:g} Hz, {size}-byte payloads, client -> router (this process) -> client, "
          f"ZENOH_RUNTIME {'as the launcher sets it' if args.zenoh_runtime == 'launcher' else 'zenoh default'}")
    print(f"{'path':<44} {'n':>5} {'p50 µs':>8} {'p90 µs':>8} {'p99 µs':>8} {'max µs':>8}")
    for name, xs in rows:
        us = [x / 1000 for x in xs]
        print(f"{name:<44} {len(us):5d} {pct(us, .5):8.1f} {pct(us, .9):8.1f} {pct(us, .99):8.1f} "
              f"{max(us, default=float('nan')):8.1f}")
    r50, o50, w50 = (pct([x / 1000 for x in res[k]], .5) for k in ("raw", "node", "wake"))
    r99, o99 = (pct([x / 1000 for x in res[k]], .99) for k in ("raw", "node"))
    print(f"ours / raw at p50: {o50 / r50:.2f}x, added at p50: {o50 - r50:+.1f} µs (target < 50 µs); "
          f"at p99: {o99 - r99:+.1f} µs; of that, reaching the main loop {w50 - r50:+.1f} µs at p50")
    x50 = pct([x / 1000 for x in other["node"]], .5)
    print(f"ω publisher express={AGENT_EXPRESS} (the agent's, even seqs) vs express={not AGENT_EXPRESS} (odd seqs), "
          f"same run: p50 {o50:.1f} vs {x50:.1f} µs to the node, p90 {pct([x / 1000 for x in res['node']], .9):.1f} "
          f"vs {pct([x / 1000 for x in other['node']], .9):.1f} µs")
    pr, po, inside = ([x / 1000 for x in res[k]] for k in ("prep_raw", "prep_ours", "inside"))
    print(f"where: sender stamp -> put(), raw p50 {pct(pr, .5):.1f} µs, ours (encode_omega) "
          f"p50 {pct(po, .5):.1f} µs; receiver recv() -> node (decode, validate) p50 {pct(inside, .5):.1f} µs, "
          f"p99 {pct(inside, .99):.1f} µs")
    if res["rejected"]:
        print(f"rejected by the agent: {res['rejected']}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-n", type=int, default=2000, help="messages of each kind (after %d warm-up)" % WARMUP)
    ap.add_argument("--hz", type=float, default=200.0, help="messages of each kind per second")
    ap.add_argument("--zenoh-runtime", choices=("launcher", "default"), default="launcher",
                    help="the children's ZENOH_RUNTIME: the launcher's (as agents run) or zenoh's default")
    ap.add_argument("--raw-block", action="store_true",
                    help="raw publisher with congestion control BLOCK too (default: zenoh's default, DROP)")
    ap.add_argument("--role", choices=("bench", "sender", "receiver"), default="bench", help=argparse.SUPPRESS)
    ap.add_argument("--connect", help=argparse.SUPPRESS)
    ap.add_argument("--fleet", help=argparse.SUPPRESS)
    args = ap.parse_args()
    return {"bench": run_bench, "sender": run_sender, "receiver": run_receiver}[args.role](args)


if __name__ == "__main__":
    sys.exit(main())

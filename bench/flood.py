"""A flood of valid-format stale ω on one key of a realtime fleet: what it costs its targets.

    python bench/flood.py                      # lake_circle, realtime, 45 s: flood from 10 s to 30 s
    python bench/flood.py --no-flood           # the same run without the flood (the baseline)
    python bench/flood.py --count 2000000 --seconds 20

Starts `cdus launch configs/lake_circle.toml --clock realtime` (bench/_fleet.py; the router
listens on a fresh tcp/127.0.0.1 port), then, from this process, a raw Zenoh client
(client mode, multicast scouting off, that endpoint only) puts as fast as it can the same
valid-format ω on the key of one vehicle (``--source``, default usv2): seq 0, t_send 0, so
every receiver rejects it as stale (or, past its rate, before decoding, as "rate"). The
flood is bounded in count (``--count``) and time (``--seconds``).

It prints, per phase (before / during / after the flood), the missed deadlines of each
target (the vehicles that listen to the source, from their stats messages) and of the
others, the targets' RSS, their reject counts by reason at the end, and the load average.
Figures are printed, never asserted: they depend on what else the machine runs.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time

from _fleet import REPO, Launch, load_line, role, rss_mb

import psutil
import zenoh

from cdus.scenario.config import load_scenario
from cdus.sim.build import listeners_of
from cdus.wire import keys
from cdus.wire.messages import OmegaMsg, encode_omega
from cdus.wire.schemas import decode_stats
from cdus.wire.transport import free_tcp_port
from cdus.wire.rejected import Rejected


def client(endpoint: str) -> zenoh.Config:
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    return conf


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--source", default="usv2", help="the vehicle whose ω key is flooded")
    ap.add_argument("--duration", type=float, default=45.0)
    ap.add_argument("--start", type=float, default=10.0, help="s of run before the flood")
    ap.add_argument("--seconds", type=float, default=20.0, help="at most this long a flood")
    ap.add_argument("--count", type=int, default=20_000_000, help="at most this many messages")
    ap.add_argument("--no-flood", action="store_true")
    args = ap.parse_args()

    sc = load_scenario(str(REPO / args.config))
    fleet = f"flood{int(time.time()) % 100000}"
    port = free_tcp_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    targets = listeners_of(sc, args.source)
    launch = ["launch", args.config, "--clock", "realtime", "--duration", str(args.duration), "--fleet", fleet,
              "-l", endpoint, "--rerun", "off", "-q", "--seed", "1", "--logs", tempfile.mkdtemp(prefix="flood"),
              "--insecure"]  # an open fleet: the flooder is an outsider without credentials
    stats: dict[str, object] = {}
    phase = {"name": "start"}
    missed_at: dict[str, dict[str, int]] = {}  # phase -> vehicle -> missed deadlines at its end
    rss: dict[str, list[float]] = {}
    flood = {"sent": 0, "seconds": 0.0}

    with Launch(launch, fleet=fleet) as la:
        if not la.up.wait(60):
            raise SystemExit("the fleet did not come up")
        session = zenoh.open(client(endpoint))
        sub = session.declare_subscriber(keys.any_stats(fleet),
                                         lambda s: stats.__setitem__(str(s.key_expr).rsplit("/", 1)[-1],
                                                                     decode_stats(s.payload.to_bytes())))
        agents = {}
        for p in la.processes():
            r = role(p)
            if r.startswith("agent:"):
                agents[r.split(":", 1)[1]] = p

        def missed() -> dict[str, int]:
            return {v: getattr(s, "missed_deadlines", 0) for v, s in stats.items() if not isinstance(s, Rejected)}

        launcher = psutil.Process(la.proc.pid)

        def cpu_now() -> dict[str, float]:
            out = {}
            for name, p in [("router", launcher), *agents.items()]:
                try:
                    t = p.cpu_times()
                    out[name] = t.user + t.system
                except psutil.Error:
                    pass
            return out

        cpu_at: dict[str, tuple[float, dict[str, float]]] = {"start": (time.monotonic(), cpu_now())}

        def sample_rss(name: str, until: float) -> None:
            while time.monotonic() < until and la.proc.poll() is None:
                for v in targets:
                    if v in agents and (m := rss_mb(agents[v])) is not None:
                        rss.setdefault(name, []).append(m)
                time.sleep(0.5)
            cpu_at[name] = (time.monotonic(), cpu_now())

        t_up = time.monotonic()
        sample_rss("before", t_up + args.start)
        missed_at["before"] = missed()
        if not args.no_flood:
            key = keys.omega(fleet, args.source, targets)
            payload = encode_omega(OmegaMsg(sc.ids.index(args.source), 0, 0.0, 0.0, -1.0))
            pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.DROP)
            t_end = time.monotonic() + args.seconds
            t0 = time.monotonic()

            def run_flood() -> None:
                n = 0
                while n < args.count and time.monotonic() < t_end:
                    for _ in range(1000):
                        pub.put(payload)
                    n += 1000
                flood["sent"], flood["seconds"] = n, time.monotonic() - t0

            th = threading.Thread(target=run_flood, daemon=True)
            th.start()
            sample_rss("during", t_end)
            th.join()
            pub.undeclare()
        else:
            sample_rss("during", time.monotonic() + args.seconds)
        missed_at["during"] = missed()
        sample_rss("after", time.monotonic() + args.duration)
        la.wait(timeout=120)
        missed_at["after"] = missed()
        sub.undeclare()
        session.close()

    print(f"{args.config}, realtime, seed 1, {args.duration:g} s; source of the flooded key: {args.source}; "
          f"targets (its listeners): {', '.join(targets)}")
    if args.no_flood:
        print("no flood (baseline)")
    else:
        rate = flood["sent"] / flood["seconds"] if flood["seconds"] else 0.0
        print(f"flood: {flood['sent']} stale ω in {flood['seconds']:.1f} s ({rate:,.0f} per s) "
              f"from {args.start:g} s of wall time after the fleet was up")
    prev: dict[str, int] = {}
    print(f"{'phase':<8} {'missed (targets)':>17} {'missed (others)':>16} {'target RSS MB min/max':>22} "
          f"{'CPU % per target':>17} {'CPU % router':>13}")
    prev_cpu = cpu_at["start"]
    for name in ("before", "during", "after"):
        t1, c1 = cpu_at.get(name, prev_cpu)
        t0c, c0 = prev_cpu
        prev_cpu = (t1, c1)
        span = max(t1 - t0c, 1e-9)
        per_target = [100 * (c1[v] - c0[v]) / span for v in targets if v in c1 and v in c0]
        cpu_t = f"{sum(per_target) / len(per_target):.0f}" if per_target else "-"
        cpu_r = f"{100 * (c1['router'] - c0['router']) / span:.0f}" if "router" in c1 and "router" in c0 else "-"
        m = missed_at.get(name, {})
        d = {v: m.get(v, 0) - prev.get(v, 0) for v in m}
        prev = m
        tm = sum(x for v, x in d.items() if v in targets)
        om = sum(x for v, x in d.items() if v not in targets)
        r = rss.get(name, [])
        rr = f"{min(r):.1f}/{max(r):.1f}" if r else "-"
        print(f"{name:<8} {tm:>17} {om:>16} {rr:>22} {cpu_t:>17} {cpu_r:>13}")
    for v in targets:
        s = stats.get(v)
        if s is not None and not isinstance(s, Rejected):
            print(f"{v}: rejected {s.rejected}, by reason {dict(sorted(s.rejected_by_reason.items()))}, "
                  f"ticks {s.tick}, missed {s.missed_deadlines}")
    metrics = la.lines
    done = [ln for ln in metrics if "done after" in ln]
    for ln in done:
        print("  " + ln.strip())
    print(load_line())


if __name__ == "__main__":
    main()

"""What securing a loopback fleet costs: authentication + the access-control list, open
(`--insecure`) vs secured (the default, `--secure`), in one run (alternating, so both see the same machine).

    python bench/secure_cost.py                       # lake_circle 60 s lockstep x2 each; 2000 ω at 200 Hz x2 each
    python bench/secure_cost.py --duration 120 --repeat 3 -n 5000

1. Lockstep speed: the real command, `cdus launch CONFIG --clock lockstep --links router
   --duration D -q`, with `--insecure` and `--secure`; "run s" is the metrics' wall_s (every
   vehicle up -> metrics), best of --repeat, and its ratio secured / open.
2. ω latency through the router: this process is the router (open, or with the run's
   credentials and access-control list exactly as `cdus launch --secure` builds them); a
   sender process publishes ω-sized payloads on vehicle a's ω key to b (as vehicle-a when
   secured, congestion control BLOCK as the agent) every 1/hz s, the send time in the first
   8 bytes; a receiver process (vehicle-b) stamps their arrival. p50 / p99 one-way latency
   (one machine, one clock) and the ratio secured / open.

Figures are printed, never asserted: this machine is noisy.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from _fleet import REPO, Launch, load_line

from cdus.app.credentials import make_credentials
from cdus.app.launcher import ZENOH_RUNTIME
from cdus.wire import keys
from cdus.wire.access import vehicle_role
from cdus.wire.transport import ROUTER_EXTRA, Transport, client_of, free_tcp_port, open_session

OMEGA_BYTES = 42  # an ω message on the wire (cdus.wire.messages, docs/link.md)
WARMUP = 50


# --------------------------------------------------------------------------- lockstep speed
def lockstep_once(config: str, duration: float, work: Path, tag: str, secure: bool) -> float:
    run = work / tag
    run.mkdir()
    metrics = run / "metrics.json"
    fleet = f"bench_sec_{os.getpid()}_{tag}"
    args = ["launch", config, "--clock", "lockstep", "--links", "router", "--duration", f"{duration:g}", "-q",
            "--rerun", "off", "--fleet", fleet, "--logs", str(run), "--metrics-out", str(metrics)]
    args.append("--secure" if secure else "--insecure")  # secured is the default; open needs --insecure
    with Launch(args, fleet=fleet) as la:
        rc = la.wait(timeout=900)
    m = json.loads(metrics.read_text()) if metrics.exists() else {}
    if rc != 0 or not m.get("wall_s") or m.get("completed") is False:
        print(f"  {tag}: exit {rc}, completed {m.get('completed')}; output ends:\n    " + "\n    ".join(la.lines[-8:]))
        return math.inf
    return float(m["wall_s"])


# --------------------------------------------------------------------------- ω latency
def client(endpoint: str, config_file: str | None):
    import zenoh

    if config_file:
        conf = zenoh.Config.from_file(config_file)
        conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
        conf.insert_json5("scouting/multicast/enabled", "false")
        return zenoh.open(conf)
    return open_session(Transport(mode="client", connect=(endpoint,), lease_ms=1000))


def run_receiver(a: argparse.Namespace) -> int:
    s = client(a.connect, a.zconf)
    lat: list[float] = []
    done = threading.Event()

    def on(sample) -> None:
        now = time.time_ns()
        sent = struct.unpack_from("<q", sample.payload.to_bytes())[0]
        lat.append((now - sent) / 1e3)
        if len(lat) >= a.n + WARMUP:
            done.set()

    sub = s.declare_subscriber(keys.inbox(a.fleet, "b"), on)
    token = s.liveliness().declare_token(keys.alive(a.fleet, "b", str(s.zid())))
    ok = done.wait(timeout=a.n / a.hz * 5 + 30)
    token.undeclare()
    sub.undeclare()
    s.close()
    print(json.dumps({"ok": ok, "us": lat[WARMUP:]}))
    return 0


def run_sender(a: argparse.Namespace) -> int:
    import zenoh

    s = client(a.connect, a.zconf)
    ready = threading.Event()
    ls = s.liveliness().declare_subscriber(keys.alive_of(a.fleet, "b"), lambda smp: ready.set(), history=True)
    if not ready.wait(timeout=30):
        print("no receiver", file=sys.stderr)
        return 1
    time.sleep(0.2)  # the receiver's subscription reaches the router's tables
    pub = s.declare_publisher(keys.omega(a.fleet, "a", ["b"]), congestion_control=zenoh.CongestionControl.BLOCK)
    pad = bytes(OMEGA_BYTES - 8)
    period = 1.0 / a.hz
    t = time.perf_counter()
    for _ in range(a.n + WARMUP + 20):  # a few extra: the receiver stops at n + WARMUP
        t += period
        while (d := t - time.perf_counter()) > 0:
            time.sleep(min(d, 0.002) if d > 0.0005 else 0)
        pub.put(struct.pack("<q", time.time_ns()) + pad)
    time.sleep(0.5)
    ls.undeclare()
    s.close()
    return 0


def latency_once(n: int, hz: float, work: Path, tag: str, secure: bool) -> list[float]:
    fleet = f"bench_sec_{os.getpid()}_{tag}"
    port = free_tcp_port()
    listen = (f"tcp/127.0.0.1:{port}",)
    extra = ROUTER_EXTRA
    zconf = {"a": None, "b": None}
    if secure:
        cred = make_credentials(work / tag, fleet, {"a": ["b"], "b": ["a"]}, listen, "password")
        extra = extra + cred.router_extra()
        zconf = {v: str(cred.file(vehicle_role(v))) for v in ("a", "b")}
    router = open_session(Transport(mode="router", listen=listen, extra=extra))
    endpoint = client_of(Transport(mode="router", listen=listen)).connect[0]
    env = {**os.environ, "ZENOH_RUNTIME": os.environ.get("ZENOH_RUNTIME", ZENOH_RUNTIME), "PYTHONUNBUFFERED": "1"}
    common = ["--connect", endpoint, "--fleet", fleet, "-n", str(n), "--hz", str(hz)]
    procs = []
    try:
        rx = subprocess.Popen([sys.executable, __file__, "--role", "receiver", *common,
                               *(["--zconf", zconf["b"]] if zconf["b"] else [])],
                              stdout=subprocess.PIPE, text=True, env=env, start_new_session=True)
        procs.append(rx)
        tx = subprocess.Popen([sys.executable, __file__, "--role", "sender", *common,
                               *(["--zconf", zconf["a"]] if zconf["a"] else [])], env=env, start_new_session=True)
        procs.append(tx)
        out, _ = rx.communicate(timeout=n / hz * 5 + 60)
        tx.wait(timeout=30)
    finally:
        for p in procs:
            if p.poll() is None:
                os.killpg(p.pid, 9)
                p.wait()
        router.close()
    res = json.loads(out.strip().splitlines()[-1])
    if not res["ok"]:
        print(f"  {tag}: only {len(res['us'])} of {n} messages arrived")
    return res["us"]


def pct(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))] if xs else math.nan


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--role", choices=("bench", "sender", "receiver"), default="bench")
    ap.add_argument("--connect")
    ap.add_argument("--fleet")
    ap.add_argument("--zconf")
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--duration", type=float, default=60.0, help="simulated seconds per lockstep run")
    ap.add_argument("--repeat", type=int, default=2, help="runs of each kind (alternating open / secured)")
    ap.add_argument("-n", type=int, default=2000, help="ω messages per latency run")
    ap.add_argument("--hz", type=float, default=200.0)
    a = ap.parse_args()
    if a.role == "receiver":
        return run_receiver(a)
    if a.role == "sender":
        return run_sender(a)
    config = str((REPO / a.config).resolve()) if not os.path.isabs(a.config) else a.config
    print(load_line())
    with tempfile.TemporaryDirectory(prefix="cdus-sec-") as tmp:
        work = Path(tmp)
        speed: dict[bool, list[float]] = {False: [], True: []}
        for k in range(a.repeat):
            for secure in (False, True):
                speed[secure].append(lockstep_once(config, a.duration, work, f"ls{k}{'s' if secure else 'o'}", secure))
        print(f"lockstep {Path(config).stem}, {a.duration:g} s simulated, --links router, best of {a.repeat}:")
        for secure in (False, True):
            best = min(speed[secure])
            print(f"  {'secured' if secure else 'open':<8} run {best:6.2f} s  {a.duration / best:6.1f}x real time  "
                  f"(runs: {', '.join(f'{x:.2f}' for x in speed[secure])})")
        ratio_speed = min(speed[True]) / min(speed[False])
        print(f"  run time secured / open: {ratio_speed:.3f}")

        lat: dict[bool, list[float]] = {False: [], True: []}
        for k in range(a.repeat):
            for secure in (False, True):
                lat[secure] += latency_once(a.n, a.hz, work, f"lat{k}{'s' if secure else 'o'}", secure)
        print(f"ω one-way latency through the router, {a.n} x {a.repeat} messages at {a.hz:g} Hz (µs):")
        for secure in (False, True):
            xs = lat[secure]
            print(f"  {'secured' if secure else 'open':<8} p50 {pct(xs, 0.5):7.1f}  p90 {pct(xs, 0.9):7.1f}  "
                  f"p99 {pct(xs, 0.99):7.1f}  mean {statistics.fmean(xs) if xs else math.nan:7.1f}  ({len(xs)} samples)")
        print(f"  p50 secured / open: {pct(lat[True], 0.5) / pct(lat[False], 0.5):.3f}; "
              f"p99 secured / open: {pct(lat[True], 0.99) / pct(lat[False], 0.99):.3f}")
    return 0


if __name__ == "__main__":
    t0 = time.perf_counter()
    rc = main()
    if "--role" not in sys.argv:
        print(f"(bench took {time.perf_counter() - t0:.0f} s)")
    sys.exit(rc)

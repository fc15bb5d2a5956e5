"""A flood of valid commands (ground credentials) or of queries (a vehicle's credentials) against a
secured lockstep fleet: what it costs the fleet (docs/ground_station.md, "Several ground stations").

    python bench/command_flood.py                      # lake_circle, lockstep: 8 s quiet, 8 s of gains flood
    python bench/command_flood.py --what queries       # world/status + world/last/* asked as vehicle-usv1
    python bench/command_flood.py --seconds 20 --inflight 64 --restart usv2

Starts `cdus launch` (secured, the default; bench/_fleet.py), then from this process a Zenoh
client with the run's ground credentials (or usv1's for ``--what queries``) asks, with at most
``--inflight`` queries waiting for their answer, as fast as the world answers: `gains c=<the
configured c>` for every vehicle (a no-op: the run's result is the same), or the world's status
and every vehicle's last telemetry. It prints, for the quiet window before the flood and for
the flood, the simulated seconds per wall second (from the world's status) and the world's CPU
seconds per wall second, then the answers by outcome, the settings reply's size and the number
of events the world sent. ``--restart V`` restarts a vehicle after the flood and times its
answer and the new process's CPU (it is sent the command list: the whole of it before the fix).
Figures are printed, never asserted: they depend on what else the machine runs.
"""

from __future__ import annotations

import argparse
import collections
import os
import tempfile
import threading
import time
from pathlib import Path

from _fleet import Launch, load_line, role

import zenoh

from cdus.scenario.config import load_scenario
from cdus.wire import keys
from cdus.wire.rejected import Rejected
from cdus.wire.messages import encode_control
from cdus.wire.schemas import decode_reply, decode_status
from cdus.wire.transport import Transport, free_tcp_port, open_session
from ground_station.console import GroundStation


class WorldClock:
    """The world's simulated time, from its status (published about once a second)."""

    def __init__(self, session, fleet: str):
        self.t = 0.0
        self.events = 0
        self.sub = session.declare_subscriber(keys.world_status(fleet), self._on)
        self.ev = session.declare_subscriber(keys.world_events(fleet), lambda s: self._count())

    def _count(self) -> None:
        self.events += 1

    def _on(self, sample) -> None:
        st = decode_status(sample.payload.to_bytes())
        if not isinstance(st, Rejected):
            self.t = st.t


def world_cpu(la: Launch) -> float:
    for p in la.processes():
        if role(p) == "world":
            t = p.cpu_times()
            return t.user + t.system
    return float("nan")


def window(la: Launch, clock: WorldClock, seconds: float) -> tuple[float, float]:
    """(simulated s per wall s, world CPU s per wall s) over ``seconds`` of wall time."""
    t0, c0, w0 = clock.t, world_cpu(la), time.monotonic()
    time.sleep(seconds)
    dw = time.monotonic() - w0
    return (clock.t - t0) / dw, (world_cpu(la) - c0) / dw


def flood(session, fleet: str, what: str, payload: bytes, seconds: float, inflight: int) -> collections.Counter:
    """Ask as fast as answers come, at most ``inflight`` waiting; count the answers by outcome."""
    out: collections.Counter = collections.Counter()
    slots = threading.Semaphore(inflight)
    lock = threading.Lock()

    def on_reply(r) -> None:
        if r.ok is None:
            word = "error"
        elif what == "commands":
            rep = decode_reply(r.ok.payload.to_bytes())
            word = "unreadable" if isinstance(rep, Rejected) else rep.status if rep.status == "applied" else (
                "refused: " + rep.reason.split(":")[0])
        else:
            word = "answered"
        with lock:
            out[word] += 1

    def done() -> None:
        slots.release()

    end = time.monotonic() + seconds
    asked = 0
    keys_asked = ([keys.world_command(fleet, keys.GROUND)] if what == "commands"
                  else [keys.world_status(fleet), keys.world_last(fleet, "*")])
    while time.monotonic() < end:
        if not slots.acquire(timeout=0.5):
            continue
        key = keys_asked[asked % len(keys_asked)]
        session.get(key, zenoh.handlers.Callback(on_reply, done), payload=payload if what == "commands" else None,
                    timeout=10.0)
        asked += 1
    for _ in range(inflight):  # the last answers
        slots.acquire(timeout=10.0)
    out["asked"] = asked
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--what", choices=("commands", "queries"), default="commands")
    ap.add_argument("--quiet", type=float, default=8.0, help="s of run measured before the flood")
    ap.add_argument("--seconds", type=float, default=8.0, help="s of flood")
    ap.add_argument("--inflight", type=int, default=32, help="queries waiting for their answer at most")
    ap.add_argument("--restart", default=None, help="restart this vehicle after the flood")
    a = ap.parse_args()
    print(load_line())
    sc = load_scenario(a.config)
    c = sc.vehicles[0].c
    work = Path(tempfile.mkdtemp(prefix="command_flood_"))
    fleet = f"bench_flood_{os.getpid()}"
    port = free_tcp_port()
    args = ["launch", a.config, "--clock", "lockstep", "--duration", "100000", "-q", "--rerun", "off",
            "--fleet", fleet, "--logs", str(work), "--listen", f"tcp/127.0.0.1:{port}"]
    with Launch(args, fleet=fleet) as la:
        if not la.up.wait(120):
            raise SystemExit("the fleet did not come up")
        gs = GroundStation(fleet, Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",),
                                            config_file=str(work / "secure" / "ground.json5")), name="bench")
        gs.open()
        role_file = "ground.json5" if a.what == "commands" else "vehicle-usv1.json5"
        asker = open_session(Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",),
                                       config_file=str(work / "secure" / role_file)))
        clock = WorldClock(gs.session, fleet)
        try:
            gs.wait_for_status(10)
            time.sleep(2.0)
            rate0, cpu0 = window(la, clock, a.quiet)
            ev0 = clock.events
            payload = encode_control("set_gains", gains={"c": c}, vehicle="", name="flood")
            t0, w0, cw0 = clock.t, time.monotonic(), world_cpu(la)
            answers = flood(asker, fleet, a.what, payload, a.seconds, a.inflight)
            dw = time.monotonic() - w0
            time.sleep(1.5)  # the status after the flood
            rate1, cpu1 = (clock.t - t0) / (dw + 1.5), (world_cpu(la) - cw0) / (dw + 1.5)
            settings = list(gs.session.get(keys.world_settings(fleet), timeout=10.0))
            size = len(settings[0].ok.payload.to_bytes()) if settings and settings[0].ok is not None else None
            print(f"{a.config}, lockstep, secured, flood of {a.what} for {dw:.1f} s, {a.inflight} in flight")
            print(f"  quiet: {rate0:6.2f} simulated s / s, world CPU {cpu0:.2f} s / s")
            print(f"  flood: {rate1:6.2f} simulated s / s, world CPU {cpu1:.2f} s / s   "
                  f"(ratio {rate1 / rate0 if rate0 else float('nan'):.2f})")
            print(f"  answers: {dict(answers)} ({answers['asked'] / dw:.0f} asked / s)")
            print(f"  settings reply: {size} bytes; events sent during the flood: {clock.events - ev0}")
            if a.restart:
                cpu_before = {p.pid for p in la.processes()}
                r0 = time.monotonic()
                ans = gs.command("restart", vehicle=a.restart, timeout=60.0)
                dt = time.monotonic() - r0
                time.sleep(3.0)
                new = [p for p in la.processes() if p.pid not in cpu_before and role(p) == f"agent:{a.restart}"]
                cpu = sum(p.cpu_times().user + p.cpu_times().system for p in new)
                print(f"  restart {a.restart}: {ans.outcome} in {dt:.2f} s; the new process's CPU 3 s later: "
                      f"{cpu:.2f} s")
        finally:
            clock.sub.undeclare()
            asker.close()
            gs.close()
    print(load_line())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

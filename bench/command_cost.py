"""What one more command costs the world, and a restarted vehicle, as a flood's list grows
(docs/ground_station.md, "A flood"). In-process, no network: the world's main thread is given
gains commands through its public door World.ask, as its command queryable would (the ground credentials' rate
lifted, so the cost of a command itself is what is measured), each on a tick of its own (the
grant moved by one between two), as the fleet moves on during a flood.

    python bench/command_cost.py                  # 1,000 / 5,000 / 18,144 commands (the issue's flood)
    PYTHONPATH=/tmp/old python bench/command_cost.py   # the same against another checkout (one with World.ask)

Prints, at each size, the world's CPU per command over the last 500, the settings reply's size
and what a vehicle restarted then is sent and costs its node (its schedule of gains changes,
as the agent fills it). Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

if "PYTHONPATH" not in os.environ:  # this checkout's packages, unless another one is named
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from cdus.scenario.config import load_scenario  # noqa: E402
from cdus.sim.build import build_node  # noqa: E402
from cdus.core.link import IdealLink  # noqa: E402
from cdus.sim.lockstep import CatchUp  # noqa: E402
from cdus.wire import keys  # noqa: E402
from cdus.wire.messages import CTL_OPS, decode_control, encode_control  # noqa: E402
from cdus.wire.transport import Transport  # noqa: E402
from world_sim.world import World  # noqa: E402

FLEET = "bench"


class Sink:
    def __init__(self):
        self.puts = []

    def put(self, *a, **k) -> None:
        self.puts.append(a)


class Session(Sink):
    pass


def world(config: str) -> World:
    w = World(load_scenario(config), FLEET, Transport(), clock="lockstep", log=lambda s: None, duration=1e5)
    w.session = Session()
    w.pub_ctl, w.pub_launcher, w.pub_status, w.pub_events = Sink(), Sink(), Sink(), Sink()
    w._wake = lambda payload=b"": None
    for vid in w.ids:
        w.alive(vid, True)
    w.started = True
    w.lockstep.start()
    w.clock.act(w.lockstep.poll())
    if hasattr(w, "_command_quota"):
        from cdus.core.quota import Quota
        w._command_quota = Quota(1e12, 10**9)
        w._event_quotas["change"] = Quota(1e12, 10**9)
    return w


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--sizes", default="1000,5000,18144")
    a = ap.parse_args()
    import world_sim.world as ws
    print(f"world_sim from {ws.__file__}")
    payload = encode_control("set_gains", gains={"c": 2.0}, vehicle="", name="flood")
    for size in (int(x) for x in a.sizes.split(",")):
        w = world(a.config)
        t_last = 0.0
        for i in range(size):
            w.lockstep.granted += 1
            t0 = time.process_time() if i >= size - 500 else 0.0
            w.ask(keys.world_command(FLEET, keys.GROUND), payload)  # queued, then answered by a pass of the main thread
            if i >= size - 500:
                t_last += time.process_time() - t0
        s = w.ask(keys.world_settings(FLEET))
        j = w.index["usv2"]
        w.lockstep.acked[j] = w.lockstep.granted - 10
        before = len(w.session.puts)
        w.clock.act([CatchUp(j)])
        sent = [p for key, p in w.session.puts[before:] if key == keys.ctl(FLEET, ["usv2"])]
        node = build_node(w.scenario, "usv2", IdealLink())
        t0 = time.process_time()
        for p in sent:  # as the agent does with each: decode it, then schedule its gains
            c = decode_control(p, CTL_OPS)
            if c.op == "gains":
                node.set_gains(node.vehicle.k, float(c.fields["gains"]["c"]), c.fields["tick"])
        node.step(w.lockstep.granted - 9)
        t_node = time.process_time() - t0
        print(f"  {size:6d} commands: world {t_last / 500 * 1e6:8.0f} µs CPU per command (the last 500); "
              f"settings reply {len(s.replies[0][1]):8d} bytes; a restart then is sent {len(sent):6d} "
              f"commands, {t_node * 1e3:7.1f} ms of its node's CPU")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

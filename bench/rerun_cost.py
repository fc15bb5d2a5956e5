"""What does Rerun cost the world? CPU with and without the Rerun sink, 10 vehicles at 50 Hz.

    python bench/rerun_cost.py                 # ring of 10, 120 simulated s, best of 3
    python bench/rerun_cost.py --vehicles 20 --flush 2,5,10

Target (issue "The world in Rerun"): logging takes at most 10% of the world's CPU at 10
vehicles and 50 Hz control. The world here is the in-process fleet: every vehicle's
controller plus the recorder (the world process alone costs about as much per simulated
second at this size: ~0.5 s of CPU for a 20 s lockstep run of this ring).

Two ways of counting, each case in a fresh process (imports excluded):

- split (the verdict): in one run with the sink, logging = the main thread's CPU inside
  the sink's methods + the CPU of every other thread (Rerun's encoder and file writer; the
  fleet itself has no threads); the world = the main thread's CPU outside the sink. Both
  come from the same run, so a busy machine shifts them together.
- difference: (CPU with the sink) - (CPU of a separate run with NullSink); simple, but on
  a shared machine the two runs' noise does not cancel.

share = logging / (world + logging). ``start`` (static paths, markers, blueprint) is paid
once per run and shown apart. The sink is closed inside the timing (last batch, flush,
file footer). Figures are printed, never asserted: this machine is noisy.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

from sim_speed import ring  # bench/sim_speed.py: a ring fleet of USVs and UAVs

TARGET = 0.10


def one(vehicles: int, duration: float, flush: float | None, path: str) -> dict:
    """CPU of one run (``flush`` None: no sink), split between the world and the sink."""
    from cdus.sim.fleet import InProcessFleet
    from cdus.sim.sink import NullSink
    from world_sim.recording import Target
    from world_sim.rerun_sink import RerunSink

    sc = ring(vehicles, duration)
    spent = {"start": 0.0, "sink": 0.0}
    with open(os.devnull, "w") as quiet:
        sink = NullSink() if flush is None else RerunSink([Target("save", path)], flush_every=flush, out=quiet)
        for name in ("start", "update", "close"):
            method = getattr(sink, name)

            def timed(*a, _m=method, _k="start" if name == "start" else "sink"):
                c = time.thread_time()
                try:
                    return _m(*a)
                finally:
                    spent[_k] += time.thread_time() - c

            setattr(sink, name, timed)
        fleet = InProcessFleet(sc, sink=sink)
        t0, th0 = time.process_time(), time.thread_time()
        fleet.run()
        sink.close()
        cpu, main = time.process_time() - t0, time.thread_time() - th0
    return {"cpu": cpu, "world": main - spent["start"] - spent["sink"], "start": spent["start"],
            "sink": spent["sink"], "threads": cpu - main, "bytes": os.path.getsize(path) if flush else 0}


def measure(args: argparse.Namespace, flush: float | None, path: str) -> dict:
    """Best of ``--repeat`` runs: the lowest total CPU (the least disturbed run)."""
    best: dict = {}
    for _ in range(args.repeat):
        cmd = [sys.executable, __file__, "--one", "off" if flush is None else str(flush), "--out", path,
               "--vehicles", str(args.vehicles), "--duration", str(args.duration)]
        r = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
        if not best or r["cpu"] < best["cpu"]:
            best = r
    return best


def main() -> None:
    from world_sim.rerun_sink import FLUSH_EVERY

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--vehicles", type=int, default=10)
    ap.add_argument("--duration", type=float, default=120.0, help="simulated seconds")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--flush", default=f"0.5,2,{FLUSH_EVERY:g},10",
                    help="flush_every values to compare, simulated s (default: %(default)s)")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(one(args.vehicles, args.duration, None if args.one == "off" else float(args.one), args.out)))
        return
    n, dur = args.vehicles, args.duration
    ms = lambda x: x / dur * 1e3  # noqa: E731 - CPU seconds -> ms per simulated second
    print(f"ring of {n} ({n - n // 2} USVs, {n // 2} UAVs), 50 Hz control, {dur:g} simulated s, "
          f"best of {args.repeat}; CPU in ms per simulated second")
    with tempfile.TemporaryDirectory() as tmp:
        base = measure(args, None, os.path.join(tmp, "off"))
        print(f"{'sink':<30} {'world':>6} {'sink':>6} {'rerun':>6} {'start':>6} {'share':>6} {'verdict':>7}"
              f" {'diff':>6} {'share':>6} {'.rrd':>7}")
        print(f"{'off (NullSink)':<30} {ms(base['cpu']):6.2f}")
        for every in (float(x) for x in args.flush.split(",")):
            r = measure(args, every, os.path.join(tmp, f"flush{every:g}.rrd"))
            steady = r["sink"] + r["threads"]
            share = steady / (r["world"] + steady)
            diff = max(0.0, r["cpu"] - base["cpu"])
            label = f"save, flush every {every:g} s" + (" (default)" if every == FLUSH_EVERY else "")
            print(f"{label:<30} {ms(r['world']):6.2f} {ms(r['sink']):6.2f} {ms(r['threads']):6.2f} "
                  f"{r['start'] * 1e3:4.0f}ms {share:6.1%} {'ok' if share <= TARGET else 'OVER':>7} "
                  f"{ms(diff):6.2f} {diff / r['cpu']:6.1%} {r['bytes'] / 1e6:5.1f}MB")
    print("world: main thread outside the sink; sink: main thread in update/close; rerun: Rerun's threads; "
          "start: once per run (ms)\nshare = (sink + rerun) / (world + sink + rerun), the verdict against "
          f"{TARGET:.0%}; diff, share: CPU with the sink - CPU of the NullSink run, and its share")


if __name__ == "__main__":
    main()

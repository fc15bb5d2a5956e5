"""What does publishing the fleet to ROS 2 cost a lockstep run? Its speed and the agents' CPU per
tick with `cdus launch --ros2` and without, in one run, interleaved so the machine's load falls
on both alike.

    python bench/ros2_overhead.py                           # lake_circle, 20 s simulated, 3 rounds
    python bench/ros2_overhead.py --duration 60 --repeat 2

Each round runs `cdus launch CONFIG --clock lockstep` as is, then with --ros2 (the bridge,
docs/ros2.md), and prints for each: ticks/s and x real time (the metrics' wall_s), the agents'
median CPU per tick (their logs' "µs per tick"), the bridge's CPU, and whether the trace and
metrics are bit-identical to `cdus sim`'s (the bridge changes nothing of the run). Then the
ratios with/without, per round and their median: speed (< 1: slower) and agents' CPU per tick
(> 1: dearer). The load average goes with every figure (this 2-core box is shared). Figures are
printed, never asserted. bench/lockstep_speed.py --ros2 measures the same beside the raw ring.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from _fleet import REPO, load_line

from cdus.scenario.config import load_scenario
from lockstep_speed import cpu_figures, identical, load, lockstep, reference

CASES = {"as is": [], "--ros2": ["--ros2"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--duration", type=float, default=20.0, help="simulated seconds of each run")
    ap.add_argument("--repeat", type=int, default=3, help="rounds (as is, --ros2)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    config = str((REPO / args.config).resolve()) if not os.path.isabs(args.config) else args.config
    sc = load_scenario(config)
    ticks = round(args.duration * sc.rates.control) + 1
    print(load_line())
    print(f"{sc.name}: {len(sc.vehicles)} vehicles, control {sc.rates.control:g} Hz, {args.duration:g} s simulated "
          f"({ticks} ticks), {args.repeat} rounds, lockstep through the router, rerun off")
    speed: dict[str, list[float]] = {c: [] for c in CASES}
    cpu: dict[str, list[float]] = {c: [] for c in CASES}
    with tempfile.TemporaryDirectory(prefix="cdus-r2-") as tmp:
        work = Path(tmp)
        ref = reference(config, args.duration, [], work / "ref")  # the bridge changes nothing of the run
        for r in range(args.repeat):
            for k, (case, extra) in enumerate(CASES.items()):
                out = work / f"r{r}c{k}"
                wall, trace, m = lockstep(config, args.duration, extra, out, "router", "off")
                per_tick, bridge = cpu_figures(out)
                speed[case].append(ticks / wall)
                cpu[case].append(float(np.median(per_tick)) if per_tick else float("nan"))
                print(f"  {case:<7} {ticks / wall:6.0f} ticks/s = {ticks / wall / sc.rates.control:5.1f}x real time, "
                      f"agents {cpu[case][-1]:4.0f} µs CPU/tick"
                      + (f", bridge {bridge:.2f} s CPU" if bridge is not None else "")
                      + f"  ({load()}; {identical(trace, m, *ref)})", flush=True)
    s = [b / a for a, b in zip(speed["as is"], speed["--ros2"])]
    c = [b / a for a, b in zip(cpu["as is"], cpu["--ros2"])]
    print("with --ros2 / without, per round:")
    print(f"  speed         {', '.join(f'{x:.2f}' for x in s)} (median {np.median(s):.2f})")
    print(f"  agents' CPU   {', '.join(f'{x:.2f}' for x in c)} (median {np.median(c):.2f}) per tick")
    print(f"{load_line()}\n(bench took {time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()

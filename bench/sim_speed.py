"""How fast is `cdus sim`? Simulated seconds per wall second, in one process.

    python bench/sim_speed.py            # lake_circle ideal + dynamic, then ring fleets of 6/60/600

Targets (issue 2): >= 100x real time for lake_circle with ideal plants at 50 Hz control,
>= 20x with vehicle models; the ring sweep shows how the cost grows with fleet size.
Figures are printed, never asserted: this machine is noisy. Each case is the best of
``--repeat`` runs.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages, not an installed copy

from cdus.scenario.config import load_scenario, parse_scenario  # noqa: E402
from cdus.sim.fleet import InProcessFleet  # noqa: E402


def speed(scenario, repeat: int) -> tuple[float, float]:
    best = math.inf
    for _ in range(repeat):
        fleet = InProcessFleet(scenario)
        t0 = time.perf_counter()
        fleet.run()
        best = min(best, time.perf_counter() - t0)
    return scenario.duration / best, best


def ring(n: int, duration: float, plant: str = "ideal") -> object:
    vehicles = []
    for j in range(n):
        kind = "usv" if j % 2 == 0 else "uav"
        center = [0.0, 0.0] if kind == "usv" else [0.0, 0.0, 20.0]
        vehicles.append({
            "id": f"{kind}{j}", "kind": kind, "phase": 2 * math.pi * j / n,
            "path": {"family": "circle", "center": center, "radius": 10.0},
            "start": {"region_min": [-20.0, -20.0] + ([10.0] if kind == "uav" else []),
                      "region_max": [20.0, 20.0] + ([30.0] if kind == "uav" else [])},
        })
    return parse_scenario({
        "scenario": {"name": f"ring{n}", "duration": duration, "seed": 1},
        "rates": {"physics": 200.0, "control": 50.0, "broadcast": 50.0},
        "defaults": {"plant": plant}, "graph": {"topology": "ring"}, "vehicle": vehicles,
    }, source=f"<ring {n}>")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--sizes", default="6,60,600")
    args = ap.parse_args()
    print(f"{'case':<44} {'sim s':>7} {'wall s':>8} {'x real time':>12}")
    for name, target in (("lake_circle", 100), ("lake_circle_dynamic", 20)):
        sc = load_scenario(f"configs/{name}.toml")
        rf, wall = speed(sc, args.repeat)
        print(f"{name + ' (50 Hz control)':<44} {sc.duration:7.0f} {wall:8.2f} {rf:11.1f}x  (target >= {target}x)")
    for n in (int(s) for s in args.sizes.split(",")):
        duration = 20.0 if n <= 60 else 4.0
        sc = ring(n, duration)
        rf, wall = speed(sc, 1 if n > 60 else args.repeat)
        per = wall / (duration * 50 * n) * 1e6
        print(f"{f'ring of {n}, ideal, 50 Hz':<44} {duration:7.0f} {wall:8.2f} {rf:11.1f}x  "
              f"({per:.1f} µs per vehicle-step)")


if __name__ == "__main__":
    main()

"""Stale neighbours under delay: hold vs extrapolate vs timeout, and the sweep's throughput.

    python bench/stale_policy.py

1. lake_circle on an irregular graph (an undirected chain) with a 200 ms delay on every
   link: the steady coordination error (worst edge, mean over the last 50 s of a 400 s run)
   with each stale-neighbour policy. A value τ s old is off by about τ|ω̇| = τ rad; on an
   irregular graph that leaves a steady error, which extrapolating with the sender's
   timestamp and ω̇ removes (docs/control.md §6). Target: extrapolate >= 10x smaller than hold.
2. `cdus sweep` runs per minute on this machine (a 3 x 2 grid x 2 seeds of lake_circle,
   250 s each, in-process, all cores).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages, not an installed copy

from cdus.scenario.config import load_scenario  # noqa: E402
from cdus.app.sweep import parse_grid, sweep  # noqa: E402
from cdus.sim.fleet import InProcessFleet  # noqa: E402


def steady_error(policy: str) -> float:
    sc = load_scenario("configs/lake_circle.toml", {
        "graph.topology": "chain", "link.delay.base": 0.2, "link.policy": policy, "scenario.duration": 400.0})
    rec = InProcessFleet(sc).run().recorder
    t = rec.view("t")
    return float(rec.edge_error().max(axis=1)[t >= t[-1] - 50.0].mean())


def main() -> None:
    print("1. steady coordination error, chain, 200 ms delay on every link")
    errors = {p: steady_error(p) for p in ("hold", "timeout", "extrapolate")}
    for p, e in errors.items():
        print(f"   {p:<12} {e:.4f} rad")
    print(f"   hold / extrapolate = {errors['hold'] / errors['extrapolate']:.1f}x (target >= 10x)")
    print("2. sweep throughput")
    with tempfile.TemporaryDirectory() as tmp:
        grid = parse_grid(["link.loss=0,0.2,0.4", "link.delay.base=0,0.1"])
        t0 = time.perf_counter()
        rows = sweep("configs/lake_circle.toml", grid, [1, 2], Path(tmp), quiet=True)
        wall = time.perf_counter() - t0
    print(f"   {len(rows)} runs of 250 s simulated in {wall:.1f} s: {60 * len(rows) / wall:.1f} runs per minute")


if __name__ == "__main__":
    main()

"""`cdus sweep` at scale: throughput on local processes vs a Dask LocalCluster, and the
driver's memory over a long sweep.

1. Memory: a sweep of --runs very short runs (concentric_circles, 0.5 simulated s, 2 local
   processes); the driver's RSS (and its peak so far, VmHWM) sampled while it runs, printed at
   10 %, 50 % and 100 % of the runs and after the tables and the plot are written. Flat means
   the rows are on disk, not in memory.
2. Throughput: the same sweep (lake_circle, a 2 x 2 grid x --seeds, --duration simulated s
   per run) with 2 local processes and on a dask.distributed LocalCluster of 2 worker
   processes (127.0.0.1); runs per minute each, and the ratio dask / local.

    python bench/sweep_scale.py [--seeds 6] [--duration 60] [--runs 2000]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from cdus.app.sweep import sweep  # noqa: E402


def rss_mb() -> tuple[float, float]:
    """(VmRSS, VmHWM) of this process, MB."""
    fields = {}
    with open("/proc/self/status") as fh:
        for line in fh:
            k, _, v = line.partition(":")
            if k in ("VmRSS", "VmHWM"):
                fields[k] = int(v.split()[0]) / 1024
    return fields["VmRSS"], fields["VmHWM"]


def throughput(seeds: int, duration: float) -> None:
    grid = {"link.loss": [0, 0.2], "link.policy": ["hold", "extrapolate"]}
    runs = 4 * seeds
    print(f"2. throughput: lake_circle, {runs} runs of {duration:g} simulated s, 2 workers each")
    rates = {}
    for name, kw in (("local processes", {"jobs": 2}), ("dask LocalCluster", {"executor": "dask", "jobs": 2})):
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            res = sweep(ROOT / "configs/lake_circle.toml", grid, seeds, tmp, duration=duration, quiet=True, **kw)
            wall = time.perf_counter() - t0
        assert res.done == runs and res.failed == 0, (res.done, res.failed)
        rates[name] = 60 * runs / wall
        print(f"   {name:<18} {wall:6.1f} s wall (cluster start-up included): {rates[name]:5.1f} runs per minute")
    print(f"   dask / local = {rates['dask LocalCluster'] / rates['local processes']:.2f}")


def memory(runs: int) -> None:
    seeds = 50
    cells = math.ceil(runs / seeds)
    grid = {"link.loss": [round(0.5 * i / cells, 6) for i in range(cells)]}
    total = cells * seeds
    print(f"1. memory of the driver: {total} runs of concentric_circles, 0.5 simulated s each, 2 local processes")
    samples: list[tuple[int, float, float]] = []
    stop = threading.Event()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "results.jsonl"

        def watch() -> None:
            rows, offset = 0, 0
            while not stop.is_set():
                if path.exists():
                    with open(path, "rb") as fh:
                        fh.seek(offset)
                        chunk = fh.read()
                    offset += len(chunk)
                    rows += chunk.count(b"\n")
                samples.append((rows, *rss_mb()))
                stop.wait(0.1)

        t = threading.Thread(target=watch, daemon=True)
        base = rss_mb()
        t.start()
        t0 = time.perf_counter()
        res = sweep(ROOT / "configs/concentric_circles.toml", grid, seeds, tmp, jobs=2, duration=0.5, quiet=True)
        wall = time.perf_counter() - t0
        stop.set()
        t.join()
        after = rss_mb()
    assert res.done == total, res.done
    print(f"   {total} runs in {wall:.1f} s ({60 * total / wall:.0f} runs per minute); RSS before the sweep "
          f"{base[0]:.1f} MB")
    for frac in (0.1, 0.5, 1.0):
        rows, rss, hwm = next(s for s in samples if s[0] >= frac * total)
        print(f"   at {frac:4.0%} ({rows:5d} rows): RSS {rss:6.1f} MB, peak so far {hwm:6.1f} MB")
    print(f"   after the tables and the plot: RSS {after[0]:6.1f} MB, peak {after[1]:6.1f} MB")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=6, help="seeds per cell of the throughput sweep (4 cells)")
    ap.add_argument("--duration", type=float, default=60.0, help="simulated s per run of the throughput sweep")
    ap.add_argument("--runs", type=int, default=2000, help="runs of the memory sweep")
    args = ap.parse_args()
    print(f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}, {os.cpu_count()} cores")
    memory(args.runs)  # first: the driver's memory before Dask is imported
    throughput(args.seeds, args.duration)


if __name__ == "__main__":
    main()

"""How fast is `cdus launch --clock lockstep`? Simulated seconds per wall second, beside `cdus sim`.

    python bench/lockstep_speed.py                        # lake_circle, 120 s simulated, best of 3
    python bench/lockstep_speed.py --config configs/lissajous_5x5.toml --duration 60 --repeat 2

Each run is the real command in a child process (`cdus launch CONFIG --clock lockstep
--duration D -q`, one process per vehicle plus the world, the router in the launcher;
and `cdus sim CONFIG --duration D -q`). "run" is the metrics' wall_s: the world's clock
from the moment every vehicle is up to the metrics (for `cdus sim`, the fleet's run);
"total" is the whole command, start-up and shutdown included. Best of --repeat.
Both link topologies (`--links direct`, the default, and `--links router`) are run, so
the figures sit side by side in one run; `python bench/raw_ring.py` gives the ceiling
that raw Zenoh processes reach in the same exchange pattern.
Target (issue "Faster distributed runs"): lockstep >= 50x real time.
Figures are printed, never asserted: this machine is noisy.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import time
from pathlib import Path

from _fleet import REPO, Launch, load_line

from cdus.scenario.config import load_scenario


def once(cmd: str, config: str, duration: float, work: Path, k: int, links: str = "direct") -> tuple[float, float, dict]:
    """(run wall s from metrics.json, total wall s of the command, CPU s by role)."""
    run = work / f"{cmd}{links}{k}"
    metrics = run / "metrics.json"
    run.mkdir()
    args = [cmd, config, "--duration", f"{duration:g}", "-q", "--metrics-out", str(metrics)]
    fleet = None
    if cmd == "launch":
        fleet = f"bench_ls_{os.getpid()}_{links}_{k}"
        # --insecure: direct links skip the router's access control, so they need an open fleet; the
        # router row runs open too, so the two topologies compare alone
        args += ["--clock", "lockstep", "--fleet", fleet, "--logs", str(run), "--links", links, "--insecure"]
    with Launch(args, fleet=fleet, track_cpu=True) as la:
        rc = la.wait(timeout=600)
    m = json.loads(metrics.read_text()) if metrics.exists() else {}
    if rc != 0 or not m.get("wall_s") or m.get("completed") is False:
        print(f"  {cmd} run {k}: exit {rc}, completed {m.get('completed')}; output ends:\n    "
              + "\n    ".join(la.lines[-8:]))
        return math.inf, la.wall, la.cpu_by_role()
    return float(m["wall_s"]), la.wall, la.cpu_by_role()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--duration", type=float, default=120.0, help="simulated seconds")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    config = str((REPO / args.config).resolve()) if not os.path.isabs(args.config) else args.config
    sc = load_scenario(config)
    print(load_line())
    print(f"{sc.name}: {len(sc.vehicles)} vehicles, control {sc.rates.control:g} Hz, broadcast "
          f"{sc.rates.broadcast:g} Hz, {args.duration:g} s simulated, best of {args.repeat}")
    print(f"{'command':<34} {'run s':>7} {'x real time':>12} {'total s':>8} {'x incl. start-up':>17}  all runs (run s)")
    with tempfile.TemporaryDirectory(prefix="cdus-ls-") as tmp:
        work = Path(tmp)
        for cmd, links, label, target in (("launch", "direct", "launch lockstep, direct links", 50),
                                          ("launch", "router", "launch lockstep, via the router", 50),
                                          ("sim", "-", "cdus sim (one process)", None)):
            runs = [once(cmd, config, args.duration, work, k, links) for k in range(args.repeat)]
            best_run = min(r for r, _, _ in runs)
            best_total = min(t for _, t, _ in runs)
            print(f"{label:<34} {best_run:7.2f} {args.duration / best_run:11.1f}x {best_total:8.2f} "
                  f"{args.duration / best_total:16.1f}x  {', '.join(f'{r:.2f}' for r, _, _ in runs)}"
                  + (f"  (target >= {target}x)" if target else ""), flush=True)
            if cmd == "launch":
                _, total, cpu = min(runs, key=lambda r: r[0])
                print(f"  CPU of the best launch (s, start-up included, sampled every 0.25 s): agents "
                      f"{cpu['agents']:.1f} ({cpu['agents'] / len(sc.vehicles):.2f} each), world {cpu['world']:.1f}, "
                      f"launcher+router {cpu['launcher']:.1f}; {sum(cpu.values()) / total:.2f} cores busy on "
                      f"average over {total:.1f} s")


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"(bench took {time.perf_counter() - t0:.0f} s)")

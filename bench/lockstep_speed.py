"""How fast is `cdus launch --clock lockstep`, next to its ceiling, and is it still `cdus sim`?

    python bench/lockstep_speed.py                    # lake_circle, 120 s simulated, 3 rounds
    python bench/lockstep_speed.py --duration 120 --repeat 5 --links direct
    python bench/lockstep_speed.py --ros2 --duration 60 --repeat 2   # the ROS 2 bridge's cost

In ONE run, interleaved so the machine's load affects all alike, each round runs:

  ring      bench/raw_ring.py's ring (as many processes as vehicles, the same one-message-
            per-neighbour-per-tick exchange, the same router and Zenoh runtime as
            `cdus launch`): the ceiling of lockstep through raw Zenoh;
  as is     `cdus launch CONFIG --clock lockstep` (broadcast = control for lake_circle);
  10 Hz     the same with `--set rates.broadcast=10` (the lookahead: 5 ticks a broadcast);
  as is --ros2   with --ros2 only: `as is` publishing the fleet to ROS 2 (docs/ros2.md), so
            the bridge's cost is the ratio of the two, measured under the same load. Each
            run also prints the agents' median CPU per tick (their logs) and the bridge's CPU.

The ring's processes run one Zenoh worker thread (ZENOH_RUNTIME, as `cdus launch` gives its
children); the launcher runs as shipped (its children on one worker thread, its own router on
Zenoh's default pools: cdus.wire.transport.ROUTER_RUNTIME says why), so "of ring" is, if
anything, conservative; the lockstep runs
record no Rerun stream unless --rerun says so (the ring records nothing either).

Each lockstep figure is the metrics' wall_s (the world's clock from every vehicle up to the
metrics, its 0.3 s wait for the agents' last counters included) as ticks/s and x real time; "of ring" divides its ticks/s by the mean of the ring
runs just before and after it. Each case's trace (--trace-out) and metrics are compared with
`cdus sim`'s, to the bit, and the verdict printed. The load average is printed with each
figure (this 2-core box is shared). Targets (issue 20): as is >= 0.8 of the ring; 10 Hz
>= 50x real time. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _fleet import REPO, Launch, cdus_argv, load_line

import raw_ring
from cdus.scenario.config import load_scenario

TRACE = ("q", "omega", "omega_rate", "path_error", "heading")
METRICS = ("duration_s", "path_settle_s", "coord_settle_s", "final_path_error_max", "final_coord_error_max",
           "omega_rate_final")
CASES = {"as is": [], "10 Hz": ["--set", "rates.broadcast=10"]}


def load() -> str:
    l1, l5, _ = os.getloadavg()
    return f"load {l1:.2f}/{l5:.2f}"


def reference(config: str, duration: float, extra: list[str], out: Path) -> tuple[Path, dict]:
    """`cdus sim`'s trace and metrics for this case."""
    out.mkdir()
    trace, metrics = out / "trace.npz", out / "metrics.json"
    subprocess.run([*cdus_argv(), "sim", config, "--duration", f"{duration:g}", "-q", "--rerun", "off",
                    "--trace-out", str(trace), "--metrics-out", str(metrics), *extra],
                   cwd=REPO, check=True, stdout=subprocess.DEVNULL)
    return trace, json.loads(metrics.read_text())


def cpu_figures(out: Path) -> tuple[list[int], float | None]:
    """Each agent's CPU per tick (µs) and the ROS 2 bridge's CPU (s, None without one), from the run's logs."""
    per_tick = []
    for log in (out / "logs").glob("*.log"):
        text = log.read_text(errors="replace")
        m = re.search(r"CPU in the run [0-9.]+ s \(([0-9]+) µs per tick\)", text)
        if m and log.stem not in ("world", "ros2"):
            per_tick.append(int(m.group(1)))
    bridge = re.search(r"ros2 bridge: .*CPU ([0-9.]+) s", (out / "logs" / "ros2.log").read_text()) \
        if (out / "logs" / "ros2.log").exists() else None
    return per_tick, float(bridge.group(1)) if bridge else None


def cpu_line(out: Path) -> str:
    """The agents' median CPU per tick and the ROS 2 bridge's CPU, from the run's logs."""
    per_tick, bridge = cpu_figures(out)
    return (f"agents {np.median(per_tick):.0f} µs CPU/tick" if per_tick else "agents' CPU not logged") + \
        (f", bridge {bridge:.2f} s CPU" if bridge is not None else "")


def lockstep(config: str, duration: float, extra: list[str], out: Path, links: str, rerun: str
             ) -> tuple[float, Path, dict]:
    """(run wall s, trace, metrics) of one `cdus launch --clock lockstep`."""
    out.mkdir()
    trace, metrics = out / "trace.npz", out / "metrics.json"
    fleet = f"bench_ls_{os.getpid()}_{out.name}"
    args = ["launch", config, "--clock", "lockstep", "--duration", f"{duration:g}", "-q", "--fleet", fleet,
            "--logs", str(out), "--links", links, "--trace-out", str(trace), "--metrics-out", str(metrics),
            "--rerun", rerun, *extra]
    if links == "direct":
        args.append("--insecure")  # direct links skip the router's access control
    with Launch(args, fleet=fleet) as la:
        rc = la.wait(timeout=900)
    m = json.loads(metrics.read_text()) if metrics.exists() else {}
    if rc != 0 or not m.get("wall_s") or m.get("completed") is not True:
        print(f"    launch failed: exit {rc}, completed {m.get('completed')}; output ends:\n      "
              + "\n      ".join(la.lines[-8:]))
        return math.inf, trace, m
    return float(m["wall_s"]), trace, m


def identical(trace: Path, m: dict, ref_trace: Path, ref: dict) -> str:
    if not trace.exists():
        return "no trace"
    a, b = np.load(trace), np.load(ref_trace)
    bad = [n for n in TRACE if a[n].shape != b[n].shape or not np.array_equal(a[n], b[n], equal_nan=True)]
    bad += [f for f in METRICS if m.get(f) != ref.get(f)]
    return "bit-identical to cdus sim" if not bad else f"DIFFERS from cdus sim in {', '.join(bad)}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="configs/lake_circle.toml")
    ap.add_argument("--duration", type=float, default=120.0,
                    help="simulated seconds (wall_s includes the world's 0.3 s wait for the agents' last "
                         "counters: short runs understate the speed)")
    ap.add_argument("--repeat", type=int, default=3, help="rounds (ring, as is, 10 Hz)")
    ap.add_argument("--ring-ticks", type=int, default=3000)
    ap.add_argument("--rerun", default="off",
                    help="the world's Rerun recording in the lockstep runs (default off: the ring records nothing; "
                         "`auto`, launch's default, saves a .rrd: about 40 %% of the world's CPU)")
    ap.add_argument("--ros2", action="store_true", help="also run `as is` with --ros2 (the ROS 2 bridge), interleaved")
    ap.add_argument("--links", choices=("router", "direct"), default="router",
                    help="lockstep links; the ring runs the matching topology (router | peer)")
    args = ap.parse_args()
    config = str((REPO / args.config).resolve()) if not os.path.isabs(args.config) else args.config
    sc = load_scenario(config)
    n = len(sc.vehicles)
    ticks = round(args.duration * sc.rates.control) + 1
    ring_mode = "router" if args.links == "router" else "peer"
    print(load_line())
    print(f"{sc.name}: {n} vehicles, control {sc.rates.control:g} Hz, broadcast {sc.rates.broadcast:g} Hz, "
          f"{args.duration:g} s simulated ({ticks} ticks), {args.repeat} rounds, links {args.links}, "
          f"rerun {args.rerun}; "
          f"ring: {n} processes, {args.ring_ticks} ticks, {ring_mode}")
    cases = {**CASES, **({"as is --ros2": ["--ros2"]} if args.ros2 else {})}
    results: dict[str, list[tuple[float, float, str]]] = {c: [] for c in cases}  # (ticks/s, ratio, load)
    rings: list[float] = []
    with tempfile.TemporaryDirectory(prefix="cdus-ls-") as tmp:
        work = Path(tmp)
        refs = {c: reference(config, args.duration, [a for a in extra if a != "--ros2"], work / f"ref{k}")
                for k, (c, extra) in enumerate(cases.items())}  # the bridge changes nothing of the run
        rings.append(raw_ring.run(n, args.ring_ticks, ring_mode)["ticks_per_s"])
        print(f"  ring            {rings[-1]:7.0f} ticks/s = {rings[-1] / sc.rates.control:5.1f}x real time  "
              f"({load()})", flush=True)
        for r in range(args.repeat):
            runs = {}
            for k, (case, extra) in enumerate(cases.items()):
                wall, trace, m = lockstep(config, args.duration, extra, work / f"r{r}c{k}", args.links,
                                            args.rerun)
                runs[case] = (ticks / wall, load(), identical(trace, m, *refs[case]) + "; " + cpu_line(work / f"r{r}c{k}"))
            rings.append(raw_ring.run(n, args.ring_ticks, ring_mode)["ticks_per_s"])
            ceiling = 0.5 * (rings[-2] + rings[-1])
            for case, (tps, ld, same) in runs.items():
                results[case].append((tps, tps / ceiling, ld))
                print(f"  {case:<15} {tps:7.0f} ticks/s = {tps / sc.rates.control:5.1f}x real time, "
                      f"{tps / ceiling:4.2f} of the ring  ({ld}; {same})", flush=True)
            print(f"  ring            {rings[-1]:7.0f} ticks/s = {rings[-1] / sc.rates.control:5.1f}x real time  "
                  f"({load()})", flush=True)
    print("summary (median over rounds):")
    print(f"  ring   {np.median(rings) / sc.rates.control:5.1f}x real time")
    for case, rs in results.items():
        xs = [t / sc.rates.control for t, _, _ in rs]
        ratios = [q for _, q, _ in rs]
        target = {"as is": "target >= 0.8 of the ring", "10 Hz": "target >= 50x real time"}.get(case, "")
        print(f"  {case:<6} {np.median(xs):5.1f}x real time, {np.median(ratios):4.2f} of the ring  ({target or 'no target'}); "
              f"runs {', '.join(f'{x:.1f}x' for x in xs)}")
    if args.ros2:
        pairs = [b[0] / a[0] for a, b in zip(results["as is"], results["as is --ros2"])]
        print(f"  --ros2 / as is, per round: {', '.join(f'{p:.2f}' for p in pairs)} (median {np.median(pairs):.2f})")
    print(load_line())


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    t0 = time.perf_counter()
    main()
    print(f"(bench took {time.perf_counter() - t0:.0f} s)")

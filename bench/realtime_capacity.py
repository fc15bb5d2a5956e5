"""How many vehicle processes hold real time on this machine? Ring fleets under `cdus launch`.

    python bench/realtime_capacity.py                   # N = 8, 16, 24, 32, 48, 64; 20 s each
    python bench/realtime_capacity.py --sizes 32,40 --duration 30

For each N: a ring of N vehicles (alternating usv/uav, ideal plants, on circles: bench
sim_speed.ring) at physics 200 Hz, control 50 Hz, ω broadcast 50 Hz, written as JSON and
run with `cdus launch FILE --clock realtime --duration D -q`. Halfway through the run
the bench samples every process's RSS and, over a few seconds, its CPU use; at the end it
reads link.missed_deadlines (summed over the agents by the world) from metrics.json.
Miss rate = missed / (N x ticks per agent). The sweep stops after a size above 5%.
Targets (issue "Faster distributed runs"): 64 vehicles under 1% missed control
deadlines, <= 60 MB RSS per agent. --links router gives the figures without direct links. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

from _fleet import Launch, cpu_seconds, ctx_switches, load_line, role, rss_mb, write_json
from sim_speed import ring

from cdus.core.schedule import total_ticks

CPU_WINDOW = 4.0  # s of the run's middle over which CPU use is measured
DONE_RE = re.compile(r"done after (\d+) ticks; missed deadlines (\d+)")


def run_size(n: int, duration: float, work: Path, links: str = "direct") -> dict:
    sc = ring(n, duration)
    path = write_json(work / f"ring{n}.json", sc.raw)
    fleet = f"bench_rt_{os.getpid()}_{links}_{n}"
    run = work / f"run{links}{n}"
    args = ["launch", str(path), "--clock", "realtime", "--duration", f"{duration:g}", "-q",
            "--fleet", fleet, "--logs", str(run), "--links", links,
            "--insecure"]  # direct links (the default here) need an open fleet; router runs open alike
    out = {"n": n}
    with Launch(args, fleet=fleet) as la:
        la.up.wait(timeout=120 + n)
        t_up = la.wall
        time.sleep(0.5 + max(0.0, duration / 2 - CPU_WINDOW / 2))  # the world starts the clock 0.5 s after
        procs = la.processes()
        roles = {p.pid: role(p) for p in procs}
        rss = {p.pid: rss_mb(p) for p in procs}
        threads = {p.pid: p.num_threads() for p in procs if p.is_running()}
        cpu0, cs0, t0 = cpu_seconds(procs + [_proc(la.proc.pid)]), ctx_switches(list(roles)), time.perf_counter()
        time.sleep(CPU_WINDOW)
        cpu1, cs1, t1 = cpu_seconds(procs + [_proc(la.proc.pid)]), ctx_switches(list(roles)), time.perf_counter()
        rc = la.wait(timeout=duration + 120)
    cpu = {pid: 100 * (cpu1[pid] - cpu0[pid]) / (t1 - t0) for pid in cpu1 if pid in cpu0}
    cs = {pid: (cs1[pid] - cs0[pid]) / (t1 - t0) for pid in cs1 if pid in cs0}
    agents = [pid for pid, r in roles.items() if r.startswith("agent")]
    world = [pid for pid, r in roles.items() if r == "world"]
    out.update(rc=rc, up_s=t_up, wall_s=la.wall,
               rss_agent=statistics.median(rss[p] for p in agents if rss[p]) if agents else None,
               rss_world=rss[world[0]] if world else None,
               cpu_agents=sum(cpu.get(p, 0.0) for p in agents), cpu_agent_max=max((cpu.get(p, 0.0) for p in agents),
                                                                                default=0.0),
               cpu_world=sum(cpu.get(p, 0.0) for p in world), cpu_router=cpu.get(la.proc.pid, 0.0),
               switches=statistics.median(cs[p] for p in agents if p in cs) if agents else 0.0,
               threads=statistics.median(threads[p] for p in agents if p in threads) if agents else 0)
    metrics_path = run / "metrics.json"
    ticks = total_ticks(duration, 1.0 / sc.rates.control) + 1
    if metrics_path.exists():
        m = json.loads(metrics_path.read_text())
        out["missed"] = int(m["link"].get("missed_deadlines", 0))
        out["completed"] = m.get("completed")
    # each agent's own last word, to cross-check the world's sum (its final counters may be late)
    logs = [DONE_RE.search((run / "logs" / f"{v.id}.log").read_text(errors="replace"))
            for v in sc.vehicles if (run / "logs" / f"{v.id}.log").exists()]
    out["missed_logs"] = sum(int(g.group(2)) for g in logs if g)
    out["ticks_logs"] = sum(int(g.group(1)) for g in logs if g)
    out["agents_done"] = sum(1 for g in logs if g)
    out["miss_pct"] = 100.0 * out.get("missed", out["missed_logs"]) / (n * ticks)
    out["ticks"] = ticks
    return out


def _proc(pid: int):
    import psutil

    return psutil.Process(pid)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="8,16,24,32,48,64")
    ap.add_argument("--duration", type=float, default=20.0, help="simulated (= wall) seconds per run")
    ap.add_argument("--keep", action="store_true", help="keep the run directories (logs, metrics)")
    ap.add_argument("--links", choices=("direct", "router"), default="direct",
                    help="how ω travels between neighbours (cdus launch --links)")
    args = ap.parse_args()
    print(f"links: {args.links}")
    print(f"{os.cpu_count()} CPUs; {load_line()}")
    print(f"{'N':>3} {'miss %':>7} {'missed':>7} {'(logs)':>7} {'RSS/agent MB':>13} {'world MB':>9} "
          f"{'CPU% agents':>12} {'(max one)':>10} {'world':>6} {'router':>7} {'ctx sw/s':>9} {'start s':>8} "
          f"{'wall s':>7}")
    results = []
    with tempfile.TemporaryDirectory(prefix="cdus-rt-") as tmp:
        work = Path(tmp)
        for n in (int(s) for s in args.sizes.split(",")):
            r = run_size(n, args.duration, work, args.links)
            results.append(r)
            print(f"{n:3d} {r['miss_pct']:7.2f} {r.get('missed', '-'):>7} {r['missed_logs']:>7} "
                  f"{r['rss_agent'] or float('nan'):13.1f} {r['rss_world'] or float('nan'):9.1f} "
                  f"{r['cpu_agents']:12.0f} {r['cpu_agent_max']:10.1f} {r['cpu_world']:6.1f} {r['cpu_router']:7.1f} "
                  f"{r['switches']:9.0f} "
                  f"{r['up_s']:8.1f} {r['wall_s']:7.1f}"
                  + ("" if r["rc"] == 0 and r.get("completed") else f"  (exit {r['rc']}, completed "
                                                                         f"{r.get('completed')})")
                  + ("" if r["agents_done"] == n else f"  ({r['agents_done']}/{n} agents reported done)"),
                  flush=True)
            if r["miss_pct"] > 5.0:
                break
        if args.keep:
            import shutil

            keep = Path(tempfile.mkdtemp(prefix="cdus-rt-kept-"))
            shutil.copytree(work, keep, dirs_exist_ok=True)
            print(f"run directories kept in {keep}")
    ok = [r["n"] for r in results if r["miss_pct"] < 1.0]
    rss = [r["rss_agent"] for r in results if r["rss_agent"]]
    print(f"largest N under 1% missed deadlines: {max(ok) if ok else 'none'} (target >= 32); "
          f"RSS per agent {min(rss):.1f}-{max(rss):.1f} MB (target <= 60 MB)" if rss else "no RSS sampled")
    print("miss % = link.missed_deadlines from metrics.json / (N x ticks); (logs) = the sum of the agents' own "
          "final counts; CPU% = share of one core over a few s mid-run (200% = both cores); ctx sw/s = context "
          "switches per second of one agent, all its threads (median agent).")
    if results:
        print(f"threads per agent: {results[-1]['threads']:g}")


if __name__ == "__main__":
    sys.exit(main())

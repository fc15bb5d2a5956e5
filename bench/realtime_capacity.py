"""How many vehicle processes hold real time on this machine? Ring fleets under `cdus launch`.

    python bench/realtime_capacity.py                   # N = 8, 16, 24, 32, 48, 64; 20 s each
    python bench/realtime_capacity.py --sizes 32,40 --duration 30
    python bench/realtime_capacity.py --sizes 64 --router-runtime one,default --repeat 3   # interleaved

For each N: a ring of N vehicles (alternating usv/uav, ideal plants, on circles: bench
sim_speed.ring) at physics 200 Hz, control 50 Hz, ω broadcast 50 Hz, written as JSON and
run with `cdus launch FILE --clock realtime --duration D -q`. Halfway through the run
the bench samples every process's RSS and, over a few seconds, its CPU use; at the end it
reads link.missed_deadlines (summed over the agents by the world) from metrics.json.
Miss rate = missed / (N x ticks per agent). The sweep stops after a size above 5%.
Per process it also reads its threads and, per thread, CPU: an agent's Python main thread
apart from Zenoh's threads, the launcher's (the router's) total. Variants of the launcher's
own Zenoh runtime (--router-runtime: ``default``, Zenoh's pools, as cdus launch runs;
``small``, ``single``, fewer threads; or a ZENOH_RUNTIME string) run interleaved, size by size, --repeat times, so they
see the same load. The last line says what limits: the CPU the run used out of the
machine's, and who used it.
Targets (issue 20): 64 vehicles under 1% missed control deadlines, <= 60 MB RSS per
agent. --links router (the default, as `cdus launch`'s). Figures are printed, never asserted.
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
from cdus.wire.transport import CHILD_RUNTIME, ROUTER_RUNTIME, ROUTER_RUNTIME_ENV, SMALL_ROUTER_RUNTIME

CPU_WINDOW = 4.0  # s of the run's middle over which CPU use is measured
DONE_RE = re.compile(r"done after (\d+) ticks; missed deadlines (\d+)")


RUNTIMES = {"default": "default", "small": SMALL_ROUTER_RUNTIME, "single": CHILD_RUNTIME}


def threads_cpu(pids: list[int]) -> dict[tuple[int, str], float]:
    """CPU seconds per (pid, thread kind): ``main`` (the Python main thread), ``zenoh`` (threads
    Zenoh's runtime names: app-, net-, rx-, tx-, acc-), ``other``."""
    hz = os.sysconf("SC_CLK_TCK")
    out: dict[tuple[int, str], float] = {}
    for pid in pids:
        try:
            tids = os.listdir(f"/proc/{pid}/task")
        except OSError:
            continue
        for tid in tids:
            try:
                with open(f"/proc/{pid}/task/{tid}/comm") as fh:
                    comm = fh.read().strip()
                with open(f"/proc/{pid}/task/{tid}/stat") as fh:
                    st = fh.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            kind = ("main" if tid == str(pid) else
                    "zenoh" if comm.startswith(("app-", "net-", "rx-", "tx-", "acc-")) else "other")
            out[(pid, kind)] = out.get((pid, kind), 0.0) + (int(st[11]) + int(st[12])) / hz
    return out


def run_size(n: int, duration: float, work: Path, links: str = "router", runtime: str = ROUTER_RUNTIME) -> dict:
    sc = ring(n, duration)
    path = write_json(work / f"ring{n}.json", sc.raw)
    tag = "".join(c for c in runtime if c.isalnum())[:12]
    fleet = f"bench_rt_{os.getpid()}_{links}_{n}_{tag}_{int(time.time() * 1000) % 100000}"
    run = work / f"run{links}{n}{tag}{int(time.time() * 1000) % 100000}"
    args = ["launch", str(path), "--clock", "realtime", "--duration", f"{duration:g}", "-q",
            "--fleet", fleet, "--logs", str(run), "--links", links,
            "--insecure"]  # direct links (the default here) need an open fleet; router runs open alike
    out = {"n": n}
    env = dict(os.environ, **{ROUTER_RUNTIME_ENV: RUNTIMES.get(runtime, runtime)})
    with Launch(args, fleet=fleet, env=env) as la:
        la.up.wait(timeout=120 + n)
        t_up = la.wall
        time.sleep(0.5 + max(0.0, duration / 2 - CPU_WINDOW / 2))  # the world starts the clock 0.5 s after
        procs = la.processes()
        roles = {p.pid: role(p) for p in procs}
        rss = {p.pid: rss_mb(p) for p in procs}
        launcher = _proc(la.proc.pid)
        threads = {p.pid: p.num_threads() for p in procs + [launcher] if p.is_running()}
        pids = [p.pid for p in procs]
        cpu0, cs0, t0 = cpu_seconds(procs + [launcher]), ctx_switches(list(roles)), time.perf_counter()
        th0, box0, u0 = threads_cpu(pids), _machine_cpu(), time.perf_counter()
        time.sleep(CPU_WINDOW)
        cpu1, cs1, t1 = cpu_seconds(procs + [launcher]), ctx_switches(list(roles)), time.perf_counter()
        th1, box1, u1 = threads_cpu(pids), _machine_cpu(), time.perf_counter()  # own window: reading takes time
        load1 = os.getloadavg()[0]
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
               threads=statistics.median(threads[p] for p in agents if p in threads) if agents else 0,
               threads_world=threads.get(world[0], 0) if world else 0, threads_launcher=threads.get(la.proc.pid, 0),
               cpu_agents_main=sum(100 * (th1[k] - th0.get(k, 0.0)) / (u1 - u0) for k in th1
                                   if k[1] == "main" and k[0] in agents),
               cpu_agents_zenoh=sum(100 * (th1[k] - th0.get(k, 0.0)) / (u1 - u0) for k in th1
                                    if k[1] == "zenoh" and k[0] in agents),
               cpu_machine=100 * (box1[0] - box0[0]) / max(1e-9, box1[1] - box0[1]) * (os.cpu_count() or 1),
               load=load1, runtime=runtime)
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


def _machine_cpu() -> tuple[float, float]:
    """(busy, total) jiffies of the whole machine, from /proc/stat."""
    with open("/proc/stat") as fh:
        f = [int(x) for x in fh.readline().split()[1:]]
    idle = f[3] + f[4]
    return float(sum(f) - idle), float(sum(f))


def _proc(pid: int):
    import psutil

    return psutil.Process(pid)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="8,16,24,32,48,64")
    ap.add_argument("--duration", type=float, default=20.0, help="simulated (= wall) seconds per run")
    ap.add_argument("--keep", action="store_true", help="keep the run directories (logs, metrics)")
    ap.add_argument("--links", choices=("direct", "router"), default="router",
                    help="how ω travels between neighbours (cdus launch --links; default router, as cdus launch)")
    ap.add_argument("--router-runtime", default=ROUTER_RUNTIME,
                    help="the launcher's own Zenoh runtime, comma-separated variants run interleaved: default "
                         "(Zenoh's pools, as cdus launch runs), small (one routing thread, transmit on another), "
                         "single (the children's: one thread) or a ZENOH_RUNTIME string. small and single cost "
                         "less CPU but stall every link behind a congested one (cdus.wire.transport)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each size and variant")
    args = ap.parse_args()
    variants = [v for v in args.router_runtime.split(",") if v] if "(" not in args.router_runtime else \
        [args.router_runtime]
    print(f"links: {args.links}; launcher runtime variants: {', '.join(variants)}")
    print(f"{os.cpu_count()} CPUs; {load_line()}")
    print(f"{'N':>3} {'runtime':>8} {'miss %':>7} {'missed':>7} {'(logs)':>7} {'RSS/agent MB':>13} {'world MB':>9} "
          f"{'CPU% agents':>12} {'(main)':>7} {'(zenoh)':>8} {'(max one)':>10} {'world':>6} {'router':>7} "
          f"{'machine':>8} {'ctx sw/s':>9} {'thr a/w/l':>10} {'load':>5} {'wall s':>7}")
    results = []
    stop = False
    with tempfile.TemporaryDirectory(prefix="cdus-rt-") as tmp:
        work = Path(tmp)
        for n in (int(s) for s in args.sizes.split(",")):
            for _ in range(args.repeat):
                for variant in variants:
                    r = run_size(n, args.duration, work, args.links, variant)
                    results.append(r)
                    print(f"{n:3d} {variant[:8]:>8} {r['miss_pct']:7.2f} {r.get('missed', '-'):>7} "
                          f"{r['missed_logs']:>7} {r['rss_agent'] or float('nan'):13.1f} "
                          f"{r['rss_world'] or float('nan'):9.1f} {r['cpu_agents']:12.0f} "
                          f"{r['cpu_agents_main']:7.0f} {r['cpu_agents_zenoh']:8.0f} {r['cpu_agent_max']:10.1f} "
                          f"{r['cpu_world']:6.1f} {r['cpu_router']:7.1f} {r['cpu_machine']:8.0f} "
                          f"{r['switches']:9.0f} {r['threads']:g}/{r['threads_world']}/{r['threads_launcher']:<4} "
                          f"{r['load']:5.1f} {r['wall_s']:7.1f}"
                          + ("" if r["rc"] == 0 and r.get("completed") else f"  (exit {r['rc']}, completed "
                                                                                 f"{r.get('completed')})")
                          + ("" if r["agents_done"] == n else f"  ({r['agents_done']}/{n} agents reported done)"),
                          flush=True)
                    stop = stop or r["miss_pct"] > 5.0
            if stop:
                break
        if args.keep:
            import shutil

            keep = Path(tempfile.mkdtemp(prefix="cdus-rt-kept-"))
            shutil.copytree(work, keep, dirs_exist_ok=True)
            print(f"run directories kept in {keep}")
    ok = [r["n"] for r in results if r["miss_pct"] < 1.0]
    rss = [r["rss_agent"] for r in results if r["rss_agent"]]
    print(f"largest N under 1% missed deadlines: {max(ok) if ok else 'none'} (target 64); "
          f"RSS per agent {min(rss):.1f}-{max(rss):.1f} MB (target <= 60 MB)" if rss else "no RSS sampled")
    print("miss % = link.missed_deadlines from metrics.json / (N x ticks); (logs) = the sum of the agents' own "
          "final counts; CPU% = share of one core over a few s mid-run (200% = both cores): agents (their Python "
          "main threads, Zenoh's threads), the largest agent, the world, the launcher (= the router); machine = "
          "every process of the box; ctx sw/s = context switches per second of one agent, all its threads "
          "(median agent); thr a/w/l = threads per agent (median) / world / launcher.")
    if results:
        r = max(results, key=lambda x: x["n"])
        cores = 100 * (os.cpu_count() or 1)
        ours = r["cpu_agents"] + r["cpu_world"] + r["cpu_router"]
        per_tick = r["cpu_agents"] / 100 / r["n"] * 1e6 / 50.0
        print(f"what limits (N = {r['n']}, {r['runtime']}): total CPU {r['cpu_machine']:.0f} % of {cores} % "
              f"(this fleet {ours:.0f} %: agents {r['cpu_agents']:.0f} % = {per_tick:.0f} µs per agent-tick, of "
              f"which their Python main threads {r['cpu_agents_main']:.0f} % and Zenoh's threads "
              f"{r['cpu_agents_zenoh']:.0f} %; router {r['cpu_router']:.0f} %; world {r['cpu_world']:.0f} %); "
              f"threads per agent {r['threads']:g}, {r['n'] * r['threads']:g} in all; load average {r['load']:.1f}")


if __name__ == "__main__":
    sys.exit(main())

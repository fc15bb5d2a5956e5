"""Monte Carlo obstacle benchmark: do seeded encounters with [[obstacle]]s keep the margin, per plant?

    python3 bench/obstacle_montecarlo.py [--encounters 200] [--presets ideal,usv_3dof,uav_double_integrator]
                                         [--seed 1] [--jobs N] [--duration 25] [--json OUT]

For each plant preset (bench/safety_montecarlo.py's: ``ideal`` boats, ``usv_3dof`` boats,
``uav_double_integrator`` drones at 10 m) it draws ``--encounters`` encounters and runs each in
the in-process fleet with ``safety.enabled`` true and false. An encounter: one obstacle of the
preset's medium at a random point P (boats: a circle of radius 1-3 m or a convex polygon of 3-6
corners within 1-3 m of P; drones: a cylinder of radius 1-3 m or a box of half-side 1-3 m, from
the water up to 12-30 m), a margin of 0.5-1.5 m, and 1-3 vehicles on straight lines through P
(shifted sideways by up to the obstacle's size, so some aim at its centre: the symmetric stall
the starboard turn breaks), at P together at T = 6-10 s, at 0.8-1.5 m/s (drones 2-4 m/s). Every
vehicle starts at least 1 m clear of the margin and 1.5 R from the others. With 2-3 vehicles the
filter holds the vehicle-vehicle rows too.

A **violation**: a vehicle's minimum clearance (metrics ``obstacles``) below its margin by more
than 0.01 m (the tests' tolerance for the vehicle-vehicle filter, which acts on samples up to a
period old; the obstacles are exact, so the count strictly below the margin is given too); the
vehicle-vehicle separation below R - 0.01 m is counted apart. Also: ``rejoined``, the share of
encounters whose worst final path error is below 0.2 m; the wall time per run.

``--solve``: the filter's solve time per call at 20 constraints (10 contacts + 10 obstacles,
every reference pointing into them), median / p99 over 200 seeded situations, for the velocity
filter (2-D and 3-D) and the dynamic one (usv_3dof, uav_double_integrator).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

if not os.environ.get("PYTHONPATH"):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout, not an installed copy

from bench.safety_montecarlo import ALTITUDE, PLANTS, PRESETS, RADIUS, _base, _vehicle  # noqa: E402
from cdus.scenario.config import parse_scenario  # noqa: E402
from cdus.sim.fleet import InProcessFleet  # noqa: E402

TOLERANCE = 0.01


def generate(preset: str, index: int, seed: int, duration: float) -> dict:
    """The scenario data of the ``index``-th encounter of ``preset`` (the same every run)."""
    rng = random.Random(f"obstacle_montecarlo:{seed}:{preset}:{index}")
    while True:  # redrawn from the same stream until every start is clear
        data, starts, clear = _draw(rng, preset, index, seed, duration)
        apart = all(math.dist(a, b) >= 1.5 * RADIUS for i, a in enumerate(starts) for b in starts[i + 1:])
        if apart and clear:
            return data


def _draw(rng: random.Random, preset: str, index: int, seed: int, duration: float):
    vkind, plant, limits, (vlo, vhi) = PLANTS[preset]
    meet_t = rng.uniform(6.0, 10.0)
    P = (rng.uniform(-20.0, 20.0), rng.uniform(-20.0, 20.0))
    size = rng.uniform(1.0, 3.0)
    margin = round(rng.uniform(0.5, 1.5), 3)
    if vkind == "usv" and rng.random() < 0.5:
        ob = {"shape": "circle", "center": list(P), "radius": size}
    elif vkind == "usv":
        n = rng.randint(3, 6)
        angles = sorted(rng.uniform(0, 2 * math.pi) for _ in range(n))
        while max((angles[(i + 1) % n] - angles[i]) % (2 * math.pi) for i in range(n)) > 0.9 * math.pi:
            angles = sorted(rng.uniform(0, 2 * math.pi) for _ in range(n))  # P inside, no sliver
        ob = {"shape": "polygon", "vertices": [[P[0] + size * math.cos(a), P[1] + size * math.sin(a)] for a in angles]}
    elif rng.random() < 0.5:
        ob = {"shape": "cylinder", "center": list(P), "radius": size, "z": [0.0, rng.uniform(12.0, 30.0)]}
    else:
        top = rng.uniform(12.0, 30.0)
        ob = {"shape": "box", "min": [P[0] - size, P[1] - size, 0.0], "max": [P[0] + size, P[1] + size, top]}
    ob["margin"] = margin
    n = rng.choice((1, 1, 2, 3))
    base_dir = rng.uniform(-math.pi, math.pi)
    vehicles, starts = [], []
    clear = True
    for j in range(n):
        travel = base_dir + (2 * math.pi * j / n if n > 1 else 0.0) + math.radians(rng.uniform(-20.0, 20.0))
        speed = rng.uniform(vlo, vhi)
        shift = rng.uniform(-1.0, 1.0) * size * (0.2 if j == 0 else 1.0)  # the first aims near the centre
        w0 = meet_t + rng.uniform(-0.2, 0.2)
        v = _vehicle(f"{vkind}{j + 1}", vkind, plant, limits, travel, speed, shift, w0, P,
                     ALTITUDE if vkind == "uav" else None)
        path = v["path"]
        start = [o + path["speed"] * w0 * h for o, h in zip(path["origin"], path["heading"])]
        starts.append(start[:2])
        clear = clear and math.dist(start[:2], P) > 2 * size + margin + 1.0
        vehicles.append(v)
    data = _base(f"omc_{preset}_{index}", seed, vehicles)
    data["scenario"]["duration"] = duration
    data["obstacle"] = [ob]
    data["graph"]["topology"] = "complete"  # also for one vehicle
    return data, starts, clear


def _job(job: tuple[dict, bool]) -> dict[str, Any]:
    data, on = job
    d = json.loads(json.dumps(data))
    d["safety"]["enabled"] = on
    t0 = time.perf_counter()
    m = InProcessFleet(parse_scenario(d, "obstacle_montecarlo")).run().metrics
    rows = m.obstacles.vehicles.values()
    return {"on": on, "wall": time.perf_counter() - t0,
            "worst": min(r["min_clearance_m"] - r["margin_m"] for r in rows),
            "sep": m.min_separation_m, "final": m.final_path_error_max}


def solve_times(seed: int = 1, n: int = 200) -> dict[str, tuple[float, float]]:
    """µs per filter call (median, p99) at 10 contacts + 10 obstacles, per filter."""
    from cdus.core.limits import default_limits
    from cdus.core.models import USV_PRESETS
    from cdus.core.obstacles import Box, Circle
    from cdus.core.safety import Contact, SafetyParams, Track, dynamic_filter, safety_filter, uav_point, usv_point

    rng = random.Random(f"obstacle_montecarlo:solve:{seed}")
    out: dict[str, list[float]] = {"velocity 2-D": [], "velocity 3-D": [], "usv_3dof": [], "uav_double_integrator": []}
    usv, uav = default_limits("usv_3dof"), default_limits("uav_double_integrator")
    for _ in range(n):
        for name in out:
            dim = 3 if name in ("velocity 3-D", "uav_double_integrator") else 2
            near = lambda r: tuple(rng.uniform(-r, r) for _ in range(dim))  # noqa: E731
            pts = [tuple(x * 1.5 * RADIUS for x in near(1.0)) for _ in range(10)]
            obs = tuple((Circle(near(6.0)[:2], rng.uniform(0.5, 2.0), 1.0) if dim == 2 else
                         Box(tuple(c - 1 for c in near(6.0)), tuple(c + 1 for c in near(6.0)), 1.0))
                        for _ in range(10))
            obs = tuple(o for o in obs if not isinstance(o, Box) or all(a < b for a, b in zip(o.lo, o.hi))) or obs[:0]
            params = SafetyParams(radius=RADIUS, obstacles=obs)
            ref = tuple(-x for x in pts[0])
            t0 = time.perf_counter()
            if name.startswith("velocity"):
                safety_filter(ref, (0.0,) * dim, [Contact(p, f"v{k}") for k, p in enumerate(pts)], params, "me")
            else:
                tracks = [Track(p, tuple(-x for x in p)) for p in pts]
                if dim == 2:
                    me = usv_point(0.0, 0.0, rng.uniform(-3, 3), 1.2, 0.0, 0.0, USV_PRESETS["cybership2"], (0.0, 0.0),
                                   usv.tau_u, usv.tau_r, usv.speed)
                    tau = (usv.tau_u, 0.0)
                else:
                    me = uav_point((0.0,) * 3, near(3.0), (0.0,) * 3, uav.accel)
                    tau = tuple(uav.accel / math.sqrt(3) for _ in range(3))
                dynamic_filter(tau, me, tracks, params, "me")
            out[name].append((time.perf_counter() - t0) * 1e6)
    return {k: (statistics.median(v), sorted(v)[int(0.99 * (len(v) - 1))]) for k, v in out.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--encounters", type=int, default=200)
    ap.add_argument("--presets", default=",".join(PRESETS))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--duration", type=float, default=25.0, help="simulated seconds per encounter")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--no-off", action="store_true", help="skip the runs with the filter off")
    ap.add_argument("--solve", action="store_true", help="also time the filter at 20 constraints")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args(argv)
    presets = [p for p in args.presets.split(",") if p]
    if any(p not in PRESETS for p in presets) or args.encounters < 1 or args.jobs < 1:
        ap.error(f"--presets from {', '.join(PRESETS)}; --encounters and --jobs >= 1")
    import cdus
    print(f"cdus from {Path(cdus.__file__).parent}; {args.encounters} encounters per preset, seed {args.seed}, "
          f"{args.duration:g} s each, {args.jobs} jobs; load {os.getloadavg()[0]:.2f}", flush=True)
    modes = (True,) if args.no_off else (True, False)
    jobs = [(generate(p, i, args.seed, args.duration), on) for p in presets for i in range(args.encounters)
            for on in modes]
    t0 = time.perf_counter()
    if args.jobs == 1:
        results = [_job(j) for j in jobs]
    else:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(_job, jobs, chunksize=2))
    report: dict[str, Any] = {"seed": args.seed, "encounters": args.encounters, "duration_s": args.duration,
                              "wall_s": round(time.perf_counter() - t0, 1), "presets": {}}
    print("| preset | filter | violations (< margin - 1 cm) | below margin | worst clearance - margin (m) | "
          "pairs < R - 1 cm | rejoined | wall per run (s) |\n|---|---|---|---|---|---|---|---|")
    for p in presets:
        for on in modes:
            rs = [r for (d, o), r in zip(jobs, results) if o == on and d["scenario"]["name"].startswith(f"omc_{p}_")]
            worst = [r["worst"] for r in rs]
            row = {"violations": sum(w < -TOLERANCE for w in worst), "below": sum(w < 0 for w in worst),
                   "worst": min(worst), "pairs": sum(r["sep"] is not None and r["sep"] < RADIUS - TOLERANCE for r in rs),
                   "rejoined": sum(r["final"] is not None and r["final"] < 0.2 for r in rs) / len(rs),
                   "wall": statistics.mean(r["wall"] for r in rs)}
            report["presets"].setdefault(p, {})["on" if on else "off"] = row
            print(f"| {p} | {'on' if on else 'off'} | {row['violations']} of {len(rs)} | {row['below']} | "
                  f"{row['worst']:.3f} | {row['pairs']} | {row['rejoined']:.0%} | {row['wall']:.2f} |")
    if args.solve:
        report["solve_us"] = solve_times(args.seed)
        print("\n| filter, 20 constraints | median µs | p99 µs |\n|---|---|---|")
        for k, (med, p99) in report["solve_us"].items():
            print(f"| {k} | {med:.0f} | {p99:.0f} |")
    print(f"wall {report['wall_s']} s; load {os.getloadavg()[0]:.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())

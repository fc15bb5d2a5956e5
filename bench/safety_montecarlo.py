"""Monte Carlo safety benchmark: randomized, seeded encounters, with and without the filter.

    python3 bench/safety_montecarlo.py [--encounters 200] [--presets ideal,usv_3dof,uav_double_integrator]
                                       [--seed 1] [--jobs N] [--json OUT]

For each plant preset it draws ``--encounters`` encounters and runs each one twice in the
in-process fleet (cdus.sim.fleet.InProcessFleet), with ``safety.enabled`` true and false,
everything else equal. The encounter kinds take turns (index mod 4):

- ``crossing``: 2-3 vehicles on straight lines crossing at a random angle (30-150° apart);
- ``head_on``: two vehicles on one line (170-190° apart), coming at each other;
- ``overtaking``: two vehicles on one line (within 10°), a fast one catching a slow one;
- ``converging``: 4-8 vehicles from all around onto one point.

Every vehicle follows a ``line`` path through a common meeting point P (each line shifted
sideways by up to 0.4 R), with ω0 = T (+-0.2): on its line, |f'| = its speed, ω falls at 1
per second, so every vehicle is at P (within its sideways shift) at t = T. All phases are
0: the formation (ω_i = ω_k) is consistent (docs/config.md) and is exactly the one that
puts everybody at P together, so an encounter is dangerous by construction (the table
shows how many really come within R without the filter). After P the lines diverge (the
overtaking pair: the fast one is ahead), so the formation can settle again. P is reached
at T = 6-10 s; each encounter runs 40 simulated seconds (0.1-0.6 s of wall time each).

Presets: ``ideal`` (boats, ideal plant, speed cap 2 m/s), ``usv_3dof`` (cybership2 boats,
heading regulator, the preset's limits), ``uav_double_integrator`` (drones at a common
10 m altitude, the preset's limits); ``cross_domain`` (opt-in: two usv_3dof boats crossing
at P and an ``uav_double_integrator`` drone that starts 8 m up and descends onto a line
0.3-1.5 m above the water through P; only the drone avoids, docs/safety.md "Across
domains"). The filter's parameters: R = 2 m, γ = 1, range 10 m, 10 Hz, 20 ms latency
(configs/crossing.toml's); control 50 Hz, physics 200 Hz.

What it prints per preset and filter setting:

- violations: encounters whose minimum separation (metrics ``min_separation_m``, same
  domain; for cross_domain also the drone-to-boat distance, the boat a point at (x, y, 0))
  is below R - 0.01 m (the tolerance the tests use: the filter acts on positions one sensor
  period plus latency old), and separately how many are strictly below R;
- min separation distribution: min, p5, p50 over the encounters;
- interventions: control steps at which a filter changed a reference, summed per run;
  mean per encounter and the largest;
- settled: fraction of encounters in which both the path (worst |Φ| < path_tol = 0.2 m)
  and the coordination (worst edge < coord_tol = 0.05) settle before the end, with the
  median settle times;
- solve time: every call of the filter is timed in the worker (the function the vehicle
  imported from cdus.core.safety, or if it imported none the module's public functions
  named *filter*, wrapped with time.perf_counter at run time); µs per call (the
  mean: total filter time / calls) and per control step of the fleet (filter time summed
  over the vehicles / control ticks). Also the wall time per run with and without the filter.

It uses only the public scenario and fleet APIs, so it runs against any checkout:
``PYTHONPATH=/path/to/checkout python3 bench/safety_montecarlo.py`` uses that checkout's
cdus (without PYTHONPATH, the checkout this script is in). It prints which one it used.
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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

if not os.environ.get("PYTHONPATH"):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout, not an installed copy

import numpy as np  # noqa: E402

from cdus.scenario.config import parse_scenario  # noqa: E402
from cdus.sim.fleet import InProcessFleet  # noqa: E402

RADIUS = 2.0
TOLERANCE = 0.01  # m: a violation is min separation < RADIUS - TOLERANCE
KINDS = ("crossing", "head_on", "overtaking", "converging")
PRESETS = ("ideal", "usv_3dof", "uav_double_integrator")
ALL_PRESETS = PRESETS + ("cross_domain",)
ALTITUDE = 10.0  # m: the drones' common altitude
DURATION = 40.0  # s simulated per encounter
PATH_TOL = 0.2
COORD_TOL = 0.05

#: preset -> (vehicle kind, plant, limits, speed range m/s)
PLANTS: dict[str, tuple[str, str, dict, tuple[float, float]]] = {
    "ideal": ("usv", "ideal", {"speed": 2.0}, (0.8, 1.5)),
    "usv_3dof": ("usv", "usv_3dof", {"preset": True}, (0.8, 1.5)),
    "uav_double_integrator": ("uav", "uav_double_integrator", {"preset": True}, (2.0, 4.0)),
}


@dataclass(frozen=True)
class Encounter:
    preset: str
    index: int
    kind: str
    meet_time: float  # s: when the vehicles reach P
    data: dict = field(compare=False)  # the scenario, as parsed TOML, safety.enabled true

    def scenario_data(self, safety: bool) -> dict:
        d = json.loads(json.dumps(self.data))
        d["safety"]["enabled"] = safety
        return d


def _unit(angle: float) -> tuple[float, float]:
    return math.cos(angle), math.sin(angle)


def _vehicle(vid: str, kind: str, plant: str, limits: dict, travel: float, speed: float, shift: float,
             omega0: float, meet: tuple[float, float], altitude: float | None) -> dict:
    """A vehicle on a line through ``meet`` (shifted ``shift`` m to its left), travelling
    along the angle ``travel`` at ``speed``: at ω it is at origin + speed ω (-d), so with
    direction -1 (ω falling at 1/s) it reaches the line's origin at t = omega0."""
    dx, dy = _unit(travel)
    nx, ny = -dy, dx
    origin = [meet[0] + shift * nx, meet[1] + shift * ny]
    heading = [-dx, -dy]
    if altitude is not None:
        origin.append(altitude)
        heading.append(0.0)
    return {
        "id": vid, "kind": kind, "plant": plant, "phase": 0.0, "omega0": omega0, "limits": dict(limits),
        "path": {"family": "line", "origin": [round(x, 9) for x in origin], "heading": [round(x, 12) for x in heading],
                 "speed": round(speed, 9)},
    }


def _base(name: str, seed: int, vehicles: list[dict]) -> dict:
    return {
        "scenario": {"name": name, "description": "safety_montecarlo encounter", "duration": DURATION, "seed": seed},
        "rates": {"physics": 200.0, "control": 50.0},
        "metrics": {"path_tol": PATH_TOL, "coord_tol": COORD_TOL},
        "gains": {"k": 1.5, "c": 0.5},
        "graph": {"topology": "ring"},
        "safety": {"enabled": True, "radius": RADIUS, "gamma": 1.0, "range": 10.0, "rate": 10.0, "latency": 0.02},
        "vehicle": vehicles,
    }


def generate(preset: str, index: int, seed: int) -> Encounter:
    """The ``index``-th encounter of ``preset`` for ``seed``: the same every run."""
    if preset not in ALL_PRESETS:
        raise ValueError(f"unknown preset {preset!r}; choose from {', '.join(ALL_PRESETS)}")
    rng = random.Random(f"safety_montecarlo:{seed}:{preset}:{index}")
    while True:  # redrawn (from the same stream: still deterministic) until every pair starts outside 1.5 R
        enc = _draw(rng, preset, index, seed)
        if _starts_apart(enc, 1.5 * RADIUS):
            return enc


def _starts_apart(enc: "Encounter", gap: float) -> bool:
    """Whether every two vehicles start at least ``gap`` apart (a start inside R is no encounter
    a filter can be judged on: the bench once drew two ideal vehicles 1.746 m apart at t = 0)."""
    starts = []
    for v in enc.data["vehicle"]:
        if "start" in v:
            starts.append(v["start"]["position"][:2])
        else:
            path = v["path"]
            starts.append([o + path["speed"] * v["omega0"] * h for o, h in zip(path["origin"], path["heading"])][:2])
    return all(math.dist(a, b) >= gap for i, a in enumerate(starts) for b in starts[i + 1:])


def _draw(rng: random.Random, preset: str, index: int, seed: int) -> "Encounter":
    meet_t = rng.uniform(6.0, 10.0)
    meet = (rng.uniform(-20.0, 20.0), rng.uniform(-20.0, 20.0))
    base_dir = rng.uniform(-math.pi, math.pi)
    name = f"mc_{preset}_{index}"
    if preset == "cross_domain":
        return _cross_domain(rng, preset, index, seed, meet_t, meet, base_dir, name)
    vkind, plant, limits, (vlo, vhi) = PLANTS[preset]
    alt = ALTITUDE if vkind == "uav" else None
    kind = KINDS[index % len(KINDS)]
    shift = lambda: rng.uniform(-0.4, 0.4) * RADIUS  # noqa: E731
    jitter = lambda: rng.uniform(-0.2, 0.2)  # noqa: E731
    travels: list[float] = []
    speeds: list[float] = []
    if kind == "crossing":
        n = rng.choice((2, 2, 3))
        travels = [base_dir]
        for _ in range(n - 1):
            travels.append(travels[-1] + rng.choice((-1, 1)) * math.radians(rng.uniform(30.0, 150.0)))
        speeds = [rng.uniform(vlo, vhi) for _ in range(n)]
    elif kind == "head_on":
        travels = [base_dir, base_dir + math.pi + math.radians(rng.uniform(-10.0, 10.0))]
        speeds = [rng.uniform(vlo, vhi) for _ in range(2)]
    elif kind == "overtaking":
        travels = [base_dir, base_dir + math.radians(rng.uniform(-10.0, 10.0))]
        fast = rng.uniform(0.5 * (vlo + vhi), vhi)
        speeds = [fast, fast * rng.uniform(0.4, 0.6)]
    else:  # converging
        n = rng.randint(4, 8)
        travels = [base_dir + 2.0 * math.pi * j / n + math.radians(rng.uniform(-10.0, 10.0)) for j in range(n)]
        speeds = [rng.uniform(vlo, vhi) for _ in range(n)]
    prefix = "uav" if vkind == "uav" else "usv"
    vehicles = [_vehicle(f"{prefix}{j + 1}", vkind, plant, limits, tr, sp, shift(), round(meet_t + jitter(), 6),
                         meet, alt) for j, (tr, sp) in enumerate(zip(travels, speeds))]
    return Encounter(preset, index, kind, meet_t, _base(name, seed, vehicles))


def _cross_domain(rng: random.Random, preset: str, index: int, seed: int, meet_t: float, meet: tuple[float, float],
                  base_dir: float, name: str) -> Encounter:
    """Two usv_3dof boats crossing at P, and a drone descending from 8 m onto a line 0.3-1.5 m
    above the water through P, timed to be over P with them."""
    _, plant, limits, (vlo, vhi) = PLANTS["usv_3dof"]
    travels = [base_dir, base_dir + rng.choice((-1, 1)) * math.radians(rng.uniform(30.0, 150.0))]
    boats = [_vehicle(f"usv{j + 1}", "usv", plant, limits, tr, rng.uniform(vlo, vhi), rng.uniform(-0.4, 0.4) * RADIUS,
                      round(meet_t + rng.uniform(-0.2, 0.2), 6), meet, None) for j, tr in enumerate(travels)]
    low = rng.uniform(0.3, 1.5)
    travel = base_dir + math.radians(rng.uniform(60.0, 300.0))
    speed = rng.uniform(1.5, 3.0)
    drone = _vehicle("uav1", "uav", "uav_double_integrator", {"preset": True}, travel, speed, 0.0, meet_t, meet, low)
    on_path = [o + speed * meet_t * h for o, h in zip(drone["path"]["origin"], drone["path"]["heading"])]
    drone["start"] = {"position": [round(on_path[0], 9), round(on_path[1], 9), 8.0]}
    return Encounter(preset, index, "descent", meet_t, _base(name, seed, boats + [drone]))


def encounters(preset: str, count: int, seed: int) -> list[Encounter]:
    return [generate(preset, i, seed) for i in range(count)]


# --------------------------------------------------------------------------- timing the filter

_TIMES: list[float] = []
_TIMER_ON = False


def _install_timer() -> list[str]:
    """Wrap every function cdus.core.vehicle imported from cdus.core.safety whose name says
    "filter" with a perf_counter timer (once per process); if it imported none (it calls
    them through the module), those functions of cdus.core.safety itself. Returns the
    wrapped names."""
    global _TIMER_ON
    import cdus.core.safety as safety_mod
    import cdus.core.vehicle as vehicle_mod

    def filters(mod):
        return [n for n, f in vars(mod).items()
                if callable(f) and not isinstance(f, type) and not n.startswith("_")
                and getattr(f, "__module__", "") == "cdus.core.safety" and "filter" in n.lower()]

    where, names = vehicle_mod, filters(vehicle_mod)
    if not names:
        where, names = safety_mod, filters(safety_mod)
    if _TIMER_ON:
        return [f"{where.__name__}.{n}" for n in names]
    for n in names:
        inner = getattr(where, n)

        def timed(*args, _inner=inner, **kwargs):
            t0 = time.perf_counter()
            try:
                return _inner(*args, **kwargs)
            finally:
                _TIMES.append(time.perf_counter() - t0)

        timed.__name__ = n
        timed.__module__ = "cdus.core.safety"
        setattr(where, n, timed)
    _TIMER_ON = True
    return [f"{where.__name__}.{n}" for n in names]


def _cross_min(q: np.ndarray, kinds: list[str]) -> float | None:
    """Smallest drone-to-boat distance, the boat a point on the water (x, y, 0)."""
    uav = [j for j, k in enumerate(kinds) if k == "uav"]
    usv = [j for j, k in enumerate(kinds) if k == "usv"]
    best = math.inf
    for a in uav:
        for b in usv:
            boat = q[:, b, :].copy()
            boat[:, 2] = 0.0
            best = min(best, float(np.min(np.linalg.norm(q[:, a, :] - boat, axis=1))))
    return best if math.isfinite(best) else None


def run_encounter(enc: Encounter, safety: bool) -> dict[str, Any]:
    """One run; the figures the tables need (an exception is reported, not raised)."""
    _install_timer()
    del _TIMES[:]
    out: dict[str, Any] = {"preset": enc.preset, "index": enc.index, "kind": enc.kind, "safety": safety}
    try:
        scenario = parse_scenario(enc.scenario_data(safety), source=f"<{enc.data['scenario']['name']}>")
        fleet = InProcessFleet(scenario, clock=time.perf_counter)
        t0 = time.perf_counter()
        res = fleet.run()
        wall = time.perf_counter() - t0
    except Exception as e:  # noqa: BLE001 - a bench reports every failure and carries on
        out["error"] = f"{type(e).__name__}: {e}"
        return out
    m = res.metrics
    kinds = [v.kind for v in scenario.vehicles]
    sep = m.min_separation_m
    cross = _cross_min(res.recorder.view("q"), kinds)
    worst = min([s for s in (sep, cross) if s is not None], default=None)
    out.update({
        "vehicles": len(kinds), "min_separation_m": sep, "cross_separation_m": cross, "worst_separation_m": worst,
        "interventions": m.interventions, "path_settle_s": m.path_settle_s,
        "coord_settle_s": m.coord_settle_s, "filter_calls": len(_TIMES), "filter_s": float(sum(_TIMES)),
        "filter_us_p50": float(np.percentile(_TIMES, 50) * 1e6) if _TIMES else None,
        "filter_us_p99": float(np.percentile(_TIMES, 99) * 1e6) if _TIMES else None,
        "ticks": len(res.recorder), "wall_s": wall, "completed": m.completed,
    })
    return out


def _job(args: tuple[Encounter, bool]) -> dict[str, Any]:
    return run_encounter(*args)


# --------------------------------------------------------------------------- the tables


def _pct(values: list[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None


def _f(x: float | None, spec: str = ".3f") -> str:
    return "n/a" if x is None else format(x, spec)


def summarize(rows: list[dict]) -> dict[str, Any]:
    ok = [r for r in rows if "error" not in r]
    seps = [r["worst_separation_m"] for r in ok if r["worst_separation_m"] is not None]
    cross = [r["cross_separation_m"] for r in ok if r.get("cross_separation_m") is not None]
    settled = [r for r in ok if r["path_settle_s"] is not None and r["coord_settle_s"] is not None]
    calls = sum(r["filter_calls"] for r in ok)
    ticks = sum(r["ticks"] for r in ok)
    ftime = sum(r["filter_s"] for r in ok)
    return {
        "encounters": len(rows), "errors": len(rows) - len(ok),
        "violations": sum(1 for s in seps if s < RADIUS - TOLERANCE),
        "strictly_below_radius": sum(1 for s in seps if s < RADIUS),
        "min_sep_min": min(seps) if seps else None, "min_sep_p5": _pct(seps, 5), "min_sep_p50": _pct(seps, 50),
        "cross_violations": sum(1 for s in cross if s < RADIUS - TOLERANCE) if cross else None,
        "cross_min_sep_min": min(cross) if cross else None, "cross_min_sep_p5": _pct(cross, 5),
        "cross_min_sep_p50": _pct(cross, 50),
        "interventions_mean": statistics.mean(r["interventions"] for r in ok) if ok else None,
        "interventions_max": max((r["interventions"] for r in ok), default=None),
        "settled": len(settled), "settled_fraction": len(settled) / len(ok) if ok else None,
        "path_settle_p50": _pct([r["path_settle_s"] for r in settled], 50),
        "coord_settle_p50": _pct([r["coord_settle_s"] for r in settled], 50),
        "filter_calls": calls, "filter_us_per_call": (ftime / calls * 1e6) if calls else None,
        "filter_us_per_step": (ftime / ticks * 1e6) if ticks else None,
        "wall_s_per_run": statistics.mean(r["wall_s"] for r in ok) if ok else None,
        "by_kind": {k: sum(1 for r in ok if r["kind"] == k and r["worst_separation_m"] is not None
                           and r["worst_separation_m"] < RADIUS - TOLERANCE)
                    for k in sorted({r["kind"] for r in ok})},
    }


def print_table(summary: dict[str, dict[str, dict]]) -> None:
    print(f"\nR = {RADIUS} m; violation: min separation < R - {TOLERANCE} m (strictly below R in brackets); "
          f"settled: path (|Φ| < {PATH_TOL} m) and coordination (< {COORD_TOL}) both settle within {DURATION:g} s; "
          f"violations and min sep count every pair (cross_domain: the boats' pair too; its drone-to-boat figures "
          f"below)")
    head = ("| preset | filter | encounters | violations (< R) | min sep min / p5 / p50 m | interventions mean / max "
            "| settled (path / coord p50 s) | filter µs per call / per step | wall s per run |")
    print(head)
    print("|" + "---|" * 9)
    for preset, by in summary.items():
        for label in ("off", "on"):
            s = by.get(label)
            if s is None:
                continue
            settled = (f"{s['settled']}/{s['encounters'] - s['errors']} ({_f(s['path_settle_p50'], '.1f')} / "
                       f"{_f(s['coord_settle_p50'], '.1f')})")
            print(f"| {preset} | {label} | {s['encounters']}" + (f" ({s['errors']} errors)" if s['errors'] else "")
                  + f" | {s['violations']} ({s['strictly_below_radius']}) | {_f(s['min_sep_min'])} / "
                  f"{_f(s['min_sep_p5'])} / {_f(s['min_sep_p50'])} | {_f(s['interventions_mean'], '.1f')} / "
                  f"{s['interventions_max']} | {settled} | {_f(s['filter_us_per_call'], '.1f')} / "
                  f"{_f(s['filter_us_per_step'], '.1f')} | {_f(s['wall_s_per_run'], '.2f')} |")
    for preset, by in summary.items():
        off, on = by.get("off"), by.get("on")
        if off and on:
            n = off["encounters"] - off["errors"]
            print(f"{preset}: dangerous without the filter (within R): {off['strictly_below_radius']}/{n}; "
                  f"violations by kind without / with: {off['by_kind']} / {on['by_kind']}")
        for label, s in by.items():
            if s["cross_violations"] is not None:
                print(f"{preset} ({label}): drone-to-boat only (the boat a point on the water): "
                      f"{s['cross_violations']} "
                      f"violations, min / p5 / p50 {_f(s['cross_min_sep_min'])} / {_f(s['cross_min_sep_p5'])} / "
                      f"{_f(s['cross_min_sep_p50'])} m")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--encounters", type=int, default=200, help="encounters per preset (default 200)")
    ap.add_argument("--presets", default=",".join(PRESETS),
                    help=f"comma-separated, from {', '.join(ALL_PRESETS)} (default: {','.join(PRESETS)})")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="worker processes (default: the cores)")
    ap.add_argument("--json", metavar="OUT", help="write every run and the summary as JSON")
    ap.add_argument("--filter", choices=("both", "on", "off"), default="both", help="which runs (default both)")
    args = ap.parse_args(argv)
    presets = [p.strip() for p in args.presets.split(",") if p.strip()]
    bad = [p for p in presets if p not in ALL_PRESETS]
    if bad or args.encounters < 1 or args.jobs < 1:
        ap.error(f"unknown preset(s) {bad}; choose from {', '.join(ALL_PRESETS)}" if bad
                 else "--encounters and --jobs must be >= 1")
    import cdus

    wrapped = _install_timer()
    timing = ", ".join(wrapped) or "nothing (no filter function found)"
    print(f"cdus from {os.path.dirname(cdus.__file__)}; timing {timing}"
          f"; {args.encounters} encounters per preset, seed {args.seed}, {args.jobs} jobs", flush=True)
    modes = {"both": (False, True), "on": (True,), "off": (False,)}[args.filter]
    jobs = [(enc, on) for p in presets for enc in encounters(p, args.encounters, args.seed) for on in modes]
    t0 = time.perf_counter()
    rows: list[dict] = []
    if args.jobs == 1:
        for j in jobs:
            rows.append(_job(j))
    else:
        with ProcessPoolExecutor(args.jobs, initializer=_install_timer) as pool:
            for i, r in enumerate(pool.map(_job, jobs, chunksize=2)):
                rows.append(r)
                if (i + 1) % max(1, len(jobs) // 10) == 0:
                    print(f"  {i + 1}/{len(jobs)} runs, {time.perf_counter() - t0:.0f} s", file=sys.stderr, flush=True)
    wall = time.perf_counter() - t0
    errors = [r for r in rows if "error" in r]
    for r in errors[:5]:
        print(f"  error in {r['preset']} #{r['index']} ({r['kind']}, filter {'on' if r['safety'] else 'off'}): "
              f"{r['error']}", file=sys.stderr)
    summary = {p: {("on" if on else "off"): summarize([r for r in rows if r["preset"] == p and r["safety"] == on])
                   for on in modes} for p in presets}
    print_table(summary)
    print(f"\n{len(rows)} runs in {wall:.0f} s wall ({args.jobs} jobs)")
    if args.json:
        Path(args.json).write_text(json.dumps({"args": vars(args), "radius": RADIUS, "tolerance": TOLERANCE,
                                               "summary": summary, "runs": rows, "wall_s": wall}, indent=1))
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())

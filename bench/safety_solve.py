"""Safety filter solve time per call for 2, 6 and 20 neighbours (docs/safety.md): the
velocity-level filter (one call per control step) and the dynamic filter (one call per
physics step, cdus.core.safety.dynamic_filter).

Each case puts one vehicle among n contacts (seeded random positions in a ring 1.2-3 R
around it, a velocity reference pointing into them so every constraint matters) and times
cdus.core.safety.safety_filter over many calls, with the method it took (pass,
projection, qp, relaxed). Also timed: the whole proximity sensor (cdus.core.proximity.sense)
for a fleet. Prints figures; asserts nothing (this machine is noisy).

    python3 -m bench.safety_solve
"""

from __future__ import annotations

import math
import random
import time
from collections import Counter

from cdus.core.proximity import Body, sense
from cdus.core.limits import default_limits
from cdus.core.plants import USV_PRESETS
from cdus.core.safety import Contact, SafetyParams, Track, dynamic_filter, safety_filter, uav_point, usv_point

R = 2.0
PARAMS = SafetyParams(radius=R, gamma=1.0)


def case(n: int, seed: int, dim: int) -> tuple[tuple[float, ...], tuple[float, ...], tuple[Contact, ...]]:
    rng = random.Random(f"{n}/{seed}/{dim}")
    q = (0.0,) * dim
    contacts = []
    for k in range(n):
        a, r = rng.uniform(0, 2 * math.pi), rng.uniform(1.2 * R, 3.0 * R)
        p = (r * math.cos(a), r * math.sin(a)) + ((rng.uniform(-1, 1),) if dim == 3 else ())
        contacts.append(Contact(p, f"v{k}", 0.5))
    a = rng.uniform(0, 2 * math.pi)
    u_ref = (2.0 * math.cos(a), 2.0 * math.sin(a)) + ((0.0,) if dim == 3 else ())
    return q, u_ref, tuple(contacts)


def time_filter(n: int, dim: int, cases: int = 200, repeat: int = 20) -> tuple[float, float, Counter]:
    """(median, p99) µs per call over ``cases`` random situations, and the methods taken."""
    per = []
    methods: Counter = Counter()
    for seed in range(cases):
        q, u_ref, contacts = case(n, seed, dim)
        _, info = safety_filter(u_ref, q, contacts, PARAMS, "me")
        methods[info.method] += 1
        t0 = time.perf_counter()
        for _ in range(repeat):
            safety_filter(u_ref, q, contacts, PARAMS, "me")
        per.append((time.perf_counter() - t0) / repeat * 1e6)
    per.sort()
    return per[len(per) // 2], per[int(0.99 * (len(per) - 1))], methods


def dynamic_case(n: int, seed: int, plant: str):
    """One vehicle (UAV or cybership2 boat, preset limits) closing at speed on n neighbours in a
    ring 1.2-3 R around it, each closing too: every row matters."""
    rng = random.Random(f"dyn/{n}/{seed}/{plant}")
    tracks = []
    dim = 3 if plant == "uav" else 2
    for k in range(n):
        a, r = rng.uniform(0, 2 * math.pi), rng.uniform(1.2 * R, 3.0 * R)
        p = (r * math.cos(a), r * math.sin(a)) + ((rng.uniform(-1, 1),) if dim == 3 else ())
        v = tuple(-x / r * rng.uniform(0.0, 1.5) for x in p)
        tracks.append(Track(p, v, 0.5, 0.01, 0.2, f"v{k}"))
    a = rng.uniform(0, 2 * math.pi)
    if plant == "uav":
        lim = default_limits("uav_double_integrator")
        me = uav_point((0.0, 0.0, 0.0), (3.0 * math.cos(a), 3.0 * math.sin(a), 0.0), (0.0, 0.0, 0.0), lim.accel)
        ref = (lim.accel * math.cos(a), lim.accel * math.sin(a), 0.0)
    else:
        lim = default_limits("usv_3dof")
        me = usv_point(0.0, 0.0, a, 1.5, 0.0, 0.1, USV_PRESETS["cybership2"], (0.0, 0.0), lim.tau_u, lim.tau_r,
                       lim.speed)
        ref = (lim.tau_u, 0.5)
    return ref, me, tuple(tracks)


def time_dynamic(n: int, plant: str, cases: int = 200, repeat: int = 20) -> tuple[float, float, Counter]:
    """(median, p99) µs per call of the dynamic filter (one call per physics step)."""
    per = []
    methods: Counter = Counter()
    for seed in range(cases):
        ref, me, tracks = dynamic_case(n, seed, plant)
        _, info = dynamic_filter(ref, me, tracks, PARAMS, "me")
        methods[info.method] += 1
        t0 = time.perf_counter()
        for _ in range(repeat):
            dynamic_filter(ref, me, tracks, PARAMS, "me")
        per.append((time.perf_counter() - t0) / repeat * 1e6)
    per.sort()
    return per[len(per) // 2], per[int(0.99 * (len(per) - 1))], methods


def time_sensor(n: int, repeat: int = 50) -> float:
    rng = random.Random(n)
    side = 10.0 * math.sqrt(n)
    bodies = [Body(f"v{j}", "usv", (rng.uniform(0, side), rng.uniform(0, side))) for j in range(n)]
    t0 = time.perf_counter()
    for _ in range(repeat):
        sense(bodies, 20.0)
    return (time.perf_counter() - t0) / repeat * 1e6


def main() -> None:
    print("safety filter, one call per control step (quadprog when a QP is needed)")
    print(f"{'neighbours':>10} {'dim':>4} {'median µs':>10} {'p99 µs':>8}  methods")
    for dim in (2, 3):
        for n in (2, 6, 20):
            med, p99, methods = time_filter(n, dim)
            print(f"{n:>10} {dim:>4} {med:>10.1f} {p99:>8.1f}  {dict(methods)}")
    print("\ndynamic filter (usv_3dof, uav_double_integrator), one call per physics step while a contact is in range")
    print(f"{'neighbours':>10} {'plant':>5} {'median µs':>10} {'p99 µs':>8}  methods")
    for plant in ("usv", "uav"):
        for n in (2, 6, 20):
            med, p99, methods = time_dynamic(n, plant)
            print(f"{n:>10} {plant:>5} {med:>10.1f} {p99:>8.1f}  {dict(methods)}")
    print("\nproximity sensor (the world, per sample, all vehicles, 20 m range)")
    for n in (6, 64, 256):
        print(f"{n:>10} vehicles {time_sensor(n):>10.1f} µs")


if __name__ == "__main__":
    main()

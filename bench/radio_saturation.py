"""When does the shared radio medium saturate? Fleet size x broadcast rate x message size.

    python bench/radio_saturation.py [--messages 2000]

Uses the channel model (cdus/core/radio.py, docs/radio.md) directly, with the default
``[radio]`` medium (6 Mbit/s, 50 µs preamble, CSMA with a 9 µs vulnerable slot, 8-message
queues, 64 header bytes): a fleet of N boats on a circle of radius 40 m (well inside radio
range: what is lost here is lost to the medium), every one broadcasting at r Hz, in the two
topologies (adhoc; station: a base station at the centre relays every message, so every
message is on the air twice).

1. A table per topology: for each (N, r, payload), the utilisation ρ (offered airtime per
   second), the mean queueing wait (M/D/1, capped by the queues), the model's delivery
   probability and the delivery ratio measured over ``--messages`` decisions (random
   sender, receiver and seq).
2. The saturation point per (topology, r, payload): the smallest N with ρ >= 1, and the
   smallest N whose delivery probability is below 0.9.
"""

from __future__ import annotations

import argparse
import math
import random
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages, not an installed copy

from cdus.core.radio import Geometry, RadioChannel, RadioSpec  # noqa: E402

RADIUS = 40.0
SIZES = (32, 512)  # payload bytes: the ω message, and a larger one (e.g. telemetry)
RATES = (10.0, 50.0, 100.0)
FLEETS = (4, 8, 16, 32, 64, 128, 256)


def fleet(n: int, topology: str, rate: float, size: int) -> tuple[RadioChannel, Geometry]:
    spec = RadioSpec(topology=topology, station=(0.0, 0.0, 0.0))
    ids = [f"usv{j}" for j in range(n)]
    ch = RadioChannel(spec, ids, ["usv"] * n, 1, rate=rate, size=size)
    pos = [(RADIUS * math.cos(2 * math.pi * j / n), RADIUS * math.sin(2 * math.pi * j / n)) for j in range(n)]
    return ch, Geometry.of(0, pos)


def row(n: int, topology: str, rate: float, size: int, messages: int) -> tuple[float, float, float, float]:
    ch, geo = fleet(n, topology, rate, size)
    m = ch.medium(geo)
    rng = random.Random(n * 1000 + int(rate) + size)
    senders = list(range(min(n, 8)))  # a few links (each link's shadowing field costs ~1 ms to draw)
    got = 0
    p_sum = 0.0
    for seq in range(messages):
        src = rng.choice(senders)
        dst = rng.choice([j for j in senders if j != src])
        d = ch.decide(src, dst, seq, 0.0, geo)
        got += d.delivered
        p_sum += d.p
    return m.utilisation, m.wait, p_sum / messages, got / messages


def predicted(n: int, topology: str, rate: float, size: int) -> float:
    ch, geo = fleet(n, topology, rate, size)
    return ch.delivery_probability(0, 1, geo)


def utilisation(n: int, topology: str, rate: float, size: int) -> float:
    ch, geo = fleet(n, topology, rate, size)
    return ch.utilisation(geo)


def smallest(pred, lo: int = 2, hi: int = 4096) -> int | None:
    """The smallest n in [lo, hi] with pred(n) (pred monotone in n), None if none."""
    if not pred(hi):
        return None
    while lo < hi:
        mid = (lo + hi) // 2
        if pred(mid):
            hi = mid
        else:
            lo = mid + 1
    return lo


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--messages", type=int, default=2000, help="decisions measured per row")
    args = ap.parse_args()
    spec = RadioSpec()
    print(f"default medium: capacity {spec.capacity:g} bit/s, preamble {spec.preamble * 1e6:g} µs, "
          f"{spec.access} slot {spec.slot * 1e6:g} µs, queue {spec.queue} per transmitter, header {spec.header} B; "
          f"{args.messages} decisions per row; boats on a {RADIUS:g} m circle")
    for topology in ("adhoc", "station"):
        print(f"\n1. {topology}")
        print(f"  {'N':>4} {'rate Hz':>8} {'payload B':>9} {'util ρ':>8} {'wait ms':>8} {'p model':>8} "
              f"{'measured':>8}")
        for size in SIZES:
            for rate in RATES:
                for n in FLEETS:
                    rho, wait, p, got = row(n, topology, rate, size, args.messages)
                    print(f"  {n:>4} {rate:>8g} {size:>9} {rho:>8.3f} {wait * 1e3:>8.3f} {p:>8.3f} {got:>8.3f}")
    print("\n2. saturation point: the smallest fleet with ρ >= 1, and with delivery probability < 0.9")
    print(f"  {'topology':>8} {'rate Hz':>8} {'payload B':>9} {'N at ρ>=1':>10} {'N at p<0.9':>10} "
          f"{'N·rate at ρ=1':>14}")
    for topology in ("adhoc", "station"):
        for size in SIZES:
            for rate in RATES:
                n_sat = smallest(lambda n: utilisation(n, topology, rate, size) >= 1.0)
                n_90 = smallest(lambda n: predicted(n, topology, rate, size) < 0.9)
                ch, _ = fleet(2, topology, rate, size)
                per_s = 1.0 / (ch.air * (2 if topology == "station" else 1))
                print(f"  {topology:>8} {rate:>8g} {size:>9} {str(n_sat):>10} {str(n_90):>10} {per_s:>14.0f}")


if __name__ == "__main__":
    main()

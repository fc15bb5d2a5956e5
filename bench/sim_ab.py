"""Is `cdus sim` as fast as it was? This checkout against another one, interleaved in one run.

    git archive BASE | tar -x -C /tmp/base
    python bench/sim_ab.py /tmp/base --rounds 3

Each round runs, in a fresh interpreter per checkout (its packages first on PYTHONPATH) and in
alternating order, the in-process fleet of lake_circle (ideal plants, 100 s simulated) and
lake_circle_dynamic (usv_3dof and uav_double_integrator, 40 s) and prints the CPU seconds of
its run (process time: less sensitive to the machine's load than wall time); then the median per case and checkout, and the ratio this/other. The load average is
printed with each round (a shared machine): compare only figures of the same run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CASES = {"lake_circle 100 s": ("lake_circle", 100.0), "lake_circle_dynamic 40 s": ("lake_circle_dynamic", 40.0)}
PROBE = """
import sys, time
from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
sc = load_scenario(sys.argv[1], {"scenario.duration": float(sys.argv[2])})
fleet = InProcessFleet(sc)
t0 = time.process_time()
fleet.run()
print(time.process_time() - t0)
"""


def cpu(checkout: Path, config: str, duration: float) -> float:
    env = dict(os.environ, PYTHONPATH=str(checkout))
    out = subprocess.run([sys.executable, "-c", PROBE, str(ROOT / "configs" / f"{config}.toml"), str(duration)],
                         env=env, cwd=checkout, check=True, capture_output=True, text=True).stdout
    return float(out.split()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("other", type=Path, help="the other checkout (e.g. the base commit's tree)")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    runs: dict[tuple[str, str], list[float]] = {}
    sides = {"this": ROOT, "other": args.other.resolve()}
    for r in range(args.rounds):
        order = list(sides) if r % 2 == 0 else list(reversed(sides))
        for case, (config, duration) in CASES.items():
            for side in order:
                w = cpu(sides[side], config, duration)
                runs.setdefault((case, side), []).append(w)
                print(f"round {r}  {case:<26} {side:<5} {w:7.2f} s   load {os.getloadavg()[0]:.2f}", flush=True)
    for case in CASES:
        this, other = statistics.median(runs[(case, "this")]), statistics.median(runs[(case, "other")])
        print(f"{case:<26} median this {this:.2f} s, other {other:.2f} s, this/other {this / other:.3f}")


if __name__ == "__main__":
    main()

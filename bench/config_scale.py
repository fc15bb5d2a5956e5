"""How does validating a scenario scale with the fleet? Seconds from TOML text to a validated Scenario.

    python bench/config_scale.py                   # 100, 1,000, 10,000 vehicles
    python bench/config_scale.py --sizes 100,1000

For each size n it prints the time to parse and validate a ring of n vehicles, an
explicit chain written as graph.edges with per-edge [[graph.edge]] deltas (the cycle and
reference checks), and a graph with no spanning tree (n/2 separate pairs: the error path).
The fleet-size limit (cdus.scenario.vehicles.MAX_VEHICLES) is lifted here to measure the
algorithms past it; the last line shows that a fleet over the limit is refused at once.
Figures are printed, never asserted (this machine is noisy): linear growth means the
time per vehicle stays flat.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages, not an installed copy

from cdus.scenario import vehicles as vehicles_module  # noqa: E402
from cdus.scenario.config import ConfigError, parse_text, parse_scenario  # noqa: E402


def fleet_toml(n: int, graph: str) -> str:
    out = ['[scenario]\nname = "scale"\n', graph]
    for j in range(n):
        out.append(f'[[vehicle]]\nid = "v{j}"\nkind = "usv"\nphase = {0.001 * j}\n'
                   f'path = {{ family = "circle", center = [0, 0], radius = 10 }}\n')
    return "\n".join(out)


def cases(n: int) -> dict[str, str]:
    chain = ", ".join(f'["v{j}", "v{j - 1}"]' for j in range(1, n))
    edge_tables = "".join(f'[[graph.edge]]\ni = "v{j}"\nk = "v{j - 1}"\ndelta = 0.001\n' for j in range(1, n))
    pairs = ", ".join(f'["v{j}", "v{j + 1}"]' for j in range(0, n - 1, 2))
    return {
        "ring": '[graph]\ntopology = "ring"\n',
        "explicit chain + deltas": f'[graph]\ntopology = "explicit"\nedges = [{chain}]\n{edge_tables}',
        "no spanning tree (error)": f'[graph]\ntopology = "explicit"\ndirected = true\nedges = [{pairs}]\n',
    }


def timed(text: str) -> tuple[float, str]:
    t0 = time.perf_counter()
    try:
        parse_scenario(parse_text(text.encode(), "<bench>"), "<bench>")
        outcome = "valid"
    except ConfigError as e:
        outcome = f"{len(e.problems)} problem(s)"
    return time.perf_counter() - t0, outcome


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="100,1000,10000")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    limit = vehicles_module.MAX_VEHICLES
    print(f"{'case':<28} {'n':>7} {'seconds':>9} {'µs/vehicle':>11}  outcome")
    vehicles_module.MAX_VEHICLES = max(sizes)
    for n in sizes:
        for name, graph in cases(n).items():
            s, outcome = timed(fleet_toml(n, graph))
            print(f"{name:<28} {n:>7} {s:>9.3f} {1e6 * s / n:>11.0f}  {outcome}", flush=True)
    vehicles_module.MAX_VEHICLES = limit
    n = max(sizes)
    s, outcome = timed(fleet_toml(n, cases(n)["ring"]))
    print(f"{'ring, limit ' + str(limit) + ' kept':<28} {n:>7} {s:>9.3f} {1e6 * s / n:>11.0f}  {outcome}")


if __name__ == "__main__":
    main()

"""Settle times of every shipped scenario over several seeds, beside the paper's.

    python bench/settle_table.py [--seeds 5]

Runs `cdus sim`'s in-process fleet for each configs/*.toml and seed 1..N and prints a
Markdown table (mean and range of the path and coordination settle times, and the
final errors). The README's table is this script's output.
"""

from __future__ import annotations

import argparse
import glob
import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # this checkout's packages, not an installed copy

from cdus.scenario.config import load_scenario  # noqa: E402
from cdus.sim.fleet import InProcessFleet  # noqa: E402

PAPER = {"lake_circle": ("87", "142"), "lissajous_5x5": ("30", "50")}


def fmt(values: list[float | None]) -> str:
    ok = [v for v in values if v is not None]
    if not ok:
        return "never"
    s = f"{statistics.mean(ok):.1f} ({min(ok):.1f}-{max(ok):.1f})"
    if len(ok) < len(values):
        s += f", {len(values) - len(ok)} never"
    return s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args()
    print("| scenario | path settle s, mean (range) | coordination settle s | paper (path / coord) "
          "| worst final \\|Φ\\| m | worst final edge error rad |")
    print("|---|---|---|---|---|---|")
    for path in sorted(glob.glob("configs/*.toml")):
        name = os.path.splitext(os.path.basename(path))[0]
        ps, cs, fp, fc = [], [], [], []
        for seed in range(1, args.seeds + 1):
            m = InProcessFleet(load_scenario(path, {"scenario.seed": seed})).run().metrics
            ps.append(m.path_settle_s)
            cs.append(m.coord_settle_s)
            fp.append(m.final_path_error_max)
            fc.append(m.final_coord_error_max)
        paper = " / ".join(PAPER[name]) + " s" if name in PAPER else "-"
        print(f"| {name} | {fmt(ps)} | {fmt(cs)} | {paper} | {max(fp):.3f} | {max(fc):.4f} |", flush=True)


if __name__ == "__main__":
    main()

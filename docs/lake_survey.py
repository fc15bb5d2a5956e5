"""Make docs/lake_survey.png: configs/lake_survey.toml run in process, seen from above.

    python docs/lake_survey.py                      # 240 simulated s -> docs/lake_survey.png
    python docs/lake_survey.py --out /tmp/survey.png --duration 60

Left: each boat's lane (the spline through its waypoints, dots) and the tracks of the boats
from their random starts, the drones' (15 m above, drawn in x, y) on top. Right: every
vehicle's path error |Φ| over time, with the settle times the metrics give. Matplotlib only
(no display needed); the PNG is written without a date, so the same run makes the same bytes.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cdus  # noqa: E402
from cdus.sim.polyline import path_polyline  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "lake_survey.png"))
    ap.add_argument("--duration", type=float, default=None, help="simulated s (default: the scenario's)")
    args = ap.parse_args()
    overrides = {} if args.duration is None else {"scenario.duration": args.duration}
    scenario = cdus.load(ROOT / "configs" / "lake_survey.toml", overrides)
    result = cdus.run(scenario)
    tr, m = result.trace, result.metrics
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 5.8), gridspec_kw={"width_ratios": [1.25, 1]})
    colours = {}
    for j, v in enumerate(scenario.vehicles):
        boat = v.kind == "usv"
        c = colours.setdefault(dict(v.path)["center"][0], f"C{len(colours)}")
        if boat:
            lane = path_polyline(v, scenario.duration)
            ax.plot(lane[:, 0], lane[:, 1], "-", color=c, lw=1, alpha=0.5)
            wp = np.array(dict(v.path)["waypoints"]) + np.array(dict(v.path)["center"])[:2]
            ax.plot(wp[:, 0], wp[:, 1], ".", color=c, ms=4)
        q = tr.q[:, j, :]
        ax.plot(q[:, 0], q[:, 1], "-" if boat else ":", color="k" if boat else c, lw=1.2 if boat else 1.6,
                label=f"{v.id} ({'boat' if boat else 'drone, 15 m'})")
        ax.plot(q[0, 0], q[0, 1], "o" if boat else "^", color=c, ms=6)
        ax2.semilogy(tr.t, np.maximum(tr.path_error[:, j], 1e-4), lw=1, label=v.id)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("lake_survey: 3 boats on spline lanes, a drone above each")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3)
    ax2.axhline(m.path_tol, color="grey", lw=0.8, ls="--")
    ax2.axvline(m.path_settle_s, color="grey", lw=0.8)
    ax2.set_xlabel("t (s)")
    ax2.set_ylabel("|Φ| (m)")
    ax2.set_title(f"path error: settles (< {m.path_tol:g} m) at {m.path_settle_s:.2f} s, "
                  f"formation at {m.coord_settle_s:.2f} s", fontsize=9)
    ax2.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100, metadata={"Software": None})
    print(f"{args.out}: path settle {m.path_settle_s:.2f} s, coordination settle {m.coord_settle_s:.2f} s")


if __name__ == "__main__":
    main()

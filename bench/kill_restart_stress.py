"""The kill/restart end-to-end scenario, many times in a row: does a run ever hang or fail?

Each run is tests/e2e/test_faults.py's kill-and-restart test: lake_circle in lockstep for
320 simulated s with usv2 killed at 150 s and restarted at 170 s. A run passes when the
launcher exits 0 within ``--timeout`` seconds, the metrics list the fault and usv2's
return, usv2's log says it rejoined at tick 8500 (t = 170 s at 50 Hz), and the fleet
re-converges (coordination settles after 170 s, final error < 0.05 rad). A run that
passes ``--timeout`` is a hang: its last log lines are printed and the fleet is killed.

    python bench/kill_restart_stress.py --runs 20

prints one line per run (status, wall seconds) and a summary (hangs, failures, wall
seconds min / median / max).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import uuid
from pathlib import Path

from _fleet import REPO, Launch, load_line

KILL_AT, RESTART_AT, DURATION = 150.0, 170.0, 320.0
EVENTS = f"""
[[event]]
at = {KILL_AT}
action = "kill"
vehicle = "usv2"

[[event]]
at = {RESTART_AT}
action = "restart"
vehicle = "usv2"
"""


def scenario(tmp: Path) -> Path:
    text = (REPO / "configs" / "lake_circle.toml").read_text()
    if "duration = 250.0" not in text:
        raise SystemExit("configs/lake_circle.toml no longer has 'duration = 250.0'; update this bench")
    cfg = tmp / "kill_restart.toml"
    cfg.write_text(text.replace("duration = 250.0", f"duration = {DURATION}") + EVENTS)
    return cfg


def check(run: Path) -> str | None:
    """None if the run did what the e2e test asks, else what was wrong."""
    try:
        m = json.loads((run / "metrics.json").read_text())
    except (OSError, ValueError) as e:
        return f"no metrics: {e}"
    seen = {(e["kind"], e.get("vehicle")) for e in m["events"]}
    if ("fault", "usv2") not in seen or ("vehicle_back", "usv2") not in seen:
        return f"events lack the fault or usv2's return: {sorted(seen)}"
    log = (run / "logs" / "usv2.log").read_text(errors="replace")
    if "rejoining at tick 8500" not in log:
        return "usv2 did not rejoin at tick 8500"
    if m["coord_settle_s"] is None or m["coord_settle_s"] <= RESTART_AT or m["final_coord_error_max"] >= 0.05:
        return f"did not re-converge: coord_settle_s {m['coord_settle_s']}, final {m['final_coord_error_max']}"
    return None


def one(cfg: Path, run: Path, timeout: float) -> tuple[str, float, str]:
    """(ok | fail | hang, wall seconds, detail)."""
    fleet = "stress" + uuid.uuid4().hex[:8]
    args = ["launch", str(cfg), "--clock", "lockstep", "--logs", str(run), "-q", "--rerun", "off", "--fleet", fleet]
    with Launch(args, fleet=fleet) as la:
        try:
            rc = la.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            tail = "\n".join("    | " + ln for ln in la.lines[-8:])
            worlds = (run / "logs" / "world.log")
            wtail = worlds.read_text(errors="replace").splitlines()[-8:] if worlds.exists() else []
            return "hang", la.wall, tail + "\n    world.log:\n" + "\n".join("    | " + ln for ln in wtail)
    if rc != 0:
        return "fail", la.wall, f"launcher exit status {rc}:\n" + "\n".join("    | " + ln for ln in la.lines[-8:])
    why = check(run)
    return ("fail", la.wall, why) if why else ("ok", la.wall, "")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--timeout", type=float, default=300.0, help="wall seconds after which a run is a hang")
    args = ap.parse_args()
    print(load_line(), flush=True)
    results = []
    with tempfile.TemporaryDirectory(prefix="cdus-stress-") as d:
        tmp = Path(d)
        cfg = scenario(tmp)
        for i in range(args.runs):
            status, wall, detail = one(cfg, tmp / f"run{i}", args.timeout)
            results.append((status, wall))
            print(f"run {i + 1:2d}/{args.runs}: {status:4s} {wall:6.1f} s" + (f"\n{detail}" if detail else ""),
                  flush=True)
    walls = [w for _, w in results]
    hangs = sum(s == "hang" for s, _ in results)
    fails = sum(s == "fail" for s, _ in results)
    print(f"\n{args.runs} runs: {args.runs - hangs - fails} ok, {fails} failed, {hangs} hung "
          f"(timeout {args.timeout:g} s); wall s min {min(walls):.1f} median {statistics.median(walls):.1f} "
          f"max {max(walls):.1f}; {DURATION:g} simulated s each")
    print(load_line())
    return 0 if hangs == fails == 0 else 1


if __name__ == "__main__":
    sys.exit(main())

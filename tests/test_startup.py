"""What does each process import at start-up? Only what its job uses: the world without a
recording loads no Rerun or pandas (~0.8 s of CPU in each of the ~70 world launches of
tests/e2e), `cdus gs` and `cdus launch` load no sweep, plotting or in-process API."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
HEAVY = {"rerun", "pandas", "pyarrow", "matplotlib"}


def modules_after(code: str) -> set[str]:
    """The modules a fresh interpreter holds after running ``code`` (in the repository)."""
    probe = textwrap.dedent(code) + "\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))\n"
    out = subprocess.run([sys.executable, "-c", probe], cwd=REPO, capture_output=True, text=True, timeout=120,
                         check=True, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    return set(json.loads(out.stdout.strip().splitlines()[-1]))


def test_a_world_without_a_recording_imports_no_rerun():
    mods = modules_after("""
        from cdus.scenario.config import load_scenario
        from cdus.wire.transport import Transport
        from world_sim.__main__ import build_parser
        from world_sim.sinks import make_sink
        from world_sim.world import World
        args = build_parser().parse_args(["--config", "configs/lake_circle.toml", "--rerun", "off"])
        World(load_scenario(args.config), "t", Transport(), sink=make_sink(args.rerun))
    """)
    assert "world_sim.world" in mods and "zenoh" in mods  # the probe did build a world
    assert not HEAVY & mods, sorted(HEAVY & mods)


def test_a_world_with_a_recording_imports_rerun_where_it_makes_the_sink(tmp_path):
    mods = modules_after(f"""
        from world_sim.sinks import make_sink
        make_sink("save:{tmp_path / 'r.rrd'}").close()
    """)
    assert "rerun" in mods and "world_sim.rerun_sink" in mods


def test_cdus_gs_and_cdus_launch_start_without_the_sweep_the_api_or_the_export():
    mods = modules_after("""
        from cdus.app.cli import build_parser, main
        build_parser().parse_args(["launch", "configs/lake_circle.toml", "--rerun", "off"])
    """)
    assert "ground_station.__main__" in mods  # the probe did load the command: `cdus gs` goes through it
    assert not {"cdus.api", "cdus.app.sweep", "cdus.app.launcher", "cdus.ros2.export", "tqdm"} & mods
    assert not HEAVY & mods, sorted(HEAVY & mods)

"""The API's lockstep runs: a fleet of processes (`cdus launch --clock lockstep`) that gives
the in-process numbers to the bit, secured by default, and leaves no process behind, also
when its caller is interrupted."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import cdus
from tests.e2e.conftest import fleet_processes, kill_group, unique_fleet

ROOT = Path(__file__).resolve().parents[2]
LAKE = str(ROOT / "configs/lake_circle.toml")


@pytest.fixture
def fleets():
    """Unique fleet names; any process left under one is killed (and fails the test)."""
    names: list[str] = []

    def new() -> str:
        names.append(unique_fleet())
        return names[-1]

    yield new
    left = [line for name in names for line in fleet_processes(name)]
    for line in left:
        try:
            os.killpg(int(line.split()[0]), signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert not left, left


def test_a_lockstep_run_through_the_api_equals_the_in_process_one_to_the_bit(tmp_path, fleets):
    sc = cdus.load(LAKE, {"scenario.duration": 6, "scenario.seed": 3, "link.loss": 0.1})
    fleet = fleets()
    res = cdus.run(sc, clock="lockstep", fleet=fleet, run_dir=tmp_path / "run")
    ref = cdus.run(sc)
    for name in ("t", "q", "heading", "omega", "omega_rate", "path_error", "edge_error", "live"):
        assert np.array_equal(getattr(res.trace, name), getattr(ref.trace, name)), name
    a, b = res.metrics, ref.metrics
    assert (a.mode, b.mode) == ("lockstep", "inproc") and a.completed is True
    for field in ("duration_s", "path_settle_s", "coord_settle_s", "final_path_error_max", "final_coord_error_max",
                  "omega_rate_final", "final_path_error", "live_final", "min_separation_m", "interventions"):
        assert getattr(a, field) == getattr(b, field), field
    assert (a.link.sent, a.link.delivered, a.link.dropped) == (b.link.sent, b.link.delivered, b.link.dropped)
    assert a.link.faults.total == b.link.faults.total and a.link.dropped > 0
    assert a.rejected_by_reason is not None and a.link.missed_deadlines == 0
    run = tmp_path / "run"
    written = json.loads((run / "metrics.json").read_text())  # the world's own file
    assert json.dumps(a.to_dict()) == json.dumps(written)
    assert any((run / "secure").glob("*.json5"))  # secured by default: a credentials file per process
    assert (run / "metrics.json").exists() and (run / "logs/world.log").exists() and res.run_dir == run
    assert any(f"fleet '{fleet}' up" in line for line in res.log)
    assert not fleet_processes(fleet)


def test_an_interrupted_caller_stops_every_process_and_gets_what_ran(tmp_path, fleets):
    fleet = fleets()
    script = textwrap.dedent(f"""
        import cdus
        sc = cdus.load({LAKE!r}, {{"scenario.duration": 3000}})
        try:
            cdus.run(sc, clock="lockstep", fleet={fleet!r}, progress=True)
        except cdus.RunInterrupted as e:
            m, tr = e.result.metrics, e.result.trace  # no trace if stopped before the first tick
            print("RESULT", m.completed, m.completion, m.duration_s == (0 if tr is None else tr.t[-1] - tr.t[0]),
                  flush=True)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], cwd=tmp_path, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, start_new_session=True,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    lines: list[str] = []
    up = threading.Event()

    def read() -> None:
        for line in proc.stdout:
            lines.append(line.rstrip("\n"))
            if f"fleet '{fleet}' up" in line:
                up.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert up.wait(60), "\n".join(lines)
        time.sleep(1.0)  # not a readiness wait: lets the run advance a little, so there is a trace
        proc.send_signal(signal.SIGINT)  # Ctrl-C to the caller (a script, a notebook kernel)
        assert proc.wait(timeout=60) == 0, "\n".join(lines)
    finally:
        kill_group(proc)
    reader.join(timeout=5)
    assert "RESULT False interrupted True" in lines, "\n".join(lines)
    assert not fleet_processes(fleet)


def test_an_insecure_lockstep_run_writes_no_credentials(tmp_path, fleets):
    sc = cdus.load(LAKE, {"scenario.duration": 1})
    res = cdus.run(sc, clock="lockstep", fleet=fleets(), run_dir=tmp_path / "run", secure=False)
    assert res.metrics.completed is True and not (tmp_path / "run/secure").exists()

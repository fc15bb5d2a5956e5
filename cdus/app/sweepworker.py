"""What does a worker do with one run of a sweep? It runs the resolved scenario (`cdus sim`'s
in-process fleet, or a launched lockstep fleet) and returns its row: the status, the reason of
a failure, the metrics flattened. It never raises.
"""

from __future__ import annotations

import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
import traceback
import uuid
from dataclasses import fields
from pathlib import Path

from cdus.app.sweepstore import FIELDS
from cdus.files import write_json
from cdus.scenario.config import ConfigError
from cdus.scenario.model import Scenario
from cdus.scenario.plugins import load_named
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics


#: the row's columns that are the metrics' own fields (the others are derived below)
_METRIC_COLUMNS = tuple(k for k in FIELDS if k in {f.name for f in fields(Metrics)})


def _flatten(metrics: Metrics) -> dict:
    """The row's metric columns from the typed record (checked once where it was read)."""
    rates = [v for v in metrics.omega_rate_final.values() if v is not None]
    row = {k: getattr(metrics, k) for k in _METRIC_COLUMNS}
    row["omega_rate_mean"] = statistics.mean(rates) if rates else None
    row["omega_rate_final"] = json.dumps(metrics.omega_rate_final)
    row["live_final"] = " ".join(metrics.live_final)
    for k in ("sent", "delivered", "dropped", "rejected", "latency_ms_p50", "latency_ms_p99"):
        row[f"link_{k}"] = None if metrics.link is None else getattr(metrics.link, k)
    return row


def run_task(scenario: Scenario, clock: str) -> dict:
    """One run of a resolved scenario (what a worker executes); never raises: a failure
    comes back as status "failed" with its reason."""
    try:
        if clock == "inproc":
            load_named(scenario.raw, str(scenario.source))  # a fresh worker knows no plug-in yet
            metrics = InProcessFleet(scenario, clock=time.perf_counter).run().metrics
        else:
            metrics = _run_lockstep(scenario)
        status, reason = "ok", ""
        if metrics.final_path_error_max is None or not math.isfinite(metrics.final_path_error_max):
            status, reason = "failed", "the fleet diverged (non-finite path error)"
        return {"status": status, "reason": reason, **_flatten(metrics)}
    except ConfigError as e:
        return {"status": "failed", "reason": f"config: {e}".replace("\n", "; ")}
    except Exception as e:  # a crash in one cell must not end the sweep
        return {"status": "failed", "reason": traceback.format_exception_only(type(e), e)[-1].strip()}


def _run_lockstep(scenario: Scenario) -> Metrics:
    """A `cdus launch --clock lockstep` fleet of the resolved scenario (its data as JSON); its
    metrics file read once into the typed record (ValueError naming the file and the field)."""
    with tempfile.TemporaryDirectory(prefix="cdus-sweep-") as tmp:
        config = Path(tmp) / "scenario.json"
        write_json(config, scenario.raw, allow_inf=True)
        logs = Path(tmp) / "run"
        args = [sys.executable, "-m", "cdus.app.cli", "launch", str(config), "--clock", "lockstep", "-q",
                "--rerun", "off", "--fleet", "sweep" + uuid.uuid4().hex[:8], "--logs", str(logs)]
        with subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              start_new_session=True) as proc:
            try:
                out, err = proc.communicate()
            except BaseException:  # Ctrl-C (or SIGTERM) of the sweep: the fleet stops before its directory goes
                _stop_launcher(proc)
                raise
        path = logs / "metrics.json"
        if proc.returncode != 0 or not path.exists():
            tail = (err or out).strip().splitlines()[-3:]
            raise RuntimeError(f"launch exited with {proc.returncode}: {' / '.join(tail)}")
        return Metrics.read(path)


LAUNCHER_STOP_S = 20.0  # how long a stopping launcher may take to stop its fleet before it is killed


def _stop_launcher(proc: subprocess.Popen) -> None:
    """Stop a launched fleet as Ctrl-C would (SIGINT to the launcher's session: it stops the
    world and the vehicles and waits for them), then kill what is left of the session."""
    import signal

    for sig, wait in ((signal.SIGINT, LAUNCHER_STOP_S), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            proc.communicate(timeout=wait)
            break
        except subprocess.TimeoutExpired:
            continue

"""One run of a sweep on a worker (cdus/app/sweepworker.py): its row, the metrics flattened,
and a failure as a row with its reason, never an exception."""

import json
from dataclasses import fields

import pytest

import cdus.app.sweepworker as worker
from cdus.app.sweepstore import FIELDS
from cdus.scenario.config import ConfigError, load_scenario
from cdus.sim.fleet import InProcessFleet

CONFIG = "configs/concentric_circles.toml"


def test_a_run_comes_back_as_its_row_of_flattened_metrics():
    s = load_scenario(CONFIG, {"scenario.duration": 2.0, "link.loss": 0.2})
    metrics = InProcessFleet(s).run().metrics
    row = worker.run_task(s, "inproc")
    assert (row["status"], row["reason"]) == ("ok", "")
    assert set(row) - {"status", "reason"} <= set(FIELDS)
    same = [k for k in FIELDS if k in {f.name for f in fields(metrics)}
            and k not in ("wall_s", "realtime_factor", "omega_rate_final", "live_final")]
    assert same and {k: row[k] for k in same} == {k: getattr(metrics, k) for k in same}
    assert json.loads(row["omega_rate_final"]) == metrics.omega_rate_final
    assert row["live_final"] == " ".join(metrics.live_final)
    assert row["link_dropped"] == metrics.link.dropped > 0


@pytest.mark.parametrize("error, reason", [
    (RuntimeError("boom"), "RuntimeError: boom"),
    (ConfigError("scenario.toml", [("link.loss", "must be in [0, 1]"), ("gains.k", "must be > 0")]),
     "config: scenario.toml: link.loss: must be in [0, 1]; scenario.toml: gains.k: must be > 0"),
])
def test_a_failed_run_is_a_row_with_its_reason_never_an_exception(monkeypatch, error, reason):
    class Failing(InProcessFleet):
        def run(self, *a, **k):
            raise error

    monkeypatch.setattr(worker, "InProcessFleet", Failing)
    s = load_scenario(CONFIG, {"scenario.duration": 1.0})
    assert worker.run_task(s, "inproc") == {"status": "failed", "reason": reason}


def test_a_lockstep_runs_metrics_file_is_read_once_and_a_bad_one_is_a_failed_row_naming_the_field(monkeypatch):
    """The worker reads the launched fleet's metrics.json into Metrics once (cdus.sim.runmetrics):
    a valid one is its row; one with a bad field (a corrupt file, another version's) is a
    failed row whose reason names the field, never an exception."""
    s = load_scenario(CONFIG, {"scenario.duration": 1.0})
    good = InProcessFleet(s).run().metrics.to_dict()  # the file a launched fleet writes
    written = {}

    class Launched:  # `cdus launch` as a process: writes the metrics file it was given, exits 0
        returncode = 0

        def __init__(self, args, **kw):
            self.logs = args[args.index("--logs") + 1]

        def __enter__(self):
            import os
            os.makedirs(self.logs, exist_ok=True)
            with open(f"{self.logs}/metrics.json", "w") as fh:
                fh.write(written["text"])
            return self

        def __exit__(self, *exc):
            return False

        def communicate(self):
            return "", ""

    monkeypatch.setattr(worker.subprocess, "Popen", Launched)
    written["text"] = json.dumps(good)
    row = worker.run_task(s, "lockstep")
    assert (row["status"], row["reason"], row["link_sent"]) == ("ok", "", good["link"]["sent"])
    written["text"] = json.dumps({**good, "link": {**good["link"], "sent": "many"}})
    row = worker.run_task(s, "lockstep")
    assert row["status"] == "failed" and "metrics: link.sent: expected an integer, got 'many'" in row["reason"]

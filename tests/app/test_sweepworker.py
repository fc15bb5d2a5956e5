"""One run of a sweep on a worker (cdus/app/sweepworker.py): its row, the metrics flattened,
and a failure as a row with its reason, never an exception."""

import json

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
    same = [k for k in FIELDS if k in metrics and k not in ("wall_s", "realtime_factor", "omega_rate_final",
                                                                "live_final")]
    assert same and {k: row[k] for k in same} == {k: metrics[k] for k in same}
    assert json.loads(row["omega_rate_final"]) == metrics["omega_rate_final"]
    assert row["live_final"] == " ".join(metrics["live_final"])
    assert row["link_dropped"] == metrics["link"]["dropped"] > 0


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

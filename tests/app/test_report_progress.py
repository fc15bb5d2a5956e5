"""The progress line's rate is measured from its first report, not from before the run began."""

from __future__ import annotations

import io

from cdus.app import report


def test_the_rate_is_measured_from_the_first_report_not_the_start_up(monkeypatch):
    clock = iter([110.0, 111.0, 113.0])  # the first report 10 s after the launcher began (start-up), then 50 s in 1 s, 50 in 2 s
    monkeypatch.setattr(report.time, "perf_counter", lambda: next(clock))
    out = io.StringIO()
    p = report.Progress("lake", stream=out)
    p(0.02, 100.0)  # the first tick's status, 10 s after the launcher began: no rate yet
    p(50.02, 100.0)
    p(100.0, 100.0)
    lines = out.getvalue().splitlines()
    assert lines[0] == "lake: t =     0.0 / 100.0 s (  0%)"
    assert lines[1] == "lake: t =    50.0 / 100.0 s ( 50%),   50.0x real time"
    assert lines[2] == "lake: t =   100.0 / 100.0 s (100%),   33.3x real time"


def test_nothing_is_said_when_quiet_or_without_a_duration():
    out = io.StringIO()
    report.Progress("lake", stream=out, quiet=True)(1.0, 10.0)
    report.Progress("lake", stream=out)(1.0, 0.0)
    assert out.getvalue() == ""

"""The suite's two phases (tests/conftest.py, tests/run.py): a test that starts a fleet process
or opens Zenoh is refused in the shared (parallel) phase unless it is ``procs``, so the parallel
phase stays free of fleets whose timing the other worker's load would change; any other process
is fine there."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import PROCS, is_procs

pytest_plugins = ["pytester"]
HERE = Path(__file__).resolve().parent
BODY = """
import subprocess, sys, pytest, zenoh
from cdus.wire.transport import Transport, zenoh_config
{mark}
def test_starts_a_fleet():
    subprocess.run([sys.executable, "-c", "pass", "-m", "cdus.app.cli", "launch"])

{mark}
def test_opens_zenoh():
    zenoh.open(zenoh_config(Transport(mode="peer"))).close()  # no endpoint, no scouting: on its own

def test_starts_another_process():
    subprocess.run(["true"], check=True)
"""


@pytest.mark.parametrize("mark, outcome", [("", {"failed": 2, "passed": 1}), ("@pytest.mark.procs", {"passed": 3})])
def test_the_shared_phase_refuses_a_process_unless_the_test_is_procs(pytester, monkeypatch, mark, outcome):
    pytester.makeconftest((HERE / "conftest.py").read_text())
    pytester.makepyfile(test_x=BODY.format(mark=mark))
    monkeypatch.setenv("CDUS_SUITE_PHASE", "shared")
    result = pytester.runpytest_inprocess("-p", "no:cacheprovider")
    result.assert_outcomes(**outcome)
    if not mark:
        out = result.stdout.str()
        assert "starts a fleet process" in out and "opens a Zenoh session" in out


def test_outside_the_shared_phase_nothing_is_refused(pytester, monkeypatch):
    pytester.makeconftest((HERE / "conftest.py").read_text())
    pytester.makepyfile(test_x=BODY.format(mark=""))
    monkeypatch.setenv("CDUS_SUITE_PHASE", "procs")
    pytester.runpytest_inprocess("-p", "no:cacheprovider").assert_outcomes(passed=3)


def test_procs_names_real_files_and_folders():
    for p in PROCS:
        assert (HERE / p).exists(), f"tests/conftest.py PROCS names {p}, which is not under tests/"
    assert is_procs("e2e/test_faults.py") and is_procs("app/test_cli.py")
    assert not is_procs("core/test_safety.py") and not is_procs("app/test_cli.pyc")

"""Which tests need the machine to themselves, and which can share it?

The suite runs in two phases (``python3 tests/run.py``, the README's test command):

1. the **shared** phase: every test that starts no fleet and opens no Zenoh session (the math,
   the codecs, the scenario checks, the rooms fed through their doors, the in-process sweeps and
   notebooks), on pytest-xdist workers, one per core;
2. the **procs** phase: the tests marked ``procs`` (below), one at a time, with the machine to
   themselves, because what they test is timing: liveliness leases, realtime ticks, readiness,
   a fleet's processes killed and restarted.

A test is ``procs`` when its file is under one of :data:`PROCS` or it carries
``@pytest.mark.procs``. In the shared phase a test that is not ``procs`` and still opens a Zenoh
session or starts one of cdus's fleet processes (:data:`FLEET_WORDS` in its command line) fails at
once, naming the mark it needs (:func:`_shared_guard`), so a new fleet test cannot slip into the
parallel phase and make it flaky. Other processes (a sweep's pool, a notebook's kernel, ``cdus sim``)
are fine there: they keep no time.
"""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent

#: the files and folders (relative to tests/) whose tests start processes or open Zenoh sessions
PROCS = (
    "e2e/", "ros2/test_access.py", "ros2/test_launch.py", "ros2/test_robot.py", "ros2/test_robot_fleet.py",
    "test_suite_phases.py", "test_startup.py",
    "api/test_lockstep.py",
    "app/test_cli.py", "app/test_launcher_runtime.py", "app/test_listen.py", "app/test_sweep_inf.py",
    "plugins/test_example_e2e.py",
    "app/test_sweep_resume.py", "app/test_command_acl.py", "app/test_credentials.py",
    "ground_station/test_console.py",
    "vehicle_agent/test_footprint.py",
    "wire/test_router_qos.py",
    "world_sim/test_recording.py",
)

#: words in a command line that make it one of cdus's fleet processes, or a command that starts them
#: (a sweep of lockstep fleets), or Zenoh's router
FLEET_WORDS = ("launch", "world_sim", "vehicle_agent", "cdus.ros2", "zenohd", "gs", "lockstep", "realtime")

#: set by tests/run.py for the shared phase
PHASE_ENV = "CDUS_SUITE_PHASE"


def is_procs(relpath: str) -> bool:
    """Whether a test file (its path relative to tests/, with "/") is in the procs phase."""
    return any(relpath == p or (p.endswith("/") and relpath.startswith(p)) for p in PROCS)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line("markers", "procs: starts processes or opens Zenoh sessions: runs alone, after "
                                       "the shared phase (tests/conftest.py, tests/run.py)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        try:
            rel = Path(str(item.fspath)).resolve().relative_to(HERE).as_posix()
        except ValueError:
            continue
        if is_procs(rel):
            item.add_marker(pytest.mark.procs)


def _refusal(what: str, nodeid: str) -> RuntimeError:
    return RuntimeError(f"{nodeid} {what} in the suite's shared (parallel) phase: add its file to PROCS "
                        "in tests/conftest.py or mark it @pytest.mark.procs, so it runs alone")


def is_fleet_command(args) -> bool:
    """Whether a Popen's ``args`` start one of cdus's fleet processes (a word of :data:`FLEET_WORDS`)."""
    words = [args] if isinstance(args, (str, bytes, os.PathLike)) else list(args)
    text = " ".join(os.fsdecode(w) if isinstance(w, (bytes, os.PathLike)) else str(w) for w in words)
    tokens = set(re.split(r"[\s/.]+", text))
    return any(w in tokens for w in FLEET_WORDS)


@pytest.fixture(autouse=True)
def _shared_guard(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch):
    """In the shared phase, a test not marked ``procs`` may not start a fleet process or open Zenoh."""
    if os.environ.get(PHASE_ENV) != "shared" or request.node.get_closest_marker("procs") is not None:
        yield
        return
    nodeid = request.node.nodeid
    popen_init = subprocess.Popen.__init__

    def guarded_init(self, args, *rest, **kwargs):
        if is_fleet_command(args):
            raise _refusal(f"starts a fleet process ({args!r})", nodeid)
        popen_init(self, args, *rest, **kwargs)

    def no_zenoh(*args, **kwargs):
        raise _refusal("opens a Zenoh session", nodeid)

    monkeypatch.setattr(subprocess.Popen, "__init__", guarded_init)
    try:
        import zenoh
    except ImportError:  # pragma: no cover (a dependency)
        pass
    else:
        monkeypatch.setattr(zenoh, "open", no_zenoh)
    yield

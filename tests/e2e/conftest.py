"""Helpers for end-to-end tests that start real processes.

Every process is started in its own session (process group); teardown kills the groups,
so no test leaves a process behind. Readiness comes from the processes' own messages
(the launcher's "up" line), never from sleeps. Fleet names are unique per test.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Callable, Sequence

import pytest
import zenoh

from cdus.wire import keys
from cdus.wire.schemas import decode_status
from cdus.wire.rejected import Rejected

ROOT = Path(__file__).resolve().parents[2]


def unique_fleet() -> str:
    return "t" + uuid.uuid4().hex[:10]


def fleet_processes(fleet: str) -> list[str]:
    out = subprocess.run(["pgrep", "-af", "--", f"--fleet {fleet}"], capture_output=True, text=True).stdout
    return [ln for ln in out.splitlines() if "pgrep" not in ln]


def kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL a process started with its own session group, and everything in that group."""
    if proc.poll() is None:
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()


class Launch:
    """`cdus launch ...` in the background, its stdout collected line by line."""

    def __init__(self, args: list[str], prefix: Sequence[str] = ()):
        """``prefix``: what to run it under, e.g. ``ip netns exec NS``."""
        self.proc = subprocess.Popen([*prefix, sys.executable, "-m", "cdus.app.cli", "launch", *args], cwd=ROOT,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
        self.lines: list[str] = []
        self.cond = threading.Condition()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            with self.cond:
                self.lines.append(line.rstrip("\n"))
                self.cond.notify_all()
        with self.cond:
            self.cond.notify_all()

    def wait_for(self, text: str | Callable[[str], bool], timeout: float = 60.0) -> str:
        """The first line containing ``text`` (or for which ``text(line)`` holds)."""
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                for ln in self.lines:
                    if (text(ln) if callable(text) else text in ln):
                        return ln
                if self.proc.poll() is not None and not self.reader.is_alive():
                    raise AssertionError(f"launcher exited before {text!r}:\n" + "\n".join(self.lines))
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"no {text!r} within {timeout} s:\n" + "\n".join(self.lines))
                self.cond.wait(timeout=min(left, 0.5))

    def wait(self, timeout: float = 120.0) -> int:
        code = self.proc.wait(timeout=timeout)
        self.reader.join(timeout=5)
        return code

    def output(self) -> str:
        with self.cond:
            return "\n".join(self.lines)

    def kill(self) -> None:
        kill_group(self.proc)


@pytest.fixture
def launches():
    started: list[tuple[Launch, str]] = []

    def start(args: list[str], fleet: str, prefix: Sequence[str] = ()) -> Launch:
        la = Launch([*args, "--fleet", fleet], prefix)
        started.append((la, fleet))
        return la

    yield start
    for la, fleet in started:
        la.kill()
        # the launcher's children live in their own groups: make sure none survived
        for line in fleet_processes(fleet):
            pid = int(line.split()[0])
            try:
                os.killpg(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


def run_cli(args: list[str], timeout: float = 300.0) -> subprocess.CompletedProcess:
    """`cdus ...` to completion in its own process group (killed on timeout)."""
    proc = subprocess.Popen([sys.executable, "-m", "cdus.app.cli", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        raise AssertionError(f"cdus {' '.join(args)} timed out:\n{out}\n{err}")
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


class WorldTime:
    """The world's simulated time, from its status messages (one that does not decode is skipped)."""

    def __init__(self, session: zenoh.Session, fleet: str):
        self.cond = threading.Condition()
        self.t = -1.0
        self.sub = session.declare_subscriber(keys.world_status(fleet), self._on)

    def _on(self, sample) -> None:
        st = decode_status(sample.payload.to_bytes())
        if not isinstance(st, Rejected):
            with self.cond:
                self.t = st.t
                self.cond.notify_all()

    def wait_past(self, t: float, timeout: float = 60.0) -> float:
        deadline = time.monotonic() + timeout
        with self.cond:
            while self.t <= t:
                assert time.monotonic() < deadline, f"the world's time stayed at {self.t}, not past {t}"
                self.cond.wait(timeout=0.2)
            return self.t


TRACE_FIELDS = ("q", "omega", "omega_rate", "path_error", "heading")


def assert_same_trace(trace_file: Path, ref) -> None:
    """A process fleet's trace (``--trace-out``) equals the in-process run ``ref`` (a RunResult)
    to the bit, field by field: the claim "lockstep == cdus sim"."""
    import numpy as np

    trace = np.load(trace_file)
    for name in TRACE_FIELDS:
        got, want = trace[name], ref.recorder.view(name)
        same = got.shape == want.shape and np.array_equal(got, want, equal_nan=True)
        assert same, (name, got.shape, want.shape, None if got.shape != want.shape else np.nanmax(np.abs(got - want)))

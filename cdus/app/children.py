"""How does the launcher start, signal and read one child process, so that none outlives it?

A :class:`Child` is one process the launcher started (the world, an agent, the ROS 2 bridge):
its own session and process group (signalled whole), its log file, its restarts. Every child is
started with ``PR_SET_PDEATHSIG`` (Linux, :func:`die_with_parent`): the moment the launcher dies
the kernel sends it its ``death_signal``.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

LOG_TAIL = 15  # lines of a child's log shown when it fails


# Children die with the launcher: prctl(PR_SET_PDEATHSIG, SIGTERM) in the child between fork
# and exec. The kernel sends the signal when the *thread* that forked the child exits, so
# children are only ever started from the launcher's main thread (start, supervise, stop).
PR_SET_PDEATHSIG = 1
_LIBC = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True) if sys.platform == "linux" else None
_PRCTL = _LIBC.prctl if _LIBC is not None else None  # looked up now: the child only calls it


def die_with_parent(parent_pid: int, sig: int = signal.SIGTERM) -> Callable[[], None] | None:
    """A ``preexec_fn`` asking the kernel for ``sig`` when the parent dies (Linux), and exiting
    at once if the parent is already gone (it died between fork and prctl). None elsewhere."""
    if _PRCTL is None:
        return None
    signum = int(sig)

    def preexec() -> None:  # runs in the forked child: no imports, no allocations of note
        _PRCTL(PR_SET_PDEATHSIG, signum, 0, 0, 0)
        if os.getppid() != parent_pid:
            os._exit(1)
    return preexec


@dataclass
class Child:
    name: str
    argv: list[str]
    log_path: Path
    proc: subprocess.Popen | None = None
    restarts: int = 0  # every restart: scheduled faults and supervision
    supervised_restarts: int = 0  # restarts by the restart policy (bounded by max_restarts)
    restart_at: float | None = None  # when the policy restarts it (the launcher's clock), None: not due
    given_up: bool = False  # the policy's restarts are used up: it stays down
    exit_code: int | None = None
    log_file: Any = None
    intended_exit: bool = False  # killed on purpose (a scheduled fault): not a failure to restart
    restart_args: tuple[str, ...] = ()  # added when it is started again (an agent rejoins)
    # what the kernel sends it when the launcher dies: the world SIGTERM (it writes its metrics);
    # an agent SIGKILL (it has nothing to save, and one paused by a fault, SIGSTOPped, would
    # hold a SIGTERM pending for ever)
    death_signal: int = signal.SIGKILL

    def start(self, env: dict[str, str]) -> None:
        self.log_file = open(self.log_path, "ab")
        argv = self.argv + list(self.restart_args if self.restarts else ())
        self.proc = subprocess.Popen(argv, stdout=self.log_file, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, start_new_session=True, env=env,
                                     preexec_fn=die_with_parent(os.getpid(), self.death_signal))
        self.exit_code = None
        self.intended_exit = False

    def poll(self) -> int | None:
        if self.proc is None:
            return None
        code = self.proc.poll()
        if code is not None and self.exit_code is None:
            self.exit_code = code
            self.log_file.close()
        return code

    def running(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def signal_group(self, sig: int) -> None:
        if self.proc is None:
            return
        try:
            os.killpg(self.proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def tail(self, n: int = LOG_TAIL) -> str:
        try:
            lines = self.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return "(no log)"
        return "\n".join("    | " + ln for ln in lines[-n:]) or "    | (empty log)"

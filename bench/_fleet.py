"""Shared by the multi-process benches: run `cdus launch` as a child and look at its processes.

`Launch` starts the launcher in its own session, remembers every process it starts (the
world and the agents, each in a session of its own), and on leaving the ``with`` block,
also on an exception, walks the same ladder as the launcher: SIGTERM the launcher (it
stops its fleet), wait, then SIGKILL whatever of ours is left, by pid. Nothing outlives it.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import psutil

BENCH = Path(__file__).resolve().parent
REPO = BENCH.parent
sys.path.insert(0, str(REPO))  # the benches import this checkout's packages, not an installed copy


def cdus_argv() -> list[str]:
    """The `cdus` command of this checkout (``python -m cdus``; no shell shim to time)."""
    return [sys.executable, "-m", "cdus"]


def write_json(path: Path, data: dict) -> Path:
    path.write_text(json.dumps(data, indent=1))
    return path


def role(p: psutil.Process) -> str:
    """world, agent:<id> or launcher (the router lives in the launcher)."""
    try:
        cmd = p.cmdline()
    except psutil.Error:
        return "?"
    if "world_sim" in cmd:
        return "world"
    if "vehicle_agent" in cmd:
        return "agent:" + cmd[cmd.index("--id") + 1] if "--id" in cmd else "agent"
    return "launcher"


class Launch:
    """``with Launch(args) as la:`` runs ``cdus <args>`` and cleans up after it."""

    def __init__(self, args: list[str], fleet: str | None = None, cwd: Path = REPO, track_cpu: bool = False,
                 env: dict[str, str] | None = None):
        self.argv = cdus_argv() + args
        self.env = env  # the launcher's environment (None: this process's)
        self.fleet = fleet
        self.cwd = cwd
        self.proc: subprocess.Popen | None = None
        self.lines: list[str] = []
        self.up = threading.Event()  # the launcher printed "fleet ... up"
        self.seen: dict[int, psutil.Process] = {}
        self.t_start = self.t_end = 0.0
        self.track_cpu = track_cpu
        self.cpu: dict[int, tuple[str, float]] = {}  # pid -> (role, newest CPU seconds seen)

    def __enter__(self) -> "Launch":
        self.t_start = time.perf_counter()
        self.proc = subprocess.Popen(self.argv, cwd=self.cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, start_new_session=True, text=True, env=self.env)
        threading.Thread(target=self._read, daemon=True).start()
        if self.track_cpu:
            threading.Thread(target=self._sample_cpu, daemon=True).start()
        return self

    def _sample_cpu(self, period: float = 0.25) -> None:
        launcher = psutil.Process(self.proc.pid)
        while self.proc.poll() is None:
            for p in [launcher] + self.processes():
                try:
                    t = p.cpu_times()
                except psutil.Error:
                    continue
                r = role(p)
                if p.pid != launcher.pid and r in ("?", "launcher"):
                    # a child shows the launcher's command line until its exec, and none as it exits
                    r = self.cpu.get(p.pid, (r, 0.0))[0]
                self.cpu[p.pid] = (r, t.user + t.system)
            time.sleep(period)

    def cpu_by_role(self) -> dict[str, float]:
        """CPU seconds of the launcher (router), the world and the agents (summed), as last sampled."""
        out = {"launcher": 0.0, "world": 0.0, "agents": 0.0}
        for r, s in self.cpu.values():
            out["agents" if r.startswith("agent") else r if r in out else "launcher"] += s
        return out

    def _read(self) -> None:
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))
            if " up: world + " in line:
                self.up.set()
        self.up.set()  # the launcher ended: stop waiting for it

    def processes(self) -> list[psutil.Process]:
        """The launcher's live descendants (world, agents), remembered for the clean-up."""
        try:
            kids = psutil.Process(self.proc.pid).children(recursive=True)
        except psutil.Error:
            return []
        for k in kids:
            self.seen.setdefault(k.pid, k)
        return kids

    def wait(self, timeout: float) -> int:
        rc = self.proc.wait(timeout=timeout)
        self.t_end = time.perf_counter()
        return rc

    @property
    def wall(self) -> float:
        return (self.t_end or time.perf_counter()) - self.t_start

    def __exit__(self, *exc) -> None:
        self.processes()
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGTERM)  # the launcher stops its fleet
                self.proc.wait(timeout=20)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                pass
        targets = [p for p in self.seen.values() if p.is_running()]
        if self.proc.poll() is None:
            targets.append(psutil.Process(self.proc.pid))
        for p in targets:
            try:
                os.killpg(p.pid, signal.SIGKILL)  # each child leads its own session and group
            except (ProcessLookupError, PermissionError):
                pass
        psutil.wait_procs(targets, timeout=5)
        self.proc.wait()
        if self.t_end == 0.0:
            self.t_end = time.perf_counter()
        if self.fleet:
            self._sweep()

    def _sweep(self) -> None:
        """A last look for a process of this (uniquely named) fleet that escaped us."""
        for p in psutil.process_iter(["pid", "cmdline"]):
            cmd = p.info["cmdline"] or []
            if "--fleet" in cmd and cmd.index("--fleet") + 1 < len(cmd) and cmd[cmd.index("--fleet") + 1] == self.fleet:
                try:
                    p.kill()
                except psutil.Error:
                    pass


def cpu_seconds(procs: list[psutil.Process]) -> dict[int, float]:
    out = {}
    for p in procs:
        try:
            t = p.cpu_times()
            out[p.pid] = t.user + t.system
        except psutil.Error:
            pass
    return out


def ctx_switches(pids: list[int]) -> dict[int, int]:
    """Context switches (voluntary + involuntary) summed over every thread of each process."""
    out = {}
    for pid in pids:
        total = 0
        try:
            for tid in os.listdir(f"/proc/{pid}/task"):
                with open(f"/proc/{pid}/task/{tid}/status") as fh:
                    for line in fh:
                        if line.startswith(("voluntary_ctxt_switches", "nonvoluntary_ctxt_switches")):
                            total += int(line.split()[1])
        except OSError:
            continue
        out[pid] = total
    return out


def rss_mb(p: psutil.Process) -> float | None:
    try:
        return p.memory_info().rss / 2**20
    except psutil.Error:
        return None


def load_line() -> str:
    """What else is using this machine (the figures of a 2-core box depend on it)."""
    l1, l5, _ = os.getloadavg()
    busy = []
    me = os.getpid()
    for p in psutil.process_iter(["pid", "name", "cmdline"]):
        if p.pid == me:
            continue
        try:
            c = p.cpu_percent(interval=None)
        except psutil.Error:
            continue
        busy.append((p, c))
    time.sleep(0.5)
    hot = []
    for p, _ in busy:
        try:
            c = p.cpu_percent(interval=None)
        except psutil.Error:
            continue
        if c > 20:
            hot.append(f"{' '.join((p.info['cmdline'] or [p.info['name']])[:3])[:60]} {c:.0f}%")
    return f"load average {l1:.2f} (1 min) {l5:.2f} (5 min); busy now: {'; '.join(hot) or 'nothing'}"

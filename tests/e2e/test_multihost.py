"""Several hosts for real: the fleet split across Linux network namespaces (docs/multihost.md).

Three namespaces stand for three hosts, joined by veth pairs, with addresses that exist
only inside them:

    hosts.r  the router and the world (cdus launch --remote ...)   10.200.1.1, 10.200.2.1
    hosts.a  the USVs (python3 -m vehicle_agent ...)               10.200.1.2 (veth to r)
    hosts.b  the UAVs                                              10.200.2.2 (veth to r)

The vehicles are started with the command lines the launcher prints for vehicles started
elsewhere, pointed at the router address their namespace can reach. Lockstep across the
namespaces must give the in-process trace bit for bit; in real time, cutting b's link for
some seconds (a partition) must cost the world its UAVs and give them back, and the
formation must settle again. Needs root and iproute2 (CI has both); skipped otherwise.
"""

from __future__ import annotations

import json
import os
import re
import secrets
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from cdus.app.launcher import ZENOH_RUNTIME
from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics

from .conftest import ROOT, Launch, fleet_processes, kill_group, unique_fleet

PORT = 7447  # the namespaces are this test's own: a fixed port cannot collide


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check)


def netns_unavailable() -> str | None:
    """Why namespaces cannot be made here, or None."""
    if os.geteuid() != 0:
        return "needs root to make network namespaces (CI runs as root)"
    if shutil.which("ip") is None:
        return "needs iproute2's `ip` (apt-get install iproute2; .ci/run installs it)"
    probe = f"cdhprobe{secrets.token_hex(3)}"
    made = _ip("netns", "add", probe, check=False)
    if made.returncode != 0:
        return f"`ip netns add` does not work here: {made.stderr.strip()}"
    _ip("netns", "del", probe, check=False)
    return None


class Hosts:
    """Namespaces r, a, b; veth r<->a (10.200.1.0/24) and r<->b (10.200.2.0/24); the
    processes started in them. ``close`` removes everything, whatever happened."""

    NAMES = ("r", "a", "b")

    def __init__(self, logs: Path):
        self.tag = f"cdh{secrets.token_hex(3)}"  # interface names stay under 15 characters
        self.logs = logs
        self.ns = {n: f"{self.tag}{n}" for n in self.NAMES}
        self.procs: list[subprocess.Popen] = []
        self.made: list[str] = []
        self.router_ip = {"a": "10.200.1.1", "b": "10.200.2.1"}

    def veth(self, host: str) -> tuple[str, str]:
        """(the router's end, the host's end) of host's link."""
        return f"{self.tag}r{host}", f"{self.tag}{host}r"

    def open(self) -> None:
        for n in self.NAMES:
            _ip("netns", "add", self.ns[n])
            self.made.append(self.ns[n])
            _ip("-n", self.ns[n], "link", "set", "lo", "up")
        for host, net in (("a", 1), ("b", 2)):
            r_end, h_end = self.veth(host)
            _ip("link", "add", r_end, "netns", self.ns["r"], "type", "veth", "peer", "name", h_end,
                "netns", self.ns[host])
            _ip("-n", self.ns["r"], "addr", "add", f"10.200.{net}.1/24", "dev", r_end)
            _ip("-n", self.ns[host], "addr", "add", f"10.200.{net}.2/24", "dev", h_end)
            _ip("-n", self.ns["r"], "link", "set", r_end, "up")
            _ip("-n", self.ns[host], "link", "set", h_end, "up")

    def prefix(self, host: str) -> list[str]:
        return ["ip", "netns", "exec", self.ns[host]]

    def endpoint(self, host: str) -> str:
        """The router's endpoint as ``host`` reaches it."""
        return f"tcp/{self.router_ip[host]}:{PORT}"

    def start(self, host: str, argv: list[str], name: str) -> subprocess.Popen:
        log = open(self.logs / f"{name}.log", "wb")
        env = {**os.environ, "PYTHONUNBUFFERED": "1", "ZENOH_RUNTIME": ZENOH_RUNTIME}
        p = subprocess.Popen([*self.prefix(host), *argv], cwd=ROOT, stdout=log, stderr=subprocess.STDOUT,
                             stdin=subprocess.DEVNULL, start_new_session=True, env=env)
        log.close()
        self.procs.append(p)
        return p

    def link(self, host: str, up: bool) -> None:
        """Set host's link to the router down (a partition) or up, at the host's end."""
        _ip("-n", self.ns[host], "link", "set", self.veth(host)[1], "up" if up else "down")

    def traffic(self, host: str) -> int:
        """Bytes the host received over its link."""
        out = json.loads(_ip("-n", self.ns[host], "-s", "-j", "link", "show", "dev", self.veth(host)[1]).stdout)
        return int(out[0]["stats64"]["rx"]["bytes"])

    def close(self) -> None:
        for p in self.procs:
            kill_group(p)
        for ns in self.made:  # deleting a namespace deletes the veth ends inside it
            _ip("netns", "del", ns, check=False)
        left = [ns for ns in self.made if ns in _ip("netns", "list").stdout]
        assert not left, f"namespaces left behind: {left}"


@pytest.fixture
def hosts(tmp_path):
    why = netns_unavailable()
    if why:
        pytest.skip(why)
    logs = tmp_path / "hosts"
    logs.mkdir()
    h = Hosts(logs)
    try:
        h.open()
        yield h
    finally:
        h.close()


def launch_in(hosts: Hosts, launches, config: str, fleet: str, run: Path, extra: list[str]) -> Launch:
    """`cdus launch` in namespace r, listening on both router addresses, every vehicle remote
    (--insecure: the namespaces' private addresses reach nobody else; a real LAN takes --secure)."""
    sc = load_scenario(config)
    return launches([config, "--listen", hosts.endpoint("a"), "--listen", hosts.endpoint("b"), "--insecure",
                     "--remote", ",".join(sc.ids), "--logs", str(run), *extra], fleet, hosts.prefix("r"))


def start_vehicles(hosts: Hosts, la: Launch, groups: dict[str, list[str]]) -> dict[str, subprocess.Popen]:
    """Each vehicle in its namespace, with the command line the launcher printed for it,
    connecting to the router address that namespace can reach."""
    procs = {}
    for host, ids in groups.items():
        for vid in ids:
            line = la.wait_for(f"--id {vid}")
            argv = shlex.split(line)
            assert argv[:3] == ["python3", "-m", "vehicle_agent"], line
            while "--connect" in argv:
                i = argv.index("--connect")
                del argv[i:i + 2]
            procs[vid] = hosts.start(host, [sys.executable, *argv[1:], "--connect", hosts.endpoint(host)], vid)
    return procs


def sim_time_past(t: float) -> Callable[[str], bool]:
    """A launcher progress line (``<name>: t = 12.3 / 40.0 s ...``) at or past ``t``."""
    def past(line: str) -> bool:
        m = re.search(r": t = +([0-9.]+) / ", line)
        return m is not None and float(m.group(1)) >= t
    return past


LAKE_GROUPS = {"a": ["usv1", "usv2", "usv3"], "b": ["uav1", "uav2", "uav3"]}


def test_lake_circle_across_three_namespaces_is_the_single_host_run(tmp_path, hosts, launches):
    fleet = unique_fleet()
    run = tmp_path / "run"
    duration = 130.0  # coordination settles at 124.04 s (in process, deterministic)
    la = launch_in(hosts, launches, "configs/lake_circle.toml", fleet, run,
                   ["--clock", "lockstep", "--duration", str(duration), "--trace-out", str(tmp_path / "trace.npz"),
                    "-q"])
    agents = start_vehicles(hosts, la, LAKE_GROUPS)
    la.wait_for(f"fleet '{fleet}' up")
    assert la.wait(timeout=300) == 0, la.output()
    for vid, p in agents.items():
        assert p.wait(timeout=30) == 0, (hosts.logs / f"{vid}.log").read_text()
    # the vehicles' traffic crossed the veths (there is no other way out of a and b)
    assert hosts.traffic("a") > 100_000 and hosts.traffic("b") > 100_000

    m = Metrics.read(run / "metrics.json")
    sc = load_scenario("configs/lake_circle.toml", {"scenario.duration": duration})
    ref = InProcessFleet(sc).run()
    refm = ref.metrics
    assert m.completed is True
    assert m.path_settle_s is not None and m.coord_settle_s is not None, m
    assert (m.path_settle_s, m.coord_settle_s) == (refm.path_settle_s, refm.coord_settle_s)
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega"):
        assert np.array_equal(trace[name], ref.recorder.view(name)), name
    assert not fleet_processes(fleet)


def test_a_partition_costs_the_world_its_uavs_and_the_formation_settles_again(tmp_path, hosts, launches):
    fleet = unique_fleet()
    run = tmp_path / "run"
    # realtime: concentric_circles settles in about 8 s; a ring usv1-usv2-uav1-uav2. 36 s (it was 40):
    # cut at t ~ 10.8 s, healed at t ~ 18 s, settled again about 8 s later; under two busy loops and
    # more (load 10) the launcher printed the losses 13 s after the cut, the heal came at t = 23.6 s
    # and the settle at t = 29.9 s, still inside the run
    la = launch_in(hosts, launches, "configs/concentric_circles.toml", fleet, run,
                   ["--clock", "realtime", "--duration", "36"])
    groups = {"a": ["usv1", "usv2"], "b": ["uav1", "uav2"]}
    agents = start_vehicles(hosts, la, groups)
    la.wait_for(f"fleet '{fleet}' up")
    la.wait_for(sim_time_past(9.0), timeout=60)  # settled (the launcher prints its progress every 10%: 10.8 s)
    cut = time.monotonic()
    hosts.link("b", up=False)
    for vid in groups["b"]:
        la.wait_for(f"vehicle {vid} lost", timeout=30)
    noticed = time.monotonic() - cut
    la.wait_for(sim_time_past(15.0), timeout=30)  # the link stays down for at least 5 s (to t = 18 s)
    healed = time.monotonic()
    hosts.link("b", up=True)
    for vid in groups["b"]:
        la.wait_for(f"vehicle {vid} back", timeout=60)
    reconnected = time.monotonic() - healed
    down_for = healed - cut
    assert la.wait(timeout=120) == 0, la.output()
    for vid, p in agents.items():
        assert p.wait(timeout=30) == 0, (hosts.logs / f"{vid}.log").read_text()

    m = Metrics.read(run / "metrics.json")
    assert m.completed is True
    events = m.events
    down = {e.vehicle: e.t for e in events if e.kind == "vehicle_lost"}
    back = {e.vehicle: e.t for e in events if e.kind == "vehicle_back"}
    # the UAVs were cut off and came back; a boat may be reported lost too while the router
    # closes the stalled links (seen once in CI: usv1, back within the run), never for good
    assert set(groups["b"]) <= set(down) and set(down) == set(back), events
    assert all(back[v] > down[v] for v in back)
    # the world said what was left: usv1-usv2 alone still has a spanning tree
    assert any(e.kind == "graph" and down["uav1"] <= e.t for e in events), events
    # the formation settled again after the partition healed, and stayed settled to the end
    assert m.coord_settle_s is not None and m.coord_settle_s > max(down.values()), m
    assert m.final_coord_error_max < m.coord_tol, m
    # figures, not assertions (run with -s to see them; docs/multihost.md quotes them)
    print(f"\npartition: link down for {down_for:.1f} s; the world lost the UAVs {noticed:.1f} s after the cut "
          f"(t = {min(down.values()):.2f} s) and had them back {reconnected:.1f} s after the link came up "
          f"(t = {min(back.values()):.2f}-{max(back.values()):.2f} s); coordination settled again at "
          f"t = {m.coord_settle_s:.2f} s (first settle in process: 8.38 s)")
    assert not fleet_processes(fleet)

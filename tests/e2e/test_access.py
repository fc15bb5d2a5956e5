"""End to end: a secured fleet (cdus launch, by default; --tls) ignores everyone but its own.

An outsider tries what would hurt a fleet: stop the world and the vehicles (through the
world's command inbox, or the world's ctl to the vehicles directly), change their gains,
have the launcher kill one, inject ω. Without credentials (or with a wrong password) it cannot even connect;
with a stolen vehicle's credentials the router's access-control list lets it publish only
that vehicle's own keys. The same commands from the credentialed ground station work, so
each check could fail.
"""

from __future__ import annotations

import json
import random
import re
import shlex
import signal
import threading
import time
from dataclasses import replace

import numpy as np
import pytest
import zenoh

from cdus.scenario.config import load_scenario
from cdus.sim.build import listeners_of
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.wire.messages import OmegaMsg, StateMsg, encode_control, encode_omega, encode_states
from cdus.wire.schemas import AgentStats, FleetEvent, decode_event, encode_event, encode_stats, encode_status
from cdus.wire.transport import free_tcp_port
from cdus.wire.rejected import Rejected

from tests.outsider import raw_client

from .conftest import WorldTime, fleet_processes, run_cli, unique_fleet
from .test_faults import hostile_omega_payloads


def member(config_file) -> zenoh.Session:
    return zenoh.open(zenoh.Config.from_file(str(config_file)))


class Events:
    """The world's events, as a member of the fleet hears them."""

    def __init__(self, session: zenoh.Session, fleet: str):
        self.cond = threading.Condition()
        self.events: list[FleetEvent] = []
        self.sub = session.declare_subscriber(keys.world_events(fleet), self._on)

    def _on(self, sample) -> None:
        e = decode_event(sample.payload.to_bytes())
        assert not isinstance(e, Rejected), e
        with self.cond:
            self.events.append(e)
            self.cond.notify_all()

    def wait_for(self, kind: str, text: str = "", timeout: float = 30.0) -> FleetEvent:
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                for e in self.events:
                    if e.kind == kind and text in e.text:
                        return e
                assert time.monotonic() < deadline, f"no {kind} event {text!r}; heard {self.events}"
                self.cond.wait(timeout=0.2)


def gs_command(launch_output_line: str) -> list[str]:
    """The `cdus gs ...` arguments the launcher printed, without the trailing action."""
    words = shlex.split(launch_output_line.split("attach a ground station:", 1)[1])
    assert words[:2] == ["cdus", "gs"] and words[-1] == "status", words
    return words[1:-1]


def test_a_default_launch_is_secured_and_its_printed_ground_station_line_works(tmp_path, launches):
    """No flag at all (not even --listen): an outsider without credentials cannot connect,
    the ground station line the launcher prints works as printed."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "3000", "--rerun", "off",
                   "--logs", str(run), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    assert "secured (password): credentials in" in la.wait_for("secured (")
    gs = gs_command(la.wait_for("attach a ground station"))
    assert "WARNING" not in la.output()
    endpoint = gs[gs.index("-e") + 1]
    assert endpoint.startswith("tcp/127.0.0.1:")
    with pytest.raises(zenoh.ZError):  # no credentials: refused at the handshake
        zenoh.open(raw_client(endpoint))
    res = run_cli([*gs, "status", "--once"], timeout=60)
    assert res.returncode == 0, res.stderr
    assert "world: t =" in res.stdout and "usv1" in res.stdout
    res = run_cli([*gs, "stop"], timeout=60)
    assert res.returncode == 0, res.stderr
    assert la.wait(timeout=60) == 0, la.output()
    assert Metrics.read(run / "metrics.json").completed is False  # stopped, as asked
    assert not fleet_processes(fleet)


def test_an_outsider_cannot_stop_retune_or_inject_into_a_secured_fleet(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    duration = 60.0
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", str(duration), "--secure",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"),
                   "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    gs = gs_command(la.wait_for("attach a ground station"))
    secure = run / "secure"
    assert f"--zenoh-config {secure / 'ground.json5'}" in " ".join(gs)
    sc = load_scenario("configs/lake_circle.toml", {"scenario.duration": duration})
    endpoint = f"tcp/127.0.0.1:{port}"
    ground = member(secure / "ground.json5")
    command = keys.world_cmd(fleet, keys.GROUND)
    try:
        events = Events(ground, fleet)
        # the ground station holds the fleet, so all of the below happens mid-run
        ground.put(command, encode_control("pause"))
        events.wait_for("fleet", "paused")

        # 1. no credentials, or a wrong password: the router does not let it in
        with pytest.raises(zenoh.ZError):
            zenoh.open(raw_client(endpoint))
        wrong = json.loads((secure / "ground.json5").read_text())
        wrong["transport"]["auth"]["usrpwd"]["password"] = "letmein"
        (tmp_path / "wrong.json5").write_text(json.dumps(wrong))
        with pytest.raises(zenoh.ZError):
            member(tmp_path / "wrong.json5")

        # 2. a stolen vehicle's credentials: commands, the world's keys and other vehicles' ω are refused
        mallory = member(secure / "vehicle-usv1.json5")
        try:
            for key in (command, keys.world_cmd(fleet, "usv1"), keys.world_cmd(fleet, keys.LAUNCHER)):
                mallory.put(key, encode_control("stop"))
                mallory.put(key, encode_control("set_gains", gains={"k": 7.0, "c": 0.1}, vehicle=""))
                mallory.put(key, encode_control("kill", vehicle="usv2"))
            mallory.put(command, encode_control("resume"))
            for targets in (sc.ids, ["usv2"]):
                mallory.put(keys.ctl(fleet, targets), encode_control("stop"))
                mallory.put(keys.ctl(fleet, targets), encode_control("gains", gains={"k": 7.0, "c": 0.1}, tick=1))
            mallory.put(keys.launcher_cmd(fleet), encode_control("kill", vehicle="usv2"))
            mallory.put(keys.launcher_cmd(fleet), encode_control("kill", vehicle="world"))
            # another vehicle's telemetry and counters, the world's status and events: not its keys
            forged_row = StateMsg(sc.ids.index("usv2"), 6000, 120.0, (0.0, 0.0), 0.0, 0.0, 0.0, 0.0, 0.0)
            for tick in (1, 50, 6000):
                mallory.put(keys.state(fleet, "usv2"), encode_states([replace(forged_row, tick=tick)]))
            mallory.put(keys.stats(fleet, "usv2"), encode_stats(AgentStats("usv2", 6000, rejected=10**6,
                                                                           rejected_by_reason={"forged": 10**6})))
            mallory.put(keys.world_status(fleet), encode_status(1e308, 1.0, "FORGED", [], [], 0.0, 0.0, [], False))
            mallory.put(keys.world_events(fleet), encode_event(FleetEvent.of(0.0, "fleet", "FORGED stopped")))
            for vid in sc.ids:
                j = sc.ids.index(vid)
                to = [v for v in sc.ids if v != vid]  # to everyone, and to its real listeners
                for dst in (to, listeners_of(sc, vid)) if vid != "usv1" else (to,):
                    for seq in range(10**6, 10**6 + 20):  # well-formed, newer than anything real
                        mallory.put(keys.omega(fleet, vid, dst), encode_omega(OmegaMsg(j, seq, 1.0, 1e3, -1.0)))
            # ...but its own key is its own: malformed payloads there reach the listeners,
            # which count and drop them (the positive control for the counts below)
            own = hostile_omega_payloads(random.Random(7), 40)
            for p in own:
                mallory.put(keys.omega(fleet, "usv1", listeners_of(sc, "usv1")), p)
        finally:
            mallory.close()
        assert la.proc.poll() is None, "the run ended before the outsider was done: the test proves nothing"

        # 3. the credentialed ground station, with the command line the launcher printed
        res = run_cli([*gs, "gains", "k=1.5", "c=2.0"], timeout=60)  # the configured gains: a visible no-op
        assert res.returncode == 0, res.stderr
        events.wait_for("gains_changed")
        ground.put(command, encode_control("pause"))
        events.wait_for("fleet", "paused")
        ground.put(command, encode_control("resume"))
        events.wait_for("fleet", "resumed")
        assert not [e for e in events.events if "FORGED" in e.text], events.events  # its event never reached us
    finally:
        ground.close()

    assert la.wait(timeout=300) == 0, la.output()
    assert "FORGED" not in la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True, m.events  # no stop got through
    kinds = [e.kind for e in m.events]
    assert kinds.count("fleet") == 2 and kinds.count("gains_changed") == 1, m.events  # the ground station's
    assert "fault" not in kinds and "vehicle_lost" not in kinds, m.events
    listeners = len(listeners_of(sc, "usv1"))
    assert m.link.rejected == len(own) * listeners, m.link  # no forged ω or command reached anyone
    # the ground station's gains were applied once by every vehicle, the outsider's never
    for v in sc.vehicles:
        log = (run / "logs" / f"{v.id}.log").read_text()
        applied = re.findall(r"gains k = \(([^)]*)\), c = (\S+) from tick", log)
        assert applied == [(", ".join(["1.5"] * v.dim), "2.0")], (v.id, applied)
        assert "Traceback" not in log
    # and nothing reached a controller: the run is the clean in-process one, bit for bit
    ref = InProcessFleet(sc).run()
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega"):
        assert np.array_equal(trace[name], ref.recorder.view(name)), name
    assert not fleet_processes(fleet)


def test_over_tls_only_a_certificate_of_the_run_gets_in_and_the_ground_station_can_stop_it(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/concentric_circles.toml", "--clock", "realtime", "--duration", "600", "--tls",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    gs = gs_command(la.wait_for("attach a ground station"))
    assert f"tls/127.0.0.1:{port}" in gs
    secure = run / "secure"
    # plain TCP, or TLS without a client certificate: refused at the handshake
    for endpoint in (f"tcp/127.0.0.1:{port}", f"tls/127.0.0.1:{port}"):
        conf = raw_client(endpoint)
        conf.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(str(secure / "ca.pem")))
        with pytest.raises(zenoh.ZError):
            zenoh.open(conf)
    # a vehicle's certificate and password: its stop is refused; the world runs on
    ground = member(secure / "ground.json5")
    try:
        status = WorldTime(ground, fleet)
        mallory = member(secure / "vehicle-usv1.json5")
        try:
            mallory.put(keys.world_cmd(fleet, keys.GROUND), encode_control("stop"))
            mallory.put(keys.ctl(fleet, ["usv1", "usv2", "uav1", "uav2"]), encode_control("stop"))
        finally:
            mallory.close()
        status.wait_past(status.wait_past(0.0) + 2.0)  # two simulated (here: wall) seconds later
        assert la.proc.poll() is None, la.output()
    finally:
        ground.close()
    res = run_cli([*gs, "status", "--once"], timeout=60)
    assert res.returncode == 0, res.stderr
    assert "world: t =" in res.stdout and "usv1" in res.stdout
    # the ground station's stop ends the run
    res = run_cli([*gs, "stop"], timeout=60)
    assert res.returncode == 0, res.stderr
    assert la.wait(timeout=60) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is False
    assert not fleet_processes(fleet)


def test_in_realtime_the_router_passes_a_flood_on_one_omega_key_at_most_at_its_stated_rate(tmp_path, launches):
    """Zenoh's downsampling, per incoming link: an outsider flooding usv1's ω key reaches usv1's
    listeners at most OMEGA_MARGIN x the broadcast rate, and usv1's own ω still gets through."""
    from cdus.app.launcher import OMEGA_MARGIN

    fleet = unique_fleet()
    port = free_tcp_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    sc = load_scenario("configs/concentric_circles.toml")
    la = launches(["configs/concentric_circles.toml", "--clock", "realtime", "--duration", "600", "--rerun", "off",
                   "--listen", endpoint, "--logs", str(tmp_path / "run"), "-q", "--insecure"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    # an open fleet on loopback, and the launcher said what that allows
    assert f"WARNING: --insecure: anyone who reaches this router ({endpoint}: any process of this host) can" \
        in la.wait_for("WARNING: --insecure")
    key = keys.omega(fleet, "usv1", listeners_of(sc, "usv1"))
    forged = encode_omega(OmegaMsg(sc.ids.index("usv1"), 10**6, 1.0, 1e3, -1.0))
    seen = {"forged": 0, "genuine": 0}
    lock = threading.Lock()
    counting = threading.Event()

    def on(sample) -> None:
        if counting.is_set():
            with lock:
                seen["forged" if sample.payload.to_bytes() == forged else "genuine"] += 1

    observer = zenoh.open(raw_client(endpoint))
    flooder = zenoh.open(raw_client(endpoint))
    try:
        observer.declare_subscriber(keys.any_omega(fleet).replace("/omega/*", "/omega/usv1"), on)
        WorldTime(observer, fleet).wait_past(1.0)  # the run is on: usv1 broadcasts
        pub = flooder.declare_publisher(key)
        sent = 0
        counting.set()
        t0 = time.monotonic()
        while time.monotonic() - t0 < 3.0:
            for _ in range(100):
                pub.put(forged)
            sent += 100
        time.sleep(0.3)  # what the router let through has arrived
        counting.clear()
        window = time.monotonic() - t0
    finally:
        flooder.close()
        observer.close()
    rate = OMEGA_MARGIN * sc.rates.broadcast
    assert sent > 20 * rate * 3.0, f"the flood ({sent} messages) was too slow to prove anything"
    assert 0 < seen["forged"] <= rate * window + 2, (seen, sent, rate, window)
    assert seen["genuine"] > 0.5 * sc.rates.broadcast * window, seen  # usv1's own link has its own budget
    assert la.proc.poll() is None, la.output()
    la.proc.send_signal(signal.SIGINT)
    assert la.wait(timeout=60) == 130, la.output()
    assert not fleet_processes(fleet)

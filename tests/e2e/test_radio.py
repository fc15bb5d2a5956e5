"""End to end: with [radio] on, a lockstep fleet of processes (the world samples the
geometry, the agents wait for the sample in force and decide each message with the radio
channel) reproduces the in-process run bit for bit: the trace, the radio counters by cause,
the utilisation and the split/rejoin events."""

from __future__ import annotations

import time

import numpy as np
import pytest

from cdus.scenario.config import load_scenario, parse_value
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics

from .conftest import ROOT, assert_same_trace, fleet_processes, unique_fleet

RADIO_KINDS = ("radio_split", "radio_joined")


@pytest.mark.parametrize("config, duration", [("configs/lake_radio.toml", 6.0), ("configs/range_out.toml", 112.0)])
def test_lockstep_with_the_radio_reproduces_the_in_process_run(tmp_path, launches, config, duration):
    """lake_radio: 6 s, six vehicles relayed by the shore station (collisions drop some
    messages). range_out, all of it: the drones leave the station's range at about 19 s and
    come back at about 84 s: the split and the join are reported by the world as by the
    in-process fleet, at the same time, and the formation settles again after the return."""
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([config, "--clock", "lockstep", "--duration", str(duration),
                   "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    assert la.wait() == 0, la.output()
    sc = load_scenario(config, {"scenario.duration": duration})
    ref = InProcessFleet(sc).run()
    assert_same_trace(tmp_path / "trace.npz", ref)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.completed is True
    radio, expected = metrics.radio, ref.metrics.radio
    assert radio.sent > 0 and radio.dropped > 0
    assert radio == expected
    ours = [(e.t, e.kind, e.text) for e in metrics.events if e.kind in RADIO_KINDS]
    theirs = [(e.t, e.kind, e.text) for e in ref.metrics.events if e.kind in RADIO_KINDS]
    assert ours == theirs
    if "range_out" in config:
        assert [k for _, k, _ in ours] == ["radio_split", "radio_joined"]
        assert radio.dropped_by["range"] > 0
        split, joined = ours[0][0], ours[1][0]
        assert 15.0 < split < joined < duration
        # re-converged after the return: settled by the end, and not before the split
        assert metrics.coord_settle_s is not None and metrics.coord_settle_s > split
        assert metrics.coord_settle_s == ref.metrics.coord_settle_s
    assert not fleet_processes(fleet)


RESTART = """
[[event]]
at = 3.0
action = "kill"
vehicle = "uav2"

[[event]]
at = 5.0
action = "restart"
vehicle = "uav2"

[[event]]
at = 7.0
action = "radio"
tx_power = -10.0
"""


def test_a_restarted_vehicle_gets_the_geometry_in_force_and_the_run_stays_equal(tmp_path, launches):
    """range_out for 10 s with uav2 killed at 3 s and restarted at 5 s, and a scheduled radio
    change at 7 s (-10 dBm: the station hears nobody): the new process is sent the newest
    geometry samples with its catch-up, waits for the one in force, and the fleet
    of processes still equals the in-process run to the bit (the trajectories; the radio
    counters too, but for what the killed process decided since its last report)."""
    config = tmp_path / "range_out_restart.toml"
    config.write_text((ROOT / "configs" / "range_out.toml").read_text() + RESTART)
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([str(config), "--clock", "lockstep", "--duration", "10", "--logs", str(run),
                   "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    assert la.wait() == 0, la.output()
    ref = InProcessFleet(load_scenario(config, {"scenario.duration": 10.0})).run()
    trace = np.load(tmp_path / "trace.npz")
    for name in ("q", "omega"):
        assert np.array_equal(trace[name], ref.recorder.view(name)), name
    metrics = Metrics.read(run / "metrics.json")
    radio, expected = metrics.radio, ref.metrics.radio
    assert (radio.utilisation, radio.splits) == (expected.utilisation, expected.splits)
    # a process killed before its first stats report (about 1 s of wall time) takes its counts
    # along (docs/metrics.md: counts are equal when no process was killed)
    assert 0 < radio.sent <= expected.sent and radio.sent >= expected.sent - 3 * 2 * 10
    assert radio.dropped_by["range"] == expected.dropped_by["range"] > 0  # after 7 s, every process
    assert [e.kind for e in metrics.events if e.kind == "vehicle_back"] == ["vehicle_back"]
    changed = [(e.t, e.text) for e in metrics.events if e.kind == "radio_changed"]
    assert changed == [(e.t, e.text) for e in ref.metrics.events if e.kind == "radio_changed"]
    assert changed == [(7.0, "radio: tx_power = -10 dBm from tick 140 (t = 7 s) (scheduled)")]
    assert not fleet_processes(fleet)


def _world_log_value(path, text: str, number: bool = True, timeout: float = 60.0):
    """The number after ``text`` in the first line of the world's log that has it (waits)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        lines = [ln for ln in (path.read_text().splitlines() if path.exists() else []) if text in ln]
        if lines:
            return float(lines[0].split(text)[1].split()[0]) if number else lines[0]
        time.sleep(0.2)
    raise AssertionError(f"no {text!r} in {path} within {timeout} s")


def test_a_ground_station_radio_command_changes_delivery_from_its_time_on(tmp_path, launches):
    """`cdus gs ... radio tx_power=-30 --at 0` on a lockstep lake_radio fleet: the world moves
    the change past its grant, relays it, and from then on the shore station hears nobody
    (range drops); the run up to the stop equals the in-process run given the same change at
    the same time (InProcessFleet.set_radio), to the bit."""
    from cdus.wire.transport import free_tcp_port

    from .test_ground_station import gs

    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/lake_radio.toml", "--clock", "lockstep", "--duration", "3000",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run),
                   "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    assert gs(fleet, port, run, "radio", "tx_power=-300").returncode == 2  # refused before sending
    res = gs(fleet, port, run, "radio", "tx_power=-30", "--at", "0")
    assert res.returncode == 0, res.stderr
    at_text = _world_log_value(run / "logs" / "world.log", "radio changed from t =")
    period = 1.0 / 50.0
    at = round(at_text / period) * period  # the world moved it to the tick after its grant
    _world_log_value(run / "logs" / "world.log", "communication graph split", number=False)  # the station hears nobody
    assert gs(fleet, port, run, "stop").returncode == 0
    assert la.wait(timeout=60) == 0, la.output()
    metrics = Metrics.read(run / "metrics.json")
    kinds = [e.kind for e in metrics.events]
    assert "radio_changed" in kinds
    assert metrics.radio.dropped_by["range"] > 0
    trace = np.load(tmp_path / "trace.npz")
    sc = load_scenario("configs/lake_radio.toml")
    ref = InProcessFleet(sc)
    ref.set_radio({"tx_power": -30.0}, at)
    out = ref.run(metrics.duration_s)
    n = len(trace["t"])
    assert n == len(out.recorder) and n * period > at + 0.5
    for name in ("q", "omega"):
        assert np.array_equal(trace[name], out.recorder.view(name)), name
    assert not fleet_processes(fleet)



def _put(session, key: str, payload: bytes) -> None:
    """A put that waits for room rather than being dropped (Zenoh drops a put under congestion
    by default): these tests count every message the fleet refuses, to the one, and then need
    the ground station's own command to arrive. The clean-clone CI lost the last command after
    a burst of 45 kB forgeries (no radio_changed event in 30 s)."""
    import zenoh

    session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)

def _range_out_with_a_forger(tmp_path, launches, secured: bool, duration: float = 10.0):
    """A lockstep range_out fleet up, with a trace, and two sessions: ``boss`` holding the ground
    credentials and ``mallory`` uav1's (secured), or one raw client for both (--insecure).
    Returns (fleet, run dir, launch, scenario, boss, mallory)."""
    from cdus.wire.transport import free_tcp_port
    from tests.outsider import raw_client

    from .test_access import member

    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/range_out.toml", "--clock", "lockstep", "--duration", str(duration),
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"),
                   "-q", *(() if secured else ("--insecure",))], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    sc = load_scenario("configs/range_out.toml", {"scenario.duration": duration})
    if secured:
        boss, mallory = member(run / "secure" / "ground.json5"), member(run / "secure" / "vehicle-uav1.json5")
    else:
        import zenoh
        boss = mallory = zenoh.open(raw_client(f"tcp/127.0.0.1:{port}"))
    return fleet, run, la, sc, boss, mallory


@pytest.mark.parametrize("secured", [True, False], ids=["secured", "insecure"])
def test_forged_radio_geometry_is_refused_by_a_secured_fleet_and_detected_on_an_open_one(tmp_path, launches, secured):
    """range_out, lockstep, 10 s, held by a pause while someone publishes a geometry sample with
    every vehicle 9,000 km away for every sample tick of the run (to the whole fleet and to each
    vehicle alone). Secured: the forger holds uav1's credential and the router refuses every one
    (the ACL: only the world publishes on the radio key), so the run is the in-process one to the
    bit and no vehicle counts a radio reject. Open (--insecure): the forgeries for the ticks to
    come stand (docs/security.md), but the world's samples that come later are counted
    ``radio_conflict`` and the world reports a ``suspect`` event."""
    import msgpack

    from cdus.wire import keys
    from cdus.wire.messages import encode_control

    from .test_access import Events

    fleet, run, la, sc, boss, mallory = _range_out_with_a_forger(tmp_path, launches, secured)
    duration = sc.duration
    try:
        events = Events(boss, fleet)
        _put(boss, keys.world_cmd(fleet, keys.GROUND), encode_control("pause"))
        events.wait_for("fleet", "paused")
        every = round(sc.radio.sample_period * sc.rates.control)
        far = msgpack.packb  # every vehicle 9,000 km out: nobody hears anybody
        for to in (sc.ids, *([v] for v in sc.ids)):
            for tick in range(0, round(duration * sc.rates.control) + 1, every):
                _put(mallory, keys.radio(fleet, to), far([1, tick, [[9.0e6, 0.0, 30.0]] * len(sc.ids)]))
        assert la.proc.poll() is None, "the run ended before the forger was done: the test proves nothing"
        _put(boss, keys.world_cmd(fleet, keys.GROUND), encode_control("resume"))
        assert la.wait() == 0, la.output()
    finally:
        boss.close()
        if mallory is not boss:
            mallory.close()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True
    radio_rejects = {k: v for k, v in m.rejected_by_reason.vehicles.items() if k.startswith("radio_")}
    ref = InProcessFleet(sc).run()
    if secured:
        assert radio_rejects == {}
        trace = np.load(tmp_path / "trace.npz")
        for name in ("q", "omega"):
            assert np.array_equal(trace[name], ref.recorder.view(name)), name
        assert m.radio == ref.metrics.radio
    else:
        assert radio_rejects.get("radio_conflict", 0) > 0, radio_rejects
        assert m.radio.dropped_by["range"] > ref.metrics.radio.dropped_by["range"]  # it did change it
        suspects = [e for e in m.events if e.kind == "suspect" and "radio_conflict" in e.text]
        assert suspects, m.events
    assert not fleet_processes(fleet)


def test_a_lockstep_fleet_beyond_the_geometry_bounds_runs_and_equals_the_in_process_run(tmp_path, launches):
    """range_out with its drones beyond the geometry's ±1e7 m: every agent refused the world's
    first sample (`radio_range`) and waited for it at tick 1 forever. Now the world sends such a
    vehicle as not live: nobody is heard, the run ends, and it equals the in-process run. (A path
    is within ±1e6 m, cdus.wire.bounds: the drones fly out there, a line from 900 km out at
    1,000 km/s, past 1e7 m after 9.1 s.)"""
    fleet = unique_fleet()
    run = tmp_path / "run"
    line = "{family='line',origin=[-9e5,0.0,30.0],heading=[1.0,0.0,0.0],speed=1e6}"
    sets = {"rates.control": "10", "rates.broadcast": "10", **{
        f"vehicle.{v}.{k}": x for v in ("uav1", "uav2", "uav3", "uav4") for k, x in (("path", line), ("phase", "0.0"))}}
    la = launches(["configs/range_out.toml", "--clock", "lockstep", "--duration", "12", "--logs", str(run), "-q",
                   *[a for k, v in sets.items() for a in ("--set", f"{k}={v}")]], fleet)
    assert la.wait(timeout=120) == 0, la.output()
    metrics = Metrics.read(run / "metrics.json")
    ref = InProcessFleet(load_scenario("configs/range_out.toml", {"scenario.duration": 12.0, **{
        k: parse_value(v) for k, v in sets.items()}})).run()
    assert abs(ref.recorder.q[:ref.recorder._n]).max() > 1e7  # they got out there
    assert metrics.radio == ref.metrics.radio
    assert metrics.radio.dropped_by["range"] == metrics.radio.sent > 0
    assert not {k for k in metrics.rejected_by_reason.vehicles if k.startswith("radio_")}
    assert not fleet_processes(fleet)


@pytest.mark.parametrize("config", ["configs/range_out.toml", "configs/lake_circle.toml"])
def test_ground_station_radio_commands_out_of_range_or_without_radio_are_refused_with_the_reason(
        tmp_path, launches, config):
    """`cdus gs radio` against a running lockstep fleet: NaN or 1e400 dBm, a station of 4
    coordinates are refused before sending (exit 2, the field named); --at past the run's end,
    or any change to a fleet without [radio], are refused by the world with its reason (exit 1)
    and a `rejected` event; no agent counts a bad radio command; the run goes on and stops clean."""
    from cdus.wire.transport import free_tcp_port

    from .test_ground_station import gs

    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches([config, "--clock", "lockstep", "--duration", "3000", "--listen", f"tcp/127.0.0.1:{port}",
                   "--logs", str(run), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    # refused by the ground station before it sends, whatever the fleet: checked once, on the fleet with [radio]
    local = ((["tx_power=nan"], "tx_power"), (["tx_power=1e400"], "tx_power"), (["station=[1,2,3,4]"], "station"))
    for args, field in local if "range_out" in config else ():
        res = gs(fleet, port, run, "radio", *args)
        assert res.returncode == 2 and f"line: {field}:" in res.stderr, (args, res.returncode, res.stderr)
    late = gs(fleet, port, run, "radio", "tx_power=10", "--at", "1e6")  # past the end, within at's bound
    assert late.returncode != 0
    assert ("past the run's end" if "range_out" in config else "no [radio]") in late.stdout + late.stderr, late
    if "lake_circle" in config:
        res = gs(fleet, port, run, "radio", "tx_power=10")
        assert res.returncode != 0 and "no [radio]" in res.stdout + res.stderr, res
    assert gs(fleet, port, run, "stop").returncode == 0
    assert la.wait(timeout=120) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert "bad_radio_command" not in m.rejected_by_reason.vehicles
    assert [e.kind for e in m.events].count("rejected") == (1 if "range_out" in config else 2)
    assert not fleet_processes(fleet)


def _hostile_geometry(sc) -> list[bytes]:
    """Geometry samples every vehicle's decoder refuses (decode_geometry): none can stand for a tick."""
    import msgpack

    n = len(sc.ids)
    drone = [1.0, 2.0, 30.0]
    last = round(sc.duration * sc.rates.control)
    return [b"\xc1", b"", msgpack.packb([2, 0, [drone] * n]), msgpack.packb([1, 0, [[1.0, float("nan"), 3.0]] * n]),
            msgpack.packb([1, 0, [[1.0, 1e300, 3.0]] * n]), msgpack.packb([1, 0, [drone] * (n + 1)]),
            msgpack.packb([1, 0, [[1.0, 2.0]] * n]), msgpack.packb([1, 0, [drone] * 5000]),
            msgpack.packb([1, -4, [drone] * n]), msgpack.packb([1, 1, [drone] * n]),  # not a sample tick
            msgpack.packb([1, last + 4, [drone] * n]), msgpack.packb([1, 0, [[1, 2, 3]] * n]),
            msgpack.packb([1, 0, [{"x": 1.0}] * n]), msgpack.packb([[[[[[[]]]]]]] * 3)]


def _hostile_radio_ctl(sc) -> list[bytes]:
    """World-to-vehicle radio changes every vehicle refuses, numbered as the world numbers its
    commands (0, 1, ...): refused, none may use up the number of the world's own command."""
    import msgpack

    from cdus.wire.messages import encode_control

    out = [encode_control("radio", radio={"tx_power": 1e9}, at=5.0, seq=0),
           encode_control("radio", radio={"station": [0.0]}, at=5.0, seq=0),
           encode_control("radio", radio={"power": 3.0}, at=5.0, seq=1),
           encode_control("radio", radio={}, at=5.0, seq=2),
           encode_control("radio", radio={"tx_power": 3.0}, at=-1.0, seq=0),  # radio_command_range
           encode_control("radio", radio={"tx_power": 3.0}, at=2e9, seq=0),
           encode_control("radio", radio={"tx_power": 3.0}, at=5.0, seq=-1),  # seq
           encode_control("radio", radio={"a": {"b": {"c": {"d": {}}}}}, at=5.0, seq=0),
           msgpack.packb({"v": 1, "op": "radio", "radio": {"tx_power": 3.0}, "at": float("nan"), "seq": 0}),
           msgpack.packb({"v": 1, "op": "radio", "radio": [1, 2], "at": 5.0, "seq": 0})]
    return out


def _hostile_radio_commands() -> list[bytes]:
    """Radio commands to the world that it refuses (each counted, answered on a query)."""
    import msgpack

    from cdus.wire.messages import encode_control

    return [b"\xc1", msgpack.packb({"v": 1, "op": "radio", "radio": {"tx_power": float("nan")}, "at": -1.0}),
            encode_control("radio", radio={"tx_power": 1e9}, at=-1.0),
            encode_control("radio", radio={"station": [1e300, 0.0]}, at=-1.0),
            encode_control("radio", radio={"station": [1.0, 2.0, 3.0, 4.0]}, at=-1.0),
            encode_control("radio", radio={"tx_power": True}, at=-1.0),
            encode_control("radio", radio={"tx_power": 3.0}, at=1e12),  # past the run's end
            encode_control("radio", radio={"txpower": 3.0}, at=-1.0),
            encode_control("radio", radio={"tx_power": 3.0, "junk": [[[[[]]]]]}, at=-1.0),
            msgpack.packb({"v": 1, "op": "radio", "radio": {"tx_power": 3.0}, "at": "soon"}),
            msgpack.packb({"v": 1, "op": "radio", "radio": {"tx_power": 3.0}, "at": [0.0] * 5000})]


@pytest.mark.parametrize("secured", [True, False], ids=["secured", "insecure"])
def test_hostile_radio_messages_are_counted_and_change_nothing_but_the_worlds_change(tmp_path, launches, secured):
    """range_out, lockstep, 10 s, held by a pause while someone publishes radio geometry every
    vehicle refuses, radio changes on the vehicles' ctl key that they refuse (numbered as the
    world numbers its commands), and radio commands to the world that it refuses; then the
    ground station changes tx_power from t = 5 s (the world's command number 0). Secured: the
    forger holds uav1's credential (the router refuses its puts on the world's keys); open
    (--insecure): a raw client, whose messages reach the vehicles, are counted by reason and
    dropped. Either way the run equals the in-process run given the same change (to the bit),
    and the world's change was applied by every vehicle (before d2ecdd7 a refused forgery
    numbered 0 made every vehicle drop it as heard again)."""
    from cdus.wire import keys
    from cdus.wire.messages import encode_control

    from .test_access import Events

    fleet, run, la, sc, boss, mallory = _range_out_with_a_forger(tmp_path, launches, secured)
    geometry, ctl, commands = _hostile_geometry(sc), _hostile_radio_ctl(sc), _hostile_radio_commands()
    try:
        events = Events(boss, fleet)
        _put(boss, keys.world_cmd(fleet, keys.GROUND), encode_control("pause"))
        events.wait_for("fleet", "paused")
        for payload in geometry:
            _put(mallory, keys.radio(fleet, sc.ids), payload)
        for payload in ctl:
            _put(mallory, keys.ctl(fleet, sc.ids), payload)
        for payload in commands:  # the vehicle's credential may not command the world: refused by the router
            _put(mallory, keys.world_cmd(fleet, keys.GROUND), payload)
            _put(boss, keys.world_cmd(fleet, keys.GROUND), payload)
        _put(boss, keys.world_cmd(fleet, keys.GROUND), encode_control("radio", radio={"tx_power": -10.0}, at=5.0))
        events.wait_for("radio_changed", "t = 5.00 s")
        assert la.proc.poll() is None, "the run ended before the forger was done: the test proves nothing"
        _put(boss, keys.world_cmd(fleet, keys.GROUND), encode_control("resume"))
        assert la.wait() == 0, la.output()
    finally:
        boss.close()
        if mallory is not boss:
            mallory.close()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True
    ref_fleet = InProcessFleet(sc)
    ref_fleet.set_radio({"tx_power": -10.0}, 5.0)
    ref = ref_fleet.run()
    assert_same_trace(tmp_path / "trace.npz", ref)
    assert m.radio == ref.metrics.radio and m.radio.dropped_by["range"] > 0
    world, vehicles = m.rejected_by_reason.world, m.rejected_by_reason.vehicles
    times = 1 if secured else 2  # the world's refusals: the ground station's (and the raw client's)
    assert sum(world.values()) == times * len(commands), world
    if secured:
        assert vehicles == {}, vehicles
    else:  # every vehicle counted each forgery once
        assert sum(vehicles.values()) == (len(geometry) + len(ctl)) * len(sc.ids), vehicles
    assert not fleet_processes(fleet)


def test_infinite_correlation_scales_start_a_fleet_that_equals_the_in_process_run(tmp_path, launches):
    """radio.shadowing_distance = inf and shadowing_time = inf are valid (not correlated in space;
    not changing with time), and so is a link down window with to = inf: `cdus launch` crashed on
    them writing the scenario for its processes (a traceback, 'Out of range float values are not
    JSON compliant'). range_out for 4 s with all three: lockstep equals cdus sim to the bit."""
    sets = {"radio.shadowing_distance": "inf", "radio.shadowing_time": "inf",
            "link.down": '[{src = "uav1", dst = "uav2", from = 2.0, to = inf}]'}
    fleet = unique_fleet()
    run = tmp_path / "run"
    args = ["configs/range_out.toml", "--clock", "lockstep", "--duration", "4", "--logs", str(run),
            "--trace-out", str(tmp_path / "trace.npz"), "-q"]
    for k, v in sets.items():
        args += ["--set", f"{k}={v}"]
    la = launches(args, fleet)
    assert la.wait() == 0, la.output()
    from cdus.scenario.config import parse_value
    sc = load_scenario("configs/range_out.toml", {"scenario.duration": 4.0, **{k: parse_value(v) for k, v in
                                                                               sets.items()}})
    assert sc.radio.shadowing_distance == sc.radio.shadowing_time == float("inf")
    ref = InProcessFleet(sc).run()
    assert_same_trace(tmp_path / "trace.npz", ref)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.radio == ref.metrics.radio and metrics.radio.dropped_by["fault"] > 0  # the down link
    assert metrics.link.faults == ref.metrics.link.faults
    assert not fleet_processes(fleet)


EDGE_EVENTS = """
[[event]]
at = 0.0
action = "pause"
vehicle = "usv2"

[[event]]
at = 1.0
action = "resume"
vehicle = "usv2"

[[event]]
at = 1.5
action = "kill"
vehicle = "uav3"

[[event]]
at = 1.5
action = "radio"
tx_power = 0.0
station = [0.0, -300.0]

[[event]]
at = 2.5
action = "restart"
vehicle = "uav3"

[[event]]
at = 4.0
action = "radio"
tx_power = 20.0

[[event]]
at = 4.0
action = "radio"
station = [0.0, -100.0]

[[event]]
at = 4.001
action = "radio"
tx_power = 15.0

[[event]]
at = 4.019
action = "radio"
tx_power = 18.0

[[event]]
at = 5.0
action = "radio"
tx_power = 10.0

[[event]]
at = 9.0
action = "radio"
tx_power = -50.0
"""


def test_faults_and_radio_changes_at_the_edges_equal_the_in_process_run(tmp_path, launches):
    """lake_radio for 5 s with a geometry sample every tick (sample_period 0.02 s): usv2 paused
    from t = 0 (before cc957bf the world waited for its tick-0 row for ever: 'vehicles_lost'
    after 30 s, no trace), uav3 killed at 1.5 s on the tick a radio change moves the station and
    restarted at 2.5 s (cdus sim rejoined it twice: an ulp off at the restart tick), two radio
    changes at one time and two within one tick, one on the last tick and one past the end. The
    trace and the radio events equal cdus sim's."""
    config = tmp_path / "lake_radio_edges.toml"
    config.write_text((ROOT / "configs" / "lake_radio.toml").read_text() + EDGE_EVENTS)
    fleet = unique_fleet()
    run = tmp_path / "run"
    la = launches([str(config), "--clock", "lockstep", "--duration", "5", "--set", "radio.sample_period=0.02",
                   "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"), "-q"], fleet)
    assert la.wait(timeout=120) == 0, la.output()
    ref = InProcessFleet(load_scenario(config, {"scenario.duration": 5.0, "radio.sample_period": 0.02})).run()
    assert_same_trace(tmp_path / "trace.npz", ref)
    metrics = Metrics.read(run / "metrics.json")
    assert metrics.completed is True
    kinds = (*RADIO_KINDS, "radio_changed")
    ours = [(e.t, e.kind, e.text) for e in metrics.events if e.kind in kinds]
    assert ours == [(e.t, e.kind, e.text) for e in ref.metrics.events if e.kind in kinds]
    # two at 4.0 s, two within tick 201 (4.02 s), one on the last tick; not the one past the end
    assert [t for t, k, _ in ours if k == "radio_changed"] == pytest.approx([1.5, 4.0, 4.0, 4.02, 4.02, 5.0])
    radio, expected = metrics.radio, ref.metrics.radio
    assert (radio.utilisation, radio.splits) == (expected.utilisation, expected.splits)
    assert not fleet_processes(fleet)


def test_realtime_under_hostile_radio_traffic_keeps_running_and_counts(tmp_path, launches):
    """An open realtime lake_radio fleet for 4 s while a raw client publishes, every 50 ms, the
    geometry samples every vehicle refuses, the radio changes they refuse on ctl, the radio
    commands the world refuses, and random bytes on one vehicle's radio key: the run completes
    with every vehicle live, no process fails, the vehicles count the radio rejects by reason
    (the world's inbox is rate-limited at the router in realtime: it counts some)."""
    import random
    import threading

    import zenoh

    from cdus.wire import keys
    from cdus.wire.transport import free_tcp_port
    from tests.outsider import raw_client

    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    duration = 4.0
    la = launches(["configs/lake_radio.toml", "--clock", "realtime", "--duration", str(duration),
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "--insecure", "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    sc = load_scenario("configs/lake_radio.toml", {"scenario.duration": duration})
    geometry, ctl, commands = _hostile_geometry(sc), _hostile_radio_ctl(sc), _hostile_radio_commands()
    mallory = zenoh.open(raw_client(f"tcp/127.0.0.1:{port}"))
    done = threading.Event()
    rng = random.Random(1)

    def attack():
        while not done.is_set():
            for payload in geometry:
                mallory.put(keys.radio(fleet, sc.ids), payload)
            for payload in ctl:
                mallory.put(keys.ctl(fleet, sc.ids), payload)
            for payload in commands:
                mallory.put(keys.world_cmd(fleet, keys.GROUND), payload)
            mallory.put(keys.radio(fleet, [rng.choice(sc.ids)]), rng.randbytes(rng.randint(0, 300)))
            done.wait(0.05)

    worker = threading.Thread(target=attack, daemon=True)
    worker.start()
    try:
        assert la.wait(timeout=120) == 0, la.output()
    finally:
        done.set()
        worker.join(timeout=10)
        mallory.close()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True, m.completion
    assert sorted(m.live_final) == sorted(sc.ids) and not any(e.kind == "vehicle_lost" for e in m.events)
    vehicles = m.rejected_by_reason.vehicles
    for reason in ("radio_malformed", "radio_version", "radio_non_finite", "radio_count", "radio_dimension",
                   "radio_oversized", "radio_range", "radio_command_range", "bad_radio_command"):
        assert vehicles.get(reason, 0) >= len(sc.ids), (reason, vehicles)
    assert sum(m.rejected_by_reason.world.values()) > 0
    assert m.radio.sent > 0 and 0 < m.radio.utilisation.samples <= int(duration / 0.2) + 1
    for log in (run / "logs").glob("*.log"):
        assert "Traceback" not in log.read_text(), log
    assert not fleet_processes(fleet)

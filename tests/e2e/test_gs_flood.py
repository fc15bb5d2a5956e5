"""End to end: a flood of valid commands from the ground credentials does not stall a lockstep
fleet or change its result (docs/ground_station.md, "A flood"). 18,144 `gains c=2` held a
lockstep lake_circle to 35 simulated s in 240 s, left 3.5 MB of events in metrics.json and a
500 KB settings reply. Here 600 no-op gains (the configured c, every vehicle), 32 waiting at a
time, against a secured lockstep concentric_circles: what the code guarantees is asserted, not
how fast the machine is: the ground credentials' rate (each refusal says so and is counted),
one settings entry per tick, the events bounded, the run completed and equal to `cdus sim`."""

from __future__ import annotations

import threading
import time

import zenoh

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.wire.messages import encode_control
from cdus.wire.schemas import decode_reply
from cdus.wire.transport import Transport, free_tcp_port
from cdus.wire.rejected import Rejected
from ground_station.console import GroundStation
from world_sim.world import (
    CHANGE_EVENTS_BURST, CHANGE_EVENTS_PER_S, COMMANDS_BURST, COMMANDS_PER_S, RATE_REFUSAL,
)

from .conftest import WorldTime, assert_same_trace, fleet_processes, unique_fleet

CONFIG = "configs/concentric_circles.toml"
DURATION = 40.0
FLOOD = 600
IN_FLIGHT = 32


def flood(session, fleet: str, payload: bytes) -> tuple[list, float]:
    """FLOOD command queries, at most IN_FLIGHT waiting for their answer: (the answers, the wall
    seconds from the first query to the last answer)."""
    answers: list = []
    lock = threading.Lock()
    slots = threading.Semaphore(IN_FLIGHT)

    def on_reply(r) -> None:
        with lock:
            answers.append(decode_reply(r.ok.payload.to_bytes()) if r.ok is not None else r.err.payload.to_bytes())

    t0 = time.monotonic()
    for _ in range(FLOOD):
        assert slots.acquire(timeout=30), "a command query was never answered"
        session.get(keys.world_command(fleet, keys.GROUND), zenoh.handlers.Callback(on_reply, slots.release),
                    payload=payload, timeout=20.0)
    for _ in range(IN_FLIGHT):
        assert slots.acquire(timeout=30)
    return answers, time.monotonic() - t0


def command(gs: GroundStation, op: str, busy: list):
    """A command asked again while the ground credentials' rate refuses it (the flood spent it);
    each refusal is added to ``busy``."""
    for _ in range(100):
        a = gs.command(op, timeout=20.0)
        assert a.reply is not None, a.detail
        if a.reply.reason == RATE_REFUSAL:
            busy.append(a.reply)
        else:
            return a.reply
        time.sleep(0.05)
    raise AssertionError(f"{op} was refused busy for 5 s")


def test_a_flood_of_valid_commands_is_bounded_answered_and_changes_nothing(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    sc = load_scenario(CONFIG, {"scenario.duration": DURATION})
    assert {v.c for v in sc.vehicles} == {2.0}  # gains c=2.0 changes nothing
    la = launches([CONFIG, "--clock", "lockstep", "--duration", str(DURATION), "--listen", f"tcp/127.0.0.1:{port}",
                   "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"), "-q", "--rerun", "off"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    gs = GroundStation(fleet, Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",),
                                        config_file=str(run / "secure" / "ground.json5")), name="flood")
    gs.open()
    try:
        assert gs.wait_for_status(10)
        WorldTime(gs.session, fleet).wait_past(1.0)
        answers, wall = flood(gs.session, fleet, encode_control("set_gains", gains={"c": 2.0}, vehicle="",
                                                                name="flood"))
        assert len(answers) == FLOOD and all(not isinstance(a, (Rejected, bytes)) for a in answers), answers[:3]
        applied = [a for a in answers if a.applied]
        busy = [a for a in answers if a.reason == RATE_REFUSAL]
        ending = [a for a in answers if not a.applied and ("ending" in a.reason or "over" in a.reason)]
        assert len(applied) + len(busy) + len(ending) == FLOOD, {a.reason for a in answers}
        # the token bucket: at most its burst and its rate over the time the flood took passed
        passed = len(applied) + len(ending)
        assert 1 <= passed <= COMMANDS_BURST + COMMANDS_PER_S * wall + 1, (passed, wall)
        assert len(busy) >= FLOOD - (COMMANDS_BURST + COMMANDS_PER_S * wall + 1)
        # the settings: one gains entry per tick (a flood within a grant is one change), asked with
        # the fleet paused, so that the run cannot end first (a pause changes nothing in lockstep)
        paused = command(gs, "pause", busy)
        if paused.applied:
            settings = None
            for _ in range(50):  # a query past its own quota is an error reply: asked again
                settings = gs.fetch_settings(timeout=5.0)
                if settings is not None:
                    break
                time.sleep(0.1)
            assert settings is not None
            ticks = [c["fields"]["tick"] for c in settings["changes"] if c["op"] == "gains"]
            assert ticks and len(ticks) == len(set(ticks)) and settings["total"] <= len(applied), settings
            # a lockstep pause holds back new grants only: the world widens its window with the
            # fleet's speed, so a pause late in the run can find every tick granted already and the
            # run ends while paused (docs/ground_station.md, the effect tick of `pause`)
            resumed = command(gs, "resume", busy)
            assert resumed.applied or resumed.reason == "the run is over", resumed
        else:  # a machine fast enough to end the run during the flood: nothing left to ask
            assert "ending" in paused.reason or "over" in paused.reason, paused
    finally:
        gs.close()
    assert la.wait(timeout=300) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True
    assert m.rejected_by_reason.world.get("rate", 0) == len(busy), m.rejected_by_reason
    changed = [e for e in m.events if e.kind == "gains_changed"]
    assert 1 <= len(changed) <= CHANGE_EVENTS_BURST + CHANGE_EVENTS_PER_S * m.wall_s + 1, len(changed)
    # no-op gains: the run is the one without the flood, to the bit
    assert_same_trace(tmp_path / "trace.npz", InProcessFleet(sc).run())
    assert not fleet_processes(fleet)

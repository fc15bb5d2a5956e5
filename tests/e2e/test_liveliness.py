"""End to end: the liveliness attacks of issue 27 against a launched lockstep fleet.

A token declared on the fleet's ``alive/**`` for a second matched every agent's watch of the
world's token: every agent took the world for back from an outage and said its recent
messages again for 10 s (370-382 k stale rejects against 0), and a run could lose a vehicle
and still say completed. A forged ``alive/usv2`` held while usv2 was killed hid its loss.
Now each process's token is ``alive/<name>/<zid>`` and watchers take only keys of exactly
that shape (docs/security.md, "Liveliness"). Open fleets see the forgeries and say so in
the metrics (``integrity``); a secured fleet's router refuses them (the ACL).
"""

from __future__ import annotations

import os
import signal
import time

import pytest

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import Integrity, Metrics
from cdus.wire import keys
from cdus.wire.messages import encode_control
from cdus.wire.transport import Transport, free_tcp_port, open_session
from vehicle_agent.agent import WORLD_BACK

from .conftest import assert_same_trace, fleet_processes, unique_fleet
from .test_access import Events, member

DURATION = 10.0  # s of simulated time: the attacks happen while the fleet is paused


def _launch(tmp_path, launches, secured: bool, *extra: str):
    fleet, port, run = unique_fleet(), free_tcp_port(), tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", str(DURATION),
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "--trace-out", str(tmp_path / "trace.npz"),
                   "--secure" if secured else "--insecure", "-q", *extra], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    session = (member(run / "secure" / "ground.json5") if secured
               else open_session(Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",))))
    return fleet, run, la, session


def _pause(session, fleet: str, events: Events, pause: bool) -> None:
    session.put(keys.world_cmd(fleet, keys.GROUND), encode_control("pause" if pause else "resume"))
    events.wait_for("fleet", "paused" if pause else "resumed")


@pytest.mark.parametrize("secured", [False, True], ids=["open", "secured"])
def test_a_wildcard_or_forged_token_for_a_second_changes_nothing_and_an_open_fleet_says_it_saw_it(
        tmp_path, launches, secured):
    fleet, run, la, session = _launch(tmp_path, launches, secured)
    try:
        events = Events(session, fleet)
        _pause(session, fleet, events, True)  # so that the tokens come and go mid-run
        zid = str(session.zid())
        forged = [f"cdus/{fleet}/alive/**", f"cdus/{fleet}/alive/usv2", keys.alive(fleet, "usv2", zid),
                  keys.alive(fleet, keys.WORLD, zid)]
        tokens = [session.liveliness().declare_token(k) for k in forged]
        if not secured:  # the world tells of the first it sees; a secured fleet's router lets none through
            events.wait_for("suspect", "no process's key")
        time.sleep(1.0)  # held for a second, as in the attack
        for t in tokens:
            t.undeclare()
        _pause(session, fleet, events, False)
        code = la.wait(timeout=120)
    finally:
        session.close()
    assert code == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True, m.completion
    assert_same_trace(tmp_path / "trace.npz",
                      InProcessFleet(load_scenario("configs/lake_circle.toml", {"scenario.duration": DURATION})).run())
    logs = {p.name: p.read_text(errors="replace") for p in (run / "logs").glob("*.log")}
    assert not [name for name, text in logs.items() if WORLD_BACK in text], "an agent took a token for the world back"
    assert m.rejected_by_reason.vehicles.get("stale", 0) == 0, m.rejected_by_reason
    integrity = m.integrity
    if secured:
        assert integrity == Integrity(tampered=False, reasons={}, notes=())
    else:
        assert integrity.tampered is True
        # the wildcard (the bare alive/usv2 intersects no watch of alive/*/*), usv2's and the world's copies
        assert integrity.reasons["token_key"] == 1 and integrity.reasons["token_extra"] == 2, integrity
        assert integrity.reasons["vehicle_token_key"] >= 6, integrity  # every agent saw the wildcard
        assert "TAMPERED" in la.output()
    assert not fleet_processes(fleet)


def test_a_forged_token_held_while_a_vehicle_is_killed_does_not_hide_its_loss(tmp_path, launches):
    fleet, run, la, session = _launch(tmp_path, launches, False)
    try:
        events = Events(session, fleet)
        _pause(session, fleet, events, True)
        tokens = [session.liveliness().declare_token(k)  # the key before session ids, and a key of its own
                  for k in (f"cdus/{fleet}/alive/usv2", keys.alive(fleet, "usv2", str(session.zid())))]
        events.wait_for("suspect", "second liveliness token of usv2")
        [pid] = [int(ln.split()[0]) for ln in fleet_processes(fleet) if "--id usv2" in ln]
        os.kill(pid, signal.SIGKILL)
        lost = events.wait_for("vehicle_lost", "usv2", timeout=30)  # while the forged tokens are held
        _pause(session, fleet, events, False)
        code = la.wait(timeout=120)
        assert tokens  # held to the end
    finally:
        session.close()
    m = Metrics.read(run / "metrics.json")
    assert lost.vehicle == "usv2" and "usv2" not in m.live_final, m.live_final
    assert (m.completed, m.completion) == (False, "vehicles_lost"), (code, la.output())
    assert m.integrity.tampered is True and m.integrity.reasons["token_extra"] >= 1, m.integrity
    assert not fleet_processes(fleet)

"""End to end, issue 27 "Broken 1": on a secured lockstep fleet, `cdus gs ... link delay.base=1e308`
was answered "applied from tick 1851" and all six agents died (OverflowError in
cdus.core.schedule.needed_seq). Every number has one bound now (cdus/wire/bounds.py): the ground
station refuses it before sending, a client past the command line is refused by the world by
name, and the run goes to its end with every vehicle live."""

from __future__ import annotations


from cdus.sim.runmetrics import Metrics
from cdus.wire import keys
from cdus.wire.messages import encode_control
from cdus.wire.transport import Transport, free_tcp_port
from ground_station.console import GroundStation

from .conftest import run_cli, unique_fleet
from .test_access import Events, gs_command, member


def test_a_link_delay_of_1e308_is_refused_and_every_vehicle_flies_to_the_end(tmp_path, launches):
    fleet, port, run = unique_fleet(), free_tcp_port(), tmp_path / "run"
    la = launches(["configs/lake_circle.toml", "--clock", "lockstep", "--duration", "20", "--secure",
                   "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "--rerun", "off", "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")
    gs = gs_command(la.wait_for("attach a ground station"))
    secure = run / "secure"
    ground = member(secure / "ground.json5")
    command = keys.world_cmd(fleet, keys.GROUND)
    try:
        events = Events(ground, fleet)
        ground.put(command, encode_control("pause"))  # held, so all of the below happens mid-run
        events.wait_for("fleet", "paused")

        # the ground station's command line: refused before anything is sent, naming the field
        res = run_cli([*gs, "link", "delay.base=1e308"], timeout=60)
        # named as typed on the `link` command line (cdus/commands: a refused argument names its own field)
        assert res.returncode == 2 and "delay.base: must be a number >= 0 and <= 3600" in res.stderr, res
        assert "1e+308" in res.stderr and "Traceback" not in res.stderr

        # a client of its own with the ground credentials, past that check: the world refuses it, with
        # the same words (one parse: cdus.commands)
        station = GroundStation(fleet, Transport(mode="client", config_file=str(secure / "ground.json5")),
                                name="attacker")
        station.open()
        try:
            assert station.wait_for_status(10)
            a = station.command("link", link={"delay": {"base": 1e308}}, at=-1.0)
            assert (a.outcome, a.code) == ("rejected", 1) and a.reply.reason.startswith("delay.base: must be a number >= 0 and <= 3600"), a
            assert "3600" in a.reply.reason
        finally:
            station.close()
        assert la.proc.poll() is None, "the run ended before the attack was done: the test proves nothing"
        ground.put(command, encode_control("resume"))
        events.wait_for("fleet", "resumed")
    finally:
        ground.close()

    assert la.wait(timeout=300) == 0, la.output()
    m = Metrics.read(run / "metrics.json")
    assert m.completed is True and m.duration_s >= 19.9, m
    kinds = [e.kind for e in m.events]
    assert "link_changed" not in kinds and "vehicle_lost" not in kinds and "gave_up" not in kinds, m.events
    assert "rejected" in kinds, m.events  # the world's log says it refused one
    for vid in ("usv1", "usv2", "usv3", "uav1", "uav2", "uav3"):
        log = (run / "logs" / f"{vid}.log").read_text()
        assert "Traceback" not in log and "OverflowError" not in log and "link faults changed" not in log, vid

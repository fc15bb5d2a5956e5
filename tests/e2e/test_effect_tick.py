"""End to end, realtime: a ground station's gains change and formation change each apply on one
and the same tick at every vehicle (docs/ground_station.md, "When a command takes effect").

Each vehicle's log says the tick it applies a change from, and whether it heard the change too
late for that tick (then it applies it from the next tick it steps). Realtime gains applied from
the wall clock's next tick: a vehicle that had stepped it already applied them later than the
others. The world now gives every change one effect tick, 0.5 s ahead of its clock."""

from __future__ import annotations

import json
import re
import time

from cdus.wire.transport import free_tcp_port

from .conftest import fleet_processes, run_cli, unique_fleet

RATE = 500.0  # Hz: a tick of 2 ms, shorter than a command takes to reach every vehicle
VEHICLES = ("usv1", "usv2", "uav1", "uav2")


def test_realtime_gains_and_formation_apply_on_one_tick_at_every_vehicle(tmp_path, launches):
    fleet = unique_fleet()
    port = free_tcp_port()
    run = tmp_path / "run"
    la = launches(["configs/concentric_circles.toml", "--clock", "realtime", "--duration", "600",
                   "--set", f"rates.control={RATE}", "--set", f"rates.physics={RATE}", "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run), "-q"], fleet)
    la.wait_for(f"fleet '{fleet}' up")

    def gs(*args: str):
        res = run_cli(["gs", "--fleet", fleet, "-e", f"tcp/127.0.0.1:{port}",
                       "--zenoh-config", str(run / "secure" / "ground.json5"), *args], timeout=60)
        assert res.returncode == 0, (args, res.stdout, res.stderr)
        return int(re.search(r"applied from tick (\d+)", res.stdout)[1])

    gains_tick = gs("gains", "c=2.5")
    formation_tick = gs("formation", "phases.usv2=1.0")
    # a stop applies at the present tick, the formation 0.5 s ahead: stop once the fleet is past it
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        res = run_cli(["gs", "--fleet", fleet, "-e", f"tcp/127.0.0.1:{port}", "--zenoh-config",
                       str(run / "secure" / "ground.json5"), "status", "--json"], timeout=60)
        if res.returncode == 0 and json.loads(res.stdout)["t"] * RATE > formation_tick + 1:
            break
        time.sleep(0.1)
    assert gs("stop") > formation_tick
    assert la.wait(timeout=60) == 0, la.output()

    for what, tick in (("gains k = ", gains_tick), ("formation phases ", formation_tick)):
        for vid in VEHICLES:
            log = (run / "logs" / f"{vid}.log").read_text()
            said = [ln for ln in log.splitlines() if what in ln]
            assert len(said) == 1, (vid, said)
            # the tick the world answered, and not heard too late for it: applied on that tick
            assert said[0].endswith(f" from tick {tick}"), (vid, said[0])
    assert not fleet_processes(fleet)

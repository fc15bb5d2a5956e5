"""The run's integrity in the summary and in the launcher's own metrics (docs/metrics.md,
``integrity``): a run something may have altered says so beside ``completed``."""

from __future__ import annotations

from dataclasses import replace

import zenoh

from cdus.app.launcher import LaunchOptions, Launcher
from cdus.app.report import summary_table
from cdus.results import Integrity
from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.wire import keys
from cdus.wire.transport import Transport

SC = load_scenario("configs/lake_circle.toml", {"scenario.duration": 0.2})


def test_the_summary_says_tampered_with_the_reasons_and_escapes_what_came_from_the_wire():
    m = InProcessFleet(SC).run().metrics
    assert m.integrity == Integrity(tampered=False, reasons={}, notes=())
    assert "TAMPERED" not in summary_table(m, SC.vehicles)
    m = replace(m, integrity=Integrity(tampered=True, reasons={"token_key": 1, "vehicle_token_key": 6},
                                       notes=("a liveliness token on cdus/f/alive/**, no process's key: ignored",
                                              "\x1b[2J")))
    line = next(ln for ln in summary_table(m, SC.vehicles).splitlines() if "TAMPERED" in ln)
    assert "token_key 1, vehicle_token_key 6" in line and "alive/**" in line and "\x1b" not in line


class Token:
    def __init__(self, key: str, up: bool = True):
        self.key_expr = key
        self.kind = zenoh.SampleKind.PUT if up else zenoh.SampleKind.DELETE


def test_the_launcher_counts_tokens_that_are_nobodys_and_a_vehicle_is_up_while_one_of_its_tokens_is(tmp_path):
    la = Launcher(SC, tmp_path / "run", Transport(mode="router", listen=("tcp/127.0.0.1:0",)),
                  LaunchOptions(fleet="f", quiet=True))
    la._on_alive(Token("cdus/f/alive/**"))
    la._on_alive(Token(keys.alive("f", "usv2", "a1")))
    la._on_alive(Token(keys.alive("f", "usv2", "f0")))
    la._on_alive(Token(keys.alive("f", "usv2", "f0"), up=False))
    assert la.alive == {"usv2"}
    la._on_alive(Token(keys.alive("f", "usv2", "a1"), up=False))
    assert la.alive == set() and la.ever_alive == {"usv2"}
    m = la.write_world_lost(-9, 1.0)
    assert m.integrity.tampered is True and m.integrity.reasons == {"token_key": 1}

"""Where a runner's picture of the fleet goes: the sink interface the fleet runners feed.

The in-process fleet and the world process call a sink as they record:
``start(scenario)`` once, ``update(recorder)`` every ``UPDATE_EVERY`` ticks with the
Recorder (the sink logs whatever rows are new since its last call, batched),
``event(e)`` for things a person should read (a :class:`FleetEvent`), ``link_state(t, src, dst, state)``
for link changes, optionally ``radio(t, watch)`` at each radio geometry sample
(cdus.sim.radio.RadioWatch: link delivery probabilities, the station, utilisation), and ``close()`` at the end, also after Ctrl-C, so a recording is
always complete. The Rerun sink lives in the world process (:mod:`world_sim.rerun_sink`).
"""

from __future__ import annotations

from typing import Protocol

from cdus.core.metrics import Recorder
from cdus.scenario.model import Scenario
from cdus.wire.schemas import FleetEvent

UPDATE_EVERY = 25  # ticks between sink updates (0.5 s of simulated time at 50 Hz)


class Sink(Protocol):
    def start(self, scenario: Scenario) -> None: ...
    def update(self, recorder: Recorder) -> None: ...
    def event(self, event: FleetEvent) -> None: ...
    def link_state(self, t: float, src: str, dst: str, state: str) -> None: ...
    def close(self) -> None: ...


class NullSink:
    """Logs nothing (``--rerun off``)."""

    def start(self, scenario: Scenario) -> None:
        pass

    def update(self, recorder: Recorder) -> None:
        pass

    def event(self, event: FleetEvent) -> None:
        pass

    def link_state(self, t: float, src: str, dst: str, state: str) -> None:
        pass

    def close(self) -> None:
        pass

"""Where a runner's picture of the fleet goes: the sink interface the fleet runners feed.

The in-process fleet and the world process call a sink as they record:
``start(scenario)`` once, ``update(recorder)`` every ``UPDATE_EVERY`` ticks with the
Recorder (the sink logs whatever rows are new since its last call, batched),
``event(e)`` for things a person should read (a :class:`FleetEvent`), ``link_state(t, src, dst, state)``
for link changes, ``radio(t, watch)`` at each radio geometry sample (cdus.sim.radio.RadioWatch:
link delivery probabilities, the station, utilisation), and ``close()`` at the end, also after
Ctrl-C, so a recording is always complete. A sink that writes a file says through ``on_stop``
(a callback the world sets, with the reason) that it stopped writing while the run goes on.
Every sink has all of these (:class:`NullSink`'s do nothing): a runner calls them without
asking whether they are there. The Rerun sink lives in the world process
(:mod:`world_sim.rerun_sink`).
"""

from __future__ import annotations

from typing import Any, Callable, Protocol

from cdus.core.metrics import Recorder
from cdus.scenario.model import Scenario
from cdus.wire.schemas import FleetEvent

UPDATE_EVERY = 25  # ticks between sink updates (0.5 s of simulated time at 50 Hz)


class Sink(Protocol):
    on_stop: Callable[[str], None] | None  # set by the world: the sink stopped writing (the reason)

    def start(self, scenario: Scenario) -> None: ...
    def update(self, recorder: Recorder) -> None: ...
    def event(self, event: FleetEvent) -> None: ...
    def link_state(self, t: float, src: str, dst: str, state: str) -> None: ...
    def radio(self, t: float, watch: Any) -> None: ...
    def close(self) -> None: ...


class NullSink:
    """Logs nothing (``--rerun off``)."""

    on_stop: Callable[[str], None] | None = None  # it never stops: nothing to say

    def start(self, scenario: Scenario) -> None:
        pass

    def update(self, recorder: Recorder) -> None:
        pass

    def event(self, event: FleetEvent) -> None:
        pass

    def link_state(self, t: float, src: str, dst: str, state: str) -> None:
        pass

    def radio(self, t: float, watch: Any) -> None:
        pass

    def close(self) -> None:
        pass

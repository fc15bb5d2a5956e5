"""What is a scheduled vehicle fault? An action on one vehicle at a simulated time.

The scenario's ``[[event]]`` tables (docs/config.md) are validated into these by the
scenario layer; the runners carry them out in order of ``at``:

- kill: the vehicle's process dies (SIGKILL); its neighbours drop it from their sums
  when its liveliness token goes; the world reports whether the graph still has a
  spanning tree.
- pause: the process is frozen (SIGSTOP): it neither steps nor sends, but it is not
  gone until the liveliness lease runs out (1 s under the launcher).
- resume: SIGCONT.
- restart: a new process for the vehicle, which rejoins where the world last saw it,
  with ω at the nearest point of its path (continuing its old ω, not a lap away).

The launcher carries them out against the world's simulated time; the in-process fleet
emulates the same effects, so a sweep can use them too.
"""

from __future__ import annotations

from dataclasses import dataclass

ACTIONS = ("kill", "pause", "resume", "restart")


@dataclass(frozen=True)
class Event:
    at: float  # simulated seconds
    action: str  # one of ACTIONS
    vehicle: str  # a vehicle id

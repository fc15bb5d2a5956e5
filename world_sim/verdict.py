"""What did the world make of one command: applied from a tick, rejected with a reason, or
decided later?"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Verdict:
    """What the world made of one command: applied from ``tick`` (``t`` s of simulated time; a
    link change's exact time), or rejected with a reason (nothing changed). A command handler
    returns a Verdict, a reason string (rejected), None (applied from the next tick nobody has
    stepped) or LATER (a lockstep vehicle fault: Lockstep decides it, a Decided action answers)."""

    applied: bool
    reason: str = ""
    tick: int | None = None
    t: float | None = None

    @staticmethod
    def no(reason: str) -> "Verdict":
        return Verdict(False, reason)


LATER = Verdict(True, "decided when its tick comes")  # a sentinel: never sent as it is

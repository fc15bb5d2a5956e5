"""How many may pass now? A token bucket: ``rate`` a second on average, ``burst`` at once.

The processes bound what a flood can make them do with it (docs/ground_station.md, "A flood";
docs/security.md, "Floods"): the world takes at most so many commands a second from the
ground credentials and answers at most so many queries a second on its status and settings
keys, and logs at most so many refused or applied commands as events; what does not pass is
refused (said so, and counted), never queued. The caller gives the time (a monotonic clock of
its own), so the decision is a pure function of what came before.
"""

from __future__ import annotations


class Quota:
    """A token bucket. ``take(now)``: True if one more may pass at ``now`` (seconds of any
    monotonic clock), and counts the ones refused since the last that passed (``held``)."""

    __slots__ = ("rate", "burst", "tokens", "at", "held")

    def __init__(self, rate: float, burst: int, now: float = 0.0):
        if not rate > 0 or burst < 1:
            raise ValueError(f"a quota needs rate > 0 and burst >= 1, got rate = {rate}, burst = {burst}")
        self.rate = float(rate)
        self.burst = int(burst)
        self.tokens = float(burst)
        self.at = now
        self.held = 0  # refused since the last one that passed

    def take(self, now: float) -> bool:
        self.tokens = min(float(self.burst), self.tokens + max(0.0, now - self.at) * self.rate)
        self.at = max(self.at, now)
        if self.tokens < 1.0:
            self.held += 1
            return False
        self.tokens -= 1.0
        return True

    def passed(self) -> int:
        """After a ``take`` that passed: how many were refused before it (since the one before);
        the count starts again."""
        held, self.held = self.held, 0
        return held

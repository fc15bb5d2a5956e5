"""What does the link do to a message? Per directed link src -> dst, decided at the receiver.

A link model is a pure decision: ``decide(src, dst, seq, t_send) -> delays`` gives the
delays (seconds) after which copies of the message become usable at ``dst``; an empty
tuple is a drop, two entries a duplicate. It depends on its arguments (and the model's
own seeded state per link) only, never on arrival order, so an in-process run and a
lockstep multi-process run make the same decisions.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol


class LinkModel(Protocol):
    def decide(self, src: int, dst: int, seq: int, t_send: float) -> tuple[float, ...]:
        ...


class IdealLink:
    """Every message arrives, at once."""

    def decide(self, src: int, dst: int, seq: int, t_send: float) -> tuple[float, ...]:
        return (0.0,)


@dataclass
class LinkCounters:
    """Counts of one directed link, or of the whole fleet."""

    sent: int = 0
    delivered: int = 0
    dropped: int = 0
    duplicated: int = 0
    rejected: int = 0
    latencies: list[float] = field(default_factory=list, repr=False)

    MAX_SAMPLES = 100_000

    def record_latency(self, seconds: float) -> None:
        """Keep a bounded, evenly thinned sample of latencies for the percentiles."""
        self._seen = getattr(self, "_seen", 0) + 1
        stride = getattr(self, "_stride", 1)
        if self._seen % stride:
            return
        self.latencies.append(seconds)
        if len(self.latencies) >= self.MAX_SAMPLES:
            self.latencies = self.latencies[::2]
            self._stride = stride * 2

    def add(self, other: "LinkCounters") -> None:
        self.sent += other.sent
        self.delivered += other.delivered
        self.dropped += other.dropped
        self.duplicated += other.duplicated
        self.rejected += other.rejected
        self.latencies.extend(other.latencies)

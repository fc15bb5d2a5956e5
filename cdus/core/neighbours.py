"""What does a vehicle know of its neighbours? The last ω each one sent, and how to use it.

A receiver keeps, per neighbour, the newest accepted message (older sequence numbers
are rejected as stale or duplicates) and turns the table into the consensus term of the
guidance with a stale-neighbour policy (docs/link.md):

- ``hold``: use the last value as it is;
- ``timeout``: like hold, but a neighbour silent for longer than ``timeout`` s drops out of
  the sum (the public Paparazzi relative uses 1.5 s);
- ``extrapolate``: ω_k + ω̇_k (t - t_send), which removes most of the τ·|ω̇| bias a
  delay τ causes (docs/control.md §6).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cdus.core.guidance import Consensus
from cdus.core.linkspec import POLICIES
from cdus.wire.messages import OmegaMsg



@dataclass(frozen=True)
class NeighbourLink:
    """One term of vehicle i's sum: neighbour k (by index), weight a_ik, offset Δ_ik."""

    k: int
    weight: float
    delta: float


def consensus_target(links: tuple[NeighbourLink, ...], omegas: dict[int, float]) -> float | None:
    """The ω the consensus term pulls towards, Σ a_ik (ω_k + Δ_ik) / Σ a_ik, over the
    neighbours whose ω is known; None if none is. A vehicle rejoining a run starts from the
    point of its path nearest to its position within half a lap of this value, so it does
    not have to make up laps of unwrapped ω."""
    num = den = 0.0
    for ln in links:
        if ln.k in omegas:
            num += ln.weight * (omegas[ln.k] + ln.delta)
            den += ln.weight
    return num / den if den > 0 else None


@dataclass
class NeighbourTable:
    links: tuple[NeighbourLink, ...]
    policy: str = "hold"
    timeout: float = 1.5
    latest: dict[int, OmegaMsg] = field(default_factory=dict)
    received_at: dict[int, float] = field(default_factory=dict)
    rejected_stale: int = 0

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise ValueError(f"unknown stale-neighbour policy {self.policy!r}; choose one of {', '.join(POLICIES)}")
        self._known = {ln.k for ln in self.links}

    def accepts(self, sender: int) -> bool:
        return sender in self._known

    def offer(self, msg: OmegaMsg, now: float) -> bool:
        """Store ``msg`` if it is newer than what we hold. Returns whether it was taken."""
        prev = self.latest.get(msg.sender)
        if prev is not None and msg.seq <= prev.seq:
            self.rejected_stale += 1
            return False
        self.latest[msg.sender] = msg
        self.received_at[msg.sender] = now
        return True

    def forget(self, k: int) -> None:
        """Neighbour k is gone: leave it out of the sum until it sends again. (Whether what it
        sends is taken is the tick protocol's business, cdus.core.node.)"""
        self.latest.pop(k, None)
        self.received_at.pop(k, None)

    def consensus(self, t: float) -> Consensus:
        """The coupling term for a control period starting at time ``t``."""
        terms = []
        for ln in self.links:
            m = self.latest.get(ln.k)
            if m is None:
                continue
            if self.policy == "timeout" and t - self.received_at[ln.k] > self.timeout:
                continue
            if self.policy == "extrapolate":
                terms.append((ln.weight, m.omega + m.omega_rate * (t - m.t_send), m.omega_rate, ln.delta))
            else:
                terms.append((ln.weight, m.omega, 0.0, ln.delta))
        return Consensus.from_terms(terms)

    def ages(self, t: float) -> dict[int, float]:
        return {k: t - m.t_send for k, m in self.latest.items()}

"""What does a vehicle know of its neighbours? The last ω each one sent, and how to use it.

A receiver keeps, per neighbour, the newest accepted message (older sequence numbers
are rejected as stale or duplicates) and turns the table into the consensus term of the
guidance with a stale-neighbour policy (``hold``, ``timeout``, ``extrapolate``: the objects
of cdus.core.policies; docs/link.md).
"""

from __future__ import annotations

from dataclasses import dataclass

from cdus.core.guidance import Consensus
from cdus.core.linkspec import POLICIES  # noqa: F401 (re-exported: the policies' names)
from cdus.core.policies import StalePolicy, make_policy
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


class NeighbourTable:
    """The newest message of each neighbour and the stale-neighbour policy that turns them into
    the consensus term. ``policy`` and ``timeout`` are the scenario's names; setting either
    builds the policy object (cdus.core.policies) the sum uses, refusing an unknown name."""

    def __init__(self, links: tuple[NeighbourLink, ...], policy: str = "hold", timeout: float = 1.5):
        self.links = links
        self.latest: dict[int, OmegaMsg] = {}
        self.received_at: dict[int, float] = {}
        self.rejected_stale = 0
        self._timeout = timeout
        self._stale: StalePolicy = make_policy(policy, timeout)
        self._known = {ln.k for ln in self.links}

    def set_policy(self, name: str, timeout: float) -> None:
        """Use the policy ``name`` with ``timeout`` (s) from now on."""
        self._stale = make_policy(name, timeout)
        self._timeout = timeout

    @property
    def policy(self) -> str:
        return self._stale.name

    @policy.setter
    def policy(self, name: str) -> None:
        self._stale = make_policy(name, self._timeout)

    @property
    def timeout(self) -> float:
        return self._timeout

    @timeout.setter
    def timeout(self, seconds: float) -> None:
        self._timeout = seconds
        self._stale = make_policy(self._stale.name, seconds)

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
        return Consensus.from_terms(self._stale.terms(self.links, self.latest, self.received_at, t))

    def ages(self, t: float) -> dict[int, float]:
        return {k: t - m.t_send for k, m in self.latest.items()}

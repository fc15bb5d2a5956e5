"""What does a vehicle do with a neighbour that has gone quiet? The stale-neighbour policies.

Each policy is an object (:class:`StalePolicy`) that turns a receiver's neighbour table into
the consensus terms of the guidance (cdus.core.neighbours; docs/link.md):

- ``hold``: use the last value as it is;
- ``timeout``: like hold, but a neighbour silent for longer than ``timeout`` s drops out of
  the sum (the public Paparazzi relative uses 1.5 s);
- ``extrapolate``: ω_k + ω̇_k (t - t_send), which removes most of the τ·|ω̇| bias a
  delay τ causes (docs/control.md §6).

:data:`POLICIES` maps the scenario's ``link.policy`` name to its builder (declared once:
cdus.core.linkspec's vocabulary is its keys); :func:`make_policy` refuses an unknown name
naming the field and the known names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Mapping, Protocol

from cdus.core.models import UnknownName

#: a consensus term: (a_ik, ω_k as used, ω̇_k as used, Δ_ik) (cdus.core.guidance.Consensus)
Term = tuple[float, float, float, float]


class StalePolicy(Protocol):
    """How the newest message of each neighbour enters the sum at time ``t``."""

    name: str

    def terms(self, links: tuple, latest: Mapping[int, Any], received_at: Mapping[int, float],
              t: float) -> list[Term]:
        """The terms of ``links`` (cdus.core.neighbours.NeighbourLink) whose neighbour's newest
        message (``latest``, taken at ``received_at``) is used at ``t``."""


def _newest(links: tuple, latest: Mapping[int, Any]):
    """(link, its neighbour's newest message) for the links whose neighbour has sent one."""
    for ln in links:
        m = latest.get(ln.k)
        if m is not None:
            yield ln, m


@dataclass(frozen=True)
class Hold:
    name: str = "hold"

    def terms(self, links, latest, received_at, t) -> list[Term]:
        return [(ln.weight, m.omega, 0.0, ln.delta) for ln, m in _newest(links, latest)]


@dataclass(frozen=True)
class Timeout:
    timeout: float = 1.5
    name: str = "timeout"

    def terms(self, links, latest, received_at, t) -> list[Term]:
        return [(ln.weight, m.omega, 0.0, ln.delta) for ln, m in _newest(links, latest)
                if not t - received_at[ln.k] > self.timeout]


@dataclass(frozen=True)
class Extrapolate:
    name: str = "extrapolate"

    def terms(self, links, latest, received_at, t) -> list[Term]:
        return [(ln.weight, m.omega + m.omega_rate * (t - m.t_send), m.omega_rate, ln.delta)
                for ln, m in _newest(links, latest)]


#: policy name -> build(timeout s) (the first is the default)
POLICIES: dict[str, Callable[[float], StalePolicy]] = {
    "hold": lambda timeout: Hold(),
    "timeout": lambda timeout: Timeout(timeout),
    "extrapolate": lambda timeout: Extrapolate(),
}


def make_policy(name: Any, timeout: float = 1.5, field: str = "policy") -> StalePolicy:
    """The policy ``name`` (with its ``timeout``, s), or :class:`UnknownName` naming ``field``."""
    try:
        return POLICIES[name](timeout)
    except (KeyError, TypeError):
        raise UnknownName(field, name, tuple(POLICIES), "stale-neighbour policy") from None

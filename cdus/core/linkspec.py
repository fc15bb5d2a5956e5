"""What faults can a link have? The link fault spec: frozen dataclasses, no validation.

The one definition of a link fault spec (docs/link.md is its user reference). The
scenario layer (:mod:`cdus.scenario.link`) builds a :class:`LinkSpec` from a ``[link]``
table; the emulator in :mod:`cdus.core.link` turns a spec into decisions. Nothing here
is random, reads a clock or does I/O.

Modelled on ``tc netem`` (delay/jitter/distribution, loss, ``loss gemodel p r 1-h 1-k``,
duplicate), toxiproxy (per-link toxics) and Jepsen's partitions and "grudges".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from cdus.core.policies import POLICIES as _STALE_POLICIES


DISTRIBUTIONS = ("uniform", "normal", "pareto")
ANY = "*"

POLICIES = tuple(_STALE_POLICIES)  # the stale-neighbour policies' names (cdus.core.policies)
DEFAULT_POLICY = "hold"
DEFAULT_TIMEOUT = 1.5  # s, the public Paparazzi relative's (docs/control.md §6)


# --------------------------------------------------------------------------- the spec


@dataclass(frozen=True)
class Delay:
    """netem-like delay of one message, in seconds (see :func:`cdus.core.link.draw_delay`).

    uniform: base + U(-jitter, jitter); normal: base + jitter·N(0, 1); pareto: base + a
    Lomax(α = 3) tail of mean ``jitter`` (never below base). Negative draws are clipped to
    0. ``reorder = False``: per-link FIFO, a message is never usable before the previous one.
    """

    base: float = 0.0
    jitter: float = 0.0
    distribution: str = "uniform"
    reorder: bool = True

    @property
    def active(self) -> bool:
        return self.base > 0.0 or self.jitter > 0.0


@dataclass(frozen=True)
class Burst:
    """Gilbert-Elliott loss, netem's ``loss gemodel p r 1-h 1-k``: p = P(good -> bad),
    r = P(bad -> good), bad_loss = 1-h, good_loss = 1-k. One step per message."""

    p: float
    r: float
    bad_loss: float = 1.0
    good_loss: float = 0.0

    @property
    def active(self) -> bool:
        """Can it drop anything? (The chain starts good.)"""
        return self.good_loss > 0.0 or (self.p > 0.0 and self.bad_loss > 0.0)

    @property
    def stationary_loss(self) -> float:
        """π_bad·bad_loss + π_good·good_loss, π_bad = p / (p + r) (the start, good, if p + r = 0)."""
        if self.p + self.r == 0.0:
            return self.good_loss
        bad = self.p / (self.p + self.r)
        return bad * self.bad_loss + (1.0 - bad) * self.good_loss


@dataclass(frozen=True)
class Override:
    """Faults of the directed links ``src -> dst`` ("*" = any vehicle); a given key replaces
    what the table (or an earlier override) set; ``delay`` replaces only the keys it names."""

    src: str = ANY
    dst: str = ANY
    delay: tuple[tuple[str, Any], ...] = ()  # the keys given, e.g. (("jitter", 0.05),)
    loss: float | None = None
    burst: Burst | None = None
    duplicate: float | None = None

    def matches(self, src: str, dst: str) -> bool:
        return self.src in (ANY, src) and self.dst in (ANY, dst)


@dataclass(frozen=True)
class Down:
    """Links ``src -> dst`` ("*" = any) are down for t_send in [start, end)."""

    start: float
    end: float
    src: str = ANY
    dst: str = ANY

    def blocks(self, src: str, dst: str) -> bool:
        return self.src in (ANY, src) and self.dst in (ANY, dst)


@dataclass(frozen=True)
class Partition:
    """For t_send in [start, end): either ``groups`` (messages between groups are dropped;
    vehicles in no group form one more group) or ``drops`` (receiver -> senders it drops)."""

    start: float
    end: float
    groups: tuple[tuple[str, ...], ...] = ()
    drops: tuple[tuple[str, tuple[str, ...]], ...] = ()

    def blocks(self, src: str, dst: str) -> bool:
        if self.groups:
            return _group_of(self.groups, src) != _group_of(self.groups, dst)
        return any(receiver == dst and src in senders for receiver, senders in self.drops)


def _group_of(groups: tuple[tuple[str, ...], ...], vid: str) -> int:
    for j, g in enumerate(groups):
        if vid in g:
            return j
    return -1


@dataclass(frozen=True)
class LinkSpec:
    """A validated ``[link]`` table."""

    policy: str = DEFAULT_POLICY
    timeout: float = DEFAULT_TIMEOUT
    seed: int | None = None  # None: the scenario's seed
    delay: Delay = Delay()
    loss: float = 0.0
    burst: Burst | None = None
    duplicate: float = 0.0
    overrides: tuple[Override, ...] = ()
    down: tuple[Down, ...] = ()
    partitions: tuple[Partition, ...] = ()

    @property
    def is_ideal(self) -> bool:
        """No link ever delays, drops or duplicates anything (conservative: False may still be
        ideal in effect, e.g. an override setting loss that a later one sets back to 0)."""
        if self.down or self.partitions:
            return False
        if _faulty(self.delay, self.loss, self.burst, self.duplicate):
            return False
        # Conservative: an override that sets any active fault counts, even if a later one undoes it.
        return not any(_faulty(Delay(**dict(o.delay)), o.loss or 0.0, o.burst, o.duplicate or 0.0)
                       for o in self.overrides)

    def for_link(self, src: str, dst: str) -> "LinkFaults":
        """The random faults of ``src -> dst`` (ids): the table's, then the matching overrides in order."""
        delay = self.delay
        loss, burst, duplicate = self.loss, self.burst, self.duplicate
        for o in self.overrides:
            if not o.matches(src, dst):
                continue
            if o.delay:
                delay = Delay(**{**delay.__dict__, **dict(o.delay)})
            if o.loss is not None:
                loss = o.loss
            if o.burst is not None:
                burst = o.burst
            if o.duplicate is not None:
                duplicate = o.duplicate
        return LinkFaults(delay, loss, burst, duplicate)

    def blocked(self, src: str, dst: str) -> tuple[tuple[float, float, str], ...]:
        """The windows [start, end) in which ``src -> dst`` drops everything, with the cause
        ("down" before "partition")."""
        windows = [(w.start, w.end, "down") for w in self.down if w.blocks(src, dst)]
        windows += [(p.start, p.end, "partition") for p in self.partitions if p.blocks(src, dst)]
        return tuple(windows)


@dataclass(frozen=True)
class LinkFaults:
    """The random faults of one directed link (windows aside)."""

    delay: Delay
    loss: float
    burst: Burst | None
    duplicate: float

    @property
    def active(self) -> bool:
        return _faulty(self.delay, self.loss, self.burst, self.duplicate)


def _faulty(delay: Delay, loss: float, burst: Burst | None, duplicate: float) -> bool:
    return delay.active or loss > 0.0 or (burst is not None and burst.active) or duplicate > 0.0

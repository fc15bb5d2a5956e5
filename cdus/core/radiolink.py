"""What do the hand-set link faults and the radio channel together do to a message? One link
model for a node.

:class:`RadioLink` composes the ``[link]`` model (:class:`cdus.core.link.LinkEmulator` or
the ideal link) with the ``[radio]`` channel (:class:`cdus.core.radio.RadioChannel`): a
message must survive both. The hand-set fault decides first (as if it acted at the
transmitter: a partition or a down window means the radio is not even keyed), then the
channel decides from the geometry in force at the send tick; the delays add up (the
link's delay of each copy plus the channel's queueing, airtime and relay delay).

Geometry schedule (docs/radio.md, "Integration"): the world samples every vehicle's position
every ``every`` control ticks; the sample of tick ``s`` is in force from tick ``s + lag``
(``lag >= 1``), and a message sent at tick ``m`` uses the newest sample in force at ``m``
(sample 0 before tick ``lag``). A deterministic runner deciding at tick ``n`` the messages
sent before ``n`` therefore needs the sample :meth:`RadioLink.sample_for` ``(n - 1)``
(:meth:`RadioLink.missing`); the in-process fleet hands it over at the end of tick ``s``,
the world once every vehicle live at ``s`` has reported it (and grants no further before).

Pure: no I/O; each decision is a function of (seed, src, dst, seq), the link spec and the
radio spec in force at the send time and the geometry sample in force at the send tick.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from cdus.core.link import LinkModel
from cdus.core.radio import Geometry, RadioChannel, RadioCounters
from cdus.core.vocabulary import RADIO_CAUSES

KEEP_SAMPLES = 256  # geometry samples kept (a gap filled this late still finds its own)


@dataclass(frozen=True)
class RadioEvent:
    """A scheduled radio change (``[[event]] action = "radio"``): from send time ``at`` on, the
    transmit power (dBm) and/or the station position; None leaves it as it is."""

    at: float
    tx_power: float | None = None
    station: tuple[float, float, float] | None = None


def as_point(q: Sequence[float]) -> tuple[float, float, float]:
    """A position as (x, y, z): a 2D vehicle (a boat) is at z = 0 (its antenna height is the
    channel's, by kind)."""
    return (float(q[0]), float(q[1]), float(q[2]) if len(q) > 2 else 0.0)


def sample_tick(m: int, every: int, lag: int) -> int:
    """The sample tick in force at tick ``m``: the newest ``s`` (a multiple of ``every``) with
    ``s + lag <= m``; sample 0 before tick ``lag``."""
    return max(0, (m - lag) // every * every) if m >= lag else 0


class RadioLink(LinkModel):
    """A :class:`LinkModel`: the hand-set link faults, then the radio channel (module docstring)."""

    def __init__(self, inner: LinkModel, channel: RadioChannel, *, period: float, every: int, lag: int):
        if every < 1 or lag < 1:
            raise ValueError(f"radio sample every and lag must be >= 1 tick, got {every}, {lag}")
        self.inner = inner
        self.channel = channel
        self.period = period
        self.every = every
        self.lag = lag
        self.counters = RadioCounters()
        self._geo: dict[int, Geometry] = {}
        self.newest = -1  # newest sample tick held

    # ---- the link emulator's run-time interface, forwarded (set_link, metrics)
    @property
    def epochs(self):
        return self.inner.epochs

    @property
    def faults(self):
        return self.inner.faults

    @property
    def radio(self) -> RadioLink:
        return self

    def update(self, spec, at: float) -> None:
        self.inner.update(spec, at)  # type: ignore[attr-defined]

    # ---- geometry
    def on_geometry(self, tick: int, positions: Sequence[Sequence[float] | None]) -> bool:
        """Take the sample of ``tick`` (the first one given for a tick stands). False if it was
        not taken (not a sample tick, or already held)."""
        if tick < 0 or tick % self.every or tick in self._geo:
            return False
        pts = tuple(None if q is None else as_point(q) for q in positions)
        self._geo[tick] = Geometry.of(tick, pts, None)
        self.newest = max(self.newest, tick)
        while len(self._geo) > KEEP_SAMPLES:
            del self._geo[min(self._geo)]
        return True

    def held(self, tick: int) -> Geometry | None:
        """The sample of ``tick`` held (the first one given), or None."""
        return self._geo.get(tick)

    def sample_for(self, m: int) -> int:
        return sample_tick(m, self.every, self.lag)

    def missing(self, m: int) -> bool:
        """Is the sample in force at tick ``m`` still to come? (deterministic runners wait)"""
        return m >= 0 and self.sample_for(m) > self.newest

    def geometry_at(self, m: int) -> Geometry | None:
        """The sample in force at tick ``m``, or (realtime, not here yet) the newest one before it."""
        s = self.sample_for(m)
        geo = self._geo.get(s)
        if geo is None:
            older = [k for k in self._geo if k <= s]
            geo = self._geo[max(older)] if older else None
        return geo

    # ---- the decision
    def decide(self, src: int, dst: int, seq: int, t_send: float) -> tuple[float, ...]:
        delays = self.inner.decide(src, dst, seq, t_send)
        c = self.counters
        c.sent += 1
        if not delays:
            c.fault += 1
            return delays
        geo = self.geometry_at(int(round(t_send / self.period)))
        if geo is None:
            c.no_geometry += 1
            c.delivered += 1
            return delays
        d = self.channel.decide(src, dst, seq, t_send, geo)
        if not d.delivered:
            cause = d.cause if d.cause in RADIO_CAUSES else "range"
            setattr(c, cause, getattr(c, cause) + 1)
            return ()
        c.delivered += 1
        extra = d.delay
        return delays if extra <= 0.0 else tuple(x + extra for x in delays)

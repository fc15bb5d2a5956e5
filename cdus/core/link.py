"""What does the link do to a message? Per directed link src -> dst, decided at the receiver.

A link model is a pure decision: ``decide(src, dst, seq, t_send) -> delays`` gives the
delays (seconds) after which copies of the message become usable at ``dst``; an empty
tuple is a drop, two entries a duplicate. It depends on its arguments (and the model's
own seeded state per link) only, never on arrival order, so an in-process run and a
lockstep multi-process run make the same decisions.
"""

from __future__ import annotations

import bisect
import hashlib
import math
from dataclasses import dataclass, field
from typing import Iterable, Protocol, Sequence

from cdus.core.linkspec import LinkSpec
from cdus.core.vocabulary import DROP_CAUSES, LINK_STATES
from cdus.wire.schemas import FleetEvent


class LinkModel(Protocol):
    """What a runner asks of a link model. ``decide`` is the model; the properties say what else
    it holds, and default to "nothing" for a model that has nothing to say: a model subclasses
    this class to take them, and its users ask them without duck typing."""

    def decide(self, src: int, dst: int, seq: int, t_send: float) -> tuple[float, ...]:
        ...

    @property
    def epochs(self) -> tuple[tuple[float, LinkSpec], ...] | None:
        """The [link] specs and the send times they apply from, or None: run-time link changes
        do not reach this model."""
        return None

    @property
    def faults(self) -> LinkEmulator | None:
        """The emulator of the hand-set [link] faults in this model (its counters and link state
        changes), or None."""
        return None

    @property
    def radio(self) -> LinkModel | None:
        """The radio path in this model (a cdus.core.radiolink.RadioLink: it takes geometry
        samples), or None."""
        return None


class IdealLink(LinkModel):
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


# --------------------------------------------------------------------------- the emulator
#
# Determinism. Every random draw is a uniform u = U(key, seq) in [0, 1): SplitMix64 (Steele,
# Lea & Flood 2014) at position ``seq`` of a stream whose 64-bit key is the BLAKE2b hash of
# "cdus-link|<seed>|<src id>|<dst id>|<purpose>", one stream per link and purpose (loss,
# burst step, burst loss, duplicate, two per delay copy). A decision is thus a function of
# (seed, src, dst, seq, t_send) and the spec alone, whatever the order of the calls: the
# in-process fleet (send order) and the agents (arrival order, at each receiver) agree.
# The Gilbert-Elliott state of message ``seq`` is the chain started good before seq 0 and
# stepped by U(key, 0..seq); it is computed by looking back to the last step that fixes the
# state whatever came before (see :func:`burst_bad`), so it too is a pure function of seq.
# Only per-link FIFO (reorder = false) keeps state: it assumes calls in seq order per
# link, which both runners guarantee.

_M64 = (1 << 64) - 1
_GAMMA = 0x9E3779B97F4A7C15
_TWO_M53 = 2.0 ** -53
_TWO_PI = 2.0 * math.pi

STREAMS = ("loss", "burst-step", "burst-loss", "duplicate", "delay0a", "delay0b", "delay1a", "delay1b")
_LOSS, _STEP, _BLOSS, _DUP, _DELAY = 0, 1, 2, 3, 4  # _DELAY + 2 * copy, + 1 for the second draw
_ARRIVE = (0.0,)
_DROP: tuple[float, ...] = ()


def stream_key(seed: int, src: str, dst: str, purpose: str) -> int:
    """The 64-bit key of one random stream of the link ``src -> dst`` (vehicle ids)."""
    text = f"cdus-link|{seed}|{src}|{dst}|{purpose}".encode()
    return int.from_bytes(hashlib.blake2b(text, digest_size=8).digest(), "little")


def uniform(key: int, seq: int) -> float:
    """Draw number ``seq`` of the stream ``key``: SplitMix64's output, as a float in [0, 1)."""
    z = (key + (seq + 1) * _GAMMA) & _M64
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _M64
    return ((z ^ (z >> 31)) >> 11) * _TWO_M53


def draw_delay(distribution: str, base: float, jitter: float, u1: float, u2: float) -> float:
    """One delay (s) from two uniforms, clipped at 0.

    uniform: base + jitter (2 u1 - 1), i.e. base ± jitter;
    normal:  base + jitter z, z = N(0, 1) by Box-Muller;
    pareto:  base + 2 jitter ((1 - u1)^(-1/3) - 1): a Lomax (Pareto II, α = 3) tail of mean
             ``jitter`` above the minimum ``base``; P(delay > base + x) = (1 + x / (2 jitter))^-3.
    """
    if distribution == "uniform":
        d = base + jitter * (2.0 * u1 - 1.0)
    elif distribution == "normal":
        d = base + jitter * math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(_TWO_PI * u2)
    else:
        d = base + 2.0 * jitter * ((1.0 - u1) ** (-1.0 / 3.0) - 1.0)
    return d if d > 0.0 else 0.0


def burst_bad(p: float, r: float, key: int, seq: int) -> bool:
    """Is the Gilbert-Elliott chain (p = P(good -> bad), r = P(bad -> good)) bad at message ``seq``?

    The chain starts good before message 0 and steps once per message k = 0, 1, ... with
    u_k = uniform(key, k): bad after the step iff u_k < (1 - r if bad before else p). A step
    with u_k < min(p, 1 - r) leaves it bad and one with u_k >= max(p, 1 - r) good whatever
    the state before, so the state at ``seq`` follows from the last such step m <= seq: the
    steps after it keep the state (p <= 1 - r) or flip it (p > 1 - r). Expected look-back
    1 / (1 - |1 - p - r|) draws; the same result as stepping forward from message 0.
    """
    lo, hi = (p, 1.0 - r) if p <= 1.0 - r else (1.0 - r, p)
    m, bad = seq, False
    if lo > 0.0 or hi < 1.0:
        while m >= 0:
            u = uniform(key, m)
            if u < lo:
                bad = True
                break
            if u >= hi:
                break
            m -= 1
    else:
        m = -1  # p = r = 0 (never moves) or p = r = 1 (flips every message)
    if p > 1.0 - r and (seq - m) % 2:
        bad = not bad
    return bad


@dataclass
class LinkFaultCounters:
    """What the emulator did on one directed link (or all): decisions, drops by cause,
    extra copies, copies given a delay > 0."""

    sent: int = 0
    dropped: int = 0
    loss: int = 0
    burst: int = 0
    down: int = 0
    partition: int = 0
    duplicated: int = 0
    delayed: int = 0

    def add(self, other: "LinkFaultCounters") -> None:
        for name in self.__dataclass_fields__:
            setattr(self, name, getattr(self, name) + getattr(other, name))

    def as_dict(self) -> dict:
        return {"sent": self.sent, "dropped": self.dropped,
                "dropped_by": {c: getattr(self, c) for c in DROP_CAUSES},
                "duplicated": self.duplicated, "delayed": self.delayed}


class _Plan:
    """One directed link's faults under one epoch's spec, compiled for decide()."""

    __slots__ = ("ideal", "lossy", "blocked", "loss", "burst", "duplicate", "distribution", "base", "jitter",
                 "delayed", "fifo")

    def __init__(self, spec: LinkSpec, src: str, dst: str):
        f = spec.for_link(src, dst)
        self.blocked = spec.blocked(src, dst)
        self.lossy = f.active
        self.fifo = not f.delay.reorder
        self.ideal = not self.lossy and not self.blocked and not self.fifo
        self.loss = f.loss
        b = f.burst
        self.burst = (b.p, b.r, b.bad_loss, b.good_loss) if b is not None and b.active else None
        self.duplicate = f.duplicate
        self.distribution = f.delay.distribution
        self.base, self.jitter = f.delay.base, f.delay.jitter
        self.delayed = f.delay.active


class _Link:
    """Per directed link: counters, the last state, random-stream keys, caches."""

    __slots__ = ("counters", "state", "keys", "plans", "chain", "fifo_seq", "fifo_last", "fifo_recent")

    def __init__(self, keys: tuple[int, ...]):
        self.counters = LinkFaultCounters()
        self.state = "up"
        self.keys = keys
        self.plans: list[_Plan] = []
        self.chain: tuple = (None, -1, False)  # (burst params, seq, bad): a cache of burst_bad
        self.fifo_seq = -1  # newest seq FIFO-adjusted
        self.fifo_last = -math.inf  # when it becomes usable (s)
        self.fifo_recent: dict[int, tuple[float, ...]] = {}


class LinkEmulator(LinkModel):
    """The link fault emulator (docs/link.md): a :class:`LinkModel`.

    ``decide(src, dst, seq, t_send)`` depends on (seed, src, dst, seq, t_send) and the spec
    in force at ``t_send`` only (see the note above on determinism). Order of the checks,
    which is also the drop cause recorded: a down window, a partition, the burst
    (Gilbert-Elliott) loss, the Bernoulli loss; a message that survives is duplicated with
    probability ``duplicate`` (each copy its own delay draw), then delayed; with
    ``reorder = false`` each copy is held until the previous one on the link is usable.
    Records counters per link and the link state changes ``(t_send, src, dst, state)``,
    state in up | lossy | down, in the order of the calls.
    """

    def __init__(self, spec: LinkSpec, ids: Sequence[str], seed: int):
        self.ids = tuple(ids)
        self.seed = seed
        self._starts: list[float] = [-math.inf]  # epoch i applies for t_send >= _starts[i]
        self._specs: list[LinkSpec] = [spec]
        self._links: dict[tuple[int, int], _Link] = {}
        self.state_changes: list[tuple[float, int, int, str]] = []

    @property
    def spec(self) -> LinkSpec:
        """The newest spec."""
        return self._specs[-1]

    @property
    def epochs(self) -> tuple[tuple[float, LinkSpec], ...]:
        return tuple(zip(self._starts, self._specs))

    @property
    def faults(self) -> LinkEmulator:
        return self

    def update(self, spec: LinkSpec, at: float) -> None:
        """From simulated time ``at`` on (t_send >= at) ``spec`` applies; earlier messages keep
        the spec they had. ``at`` may not go back before the newest epoch's start; the same
        ``at`` again replaces that epoch. (``spec.seed`` is not used: the streams stay.)"""
        if at < self._starts[-1]:
            raise ValueError(f"link update at t = {at:g} s is before the previous one at t = {self._starts[-1]:g} s; "
                             f"updates must come in time order")
        if at == self._starts[-1]:
            self._specs[-1] = spec
        else:
            self._starts.append(at)
            self._specs.append(spec)
        for link in self._links.values():
            link.plans.clear()

    def _link(self, src: int, dst: int) -> _Link:
        s, d = self.ids[src], self.ids[dst]
        link = self._links[(src, dst)] = _Link(tuple(stream_key(self.seed, s, d, p) for p in STREAMS))
        return link

    def _plan(self, link: _Link, src: int, dst: int, epoch: int) -> _Plan:
        plans = link.plans
        while len(plans) <= epoch:
            plans.append(_Plan(self._specs[len(plans)], self.ids[src], self.ids[dst]))
        return plans[epoch]

    def _set_state(self, link: _Link, t: float, src: int, dst: int, state: str) -> None:
        link.state = state
        self.state_changes.append((t, src, dst, state))

    def decide(self, src: int, dst: int, seq: int, t_send: float) -> tuple[float, ...]:
        link = self._links.get((src, dst)) or self._link(src, dst)
        c = link.counters
        c.sent += 1
        epoch = 0 if len(self._starts) == 1 else bisect.bisect_right(self._starts, t_send) - 1
        plans = link.plans
        plan = plans[epoch] if epoch < len(plans) else self._plan(link, src, dst, epoch)
        if plan.ideal:  # the fast path
            if link.state != "up":
                self._set_state(link, t_send, src, dst, "up")
            return _ARRIVE

        for start, end, cause in plan.blocked:
            if start <= t_send < end:
                if link.state != "down":
                    self._set_state(link, t_send, src, dst, "down")
                c.dropped += 1
                setattr(c, cause, getattr(c, cause) + 1)
                return _DROP
        state = "lossy" if plan.lossy else "up"
        if link.state != state:
            self._set_state(link, t_send, src, dst, state)

        keys = link.keys
        burst = plan.burst
        if burst is not None:
            cached, cseq, bad = link.chain
            if cached == burst and 0 <= seq - cseq <= 32:
                for k in range(cseq + 1, seq + 1):
                    bad = uniform(keys[_STEP], k) < (1.0 - burst[1] if bad else burst[0])
            else:
                bad = burst_bad(burst[0], burst[1], keys[_STEP], seq)
            link.chain = (burst, seq, bad)
            x = burst[2] if bad else burst[3]
            if x > 0.0 and (x >= 1.0 or uniform(keys[_BLOSS], seq) < x):
                c.dropped += 1
                c.burst += 1
                return _DROP
        if plan.loss > 0.0 and uniform(keys[_LOSS], seq) < plan.loss:
            c.dropped += 1
            c.loss += 1
            return _DROP

        copies = 2 if plan.duplicate > 0.0 and uniform(keys[_DUP], seq) < plan.duplicate else 1
        if plan.delayed:
            dist, base, jitter = plan.distribution, plan.base, plan.jitter
            delays = tuple(draw_delay(dist, base, jitter, uniform(keys[_DELAY + 2 * j], seq),
                                      uniform(keys[_DELAY + 2 * j + 1], seq) if dist == "normal" else 0.0)
                           for j in range(copies))
        else:
            delays = (0.0,) * copies
        if plan.fifo:
            delays = self._fifo(link, seq, t_send, delays)
        if copies == 2:
            c.duplicated += 1
        for d in delays:
            if d > 0.0:
                c.delayed += 1
        return delays

    @staticmethod
    def _fifo(link: _Link, seq: int, t_send: float, delays: tuple[float, ...]) -> tuple[float, ...]:
        """Hold each copy until the previous one on the link is usable (calls in seq order;
        a repeated seq gets its first answer again, an older one its unheld delays)."""
        if seq <= link.fifo_seq:
            return link.fifo_recent.get(seq, delays)
        last = link.fifo_last
        held = []
        for d in delays:
            if t_send + d < last:
                d = last - t_send
            last = max(last, t_send + d)
            held.append(d)
        out = tuple(held)
        link.fifo_seq, link.fifo_last = seq, last
        recent = link.fifo_recent
        recent[seq] = out
        if len(recent) > 256:
            del recent[next(iter(recent))]
        return out

    # ---- records

    def counters(self) -> dict[tuple[int, int], LinkFaultCounters]:
        """Per directed link (src, dst), the links decided so far."""
        return {key: link.counters for key, link in sorted(self._links.items())}

    def counters_summary(self) -> dict:
        """For the metrics JSON: ``{"total": {...}, "links": {"usv1->usv2": {...}}, "state_changes":
        [{"t", "link", "state"}, ...]}``; each counter block is ``{sent, dropped, dropped_by: {loss,
        burst, down, partition}, duplicated, delayed}``."""
        total = LinkFaultCounters()
        links = {}
        for (src, dst), c in self.counters().items():
            total.add(c)
            links[f"{self.ids[src]}->{self.ids[dst]}"] = c.as_dict()
        changes = [{"t": t, "link": f"{self.ids[s]}->{self.ids[d]}", "state": state}
                   for t, s, d, state in sorted(self.state_changes, key=lambda e: (e[0], e[1], e[2]))]
        return {"total": total.as_dict(), "links": links, "state_changes": changes}


def _fault_counters(d: dict) -> LinkFaultCounters:
    """A counter block of :meth:`LinkFaultCounters.as_dict` back into counters."""
    return LinkFaultCounters(sent=d["sent"], dropped=d["dropped"], duplicated=d["duplicated"], delayed=d["delayed"],
                             **d["dropped_by"])


def merge_link_summaries(summaries: Iterable[dict]) -> dict:
    """One summary from several :meth:`LinkEmulator.counters_summary` (e.g. one per agent
    process, each deciding its incoming links): totals added, a link's counters added over the
    processes that decided it (a restarted vehicle's old and new process: the new one counts
    from zero), state changes by time."""
    total = LinkFaultCounters()
    links: dict[str, LinkFaultCounters] = {}
    changes: list[dict] = []
    for s in summaries:
        total.add(_fault_counters(s["total"]))
        for name, c in s["links"].items():
            links.setdefault(name, LinkFaultCounters()).add(_fault_counters(c))
        changes.extend(s["state_changes"])
    changes.sort(key=lambda e: e["t"])
    return {"total": total.as_dict(), "links": {k: links[k].as_dict() for k in sorted(links)},
            "state_changes": changes}


@dataclass
class DropBursts:
    """Runs of consecutive drops on each directed link; a run of ``min_len`` or more is news.

    ``feed`` every decision in send order per link; a burst is reported when the run ends
    (the next message gets through): ``done`` holds (t_first, t_next, src, dst, drops).
    """

    min_len: int = 10
    runs: dict[tuple[int, int], tuple[float, int]] = field(default_factory=dict)
    done: list[tuple[float, float, int, int, int]] = field(default_factory=list)
    reported: int = 0  # how many of ``done`` have been taken as events

    def feed(self, src: int, dst: int, dropped: bool, t: float) -> None:
        key = (src, dst)
        if dropped:
            start, count = self.runs.get(key, (t, 0))
            self.runs[key] = (start, count + 1)
        elif key in self.runs:
            start, count = self.runs.pop(key)
            if count >= self.min_len:
                self.done.append((start, t, src, dst, count))


def burst_events(bursts: DropBursts, ids: Sequence[str]) -> list[FleetEvent]:
    """The bursts ended since the last call, as ``link_burst`` events at the time each ended."""
    new = bursts.done[bursts.reported:]
    bursts.reported = len(bursts.done)
    return [FleetEvent.of(t1, "link_burst", f"link {ids[src]}->{ids[dst]}: {count} messages dropped in a row "
                                            f"({t0:.2f}-{t1:.2f} s)", link=f"{ids[src]}->{ids[dst]}")
            for t0, t1, src, dst, count in new]

"""What does a vehicle take from the wire? The checks an ω message passes at entry, and how a
taken one waits until the link model makes it usable.

:class:`Intake` is the part of :class:`cdus.core.node.VehicleNode` that receives (its state
is the node's: the peers, the inbox, the counters): ``on_message`` checks a decoded ω message
in the order docs/architecture.md ("What a vehicle accepts") gives (the sender is a
neighbour, its send time is the one its seq implies, its seq is within what the sender can
have sent, it is newer than the newest taken unless it fills a gap, and ω agrees with the
sender's past: :func:`omega_plausible`); a reject is counted by reason (:data:`REJECT_REASONS`)
and never advances the sender's seq. A taken message is decided by the link model (whether
and when it becomes usable) and offered to the neighbour table on its delivery tick.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

from cdus.core.events import RosterChange
from cdus.core.schedule import delivery_tick, send_tick
from cdus.wire.messages import OmegaMsg

REJECT_REASONS = ("not_a_neighbour", "inconsistent", "future", "stale", "conflict", "implausible", "gone")
#: reasons a hostile or broken sender shows (the world turns new counts of them into an event)
HOSTILE_REASONS = ("future", "conflict", "implausible")
RECENT = 8  # messages kept per sender to tell a duplicate ("stale") from a forgery ("conflict")
GAP = 64  # seqs skipped by a newer message that are still taken if they come (an outage's resends)
CANDIDATES = 4  # messages kept per seq that agree with the sender's past (the genuine one among forgeries)
HEAL = 3  # consecutive messages consistent with each other but not with the sender's past: a new past
#: slack of the loose check over a gap of several ticks (rad/s on the mean rate; docs/architecture.md)
GAP_RATE_SLACK = 1.0


def omega_plausible(prev: OmegaMsg, msg: OmegaMsg, period: float) -> bool:
    """Can a genuine sender that sent ``prev`` send ``msg`` next (``msg.seq > prev.seq``)?

    A vehicle's ω at tick n is ω at tick n - 1 plus T ω̇_n, where ω̇_n is the mean rate over
    that period and is what the message carries (cdus.core.vehicle.Vehicle.control), packed as
    float32 (relative error <= 2^-24). So for consecutive ticks the relation is exact up to
    rounding. Over a gap of g > 1 ticks (a broadcast period of several control ticks, or
    messages lost) only the end rates are known: the mean rate must lie within the end rates'
    half spread, plus their mean (a sender frozen meanwhile kept its ω), plus
    :data:`GAP_RATE_SLACK`, around their mean. A restart or a rejoin moves ω freely; the caller skips
    the check where the roster explains the gap (and heals after :data:`HEAL` messages).
    """
    g = round((msg.t_send - prev.t_send) / period)
    if g <= 0:
        return False
    d = msg.omega - prev.omega
    ulp = 4 * math.ulp(max(abs(msg.omega), abs(prev.omega), 1.0))
    if g == 1:
        return abs(d - period * msg.omega_rate) <= period * abs(msg.omega_rate) * 2.0 ** -21 + ulp
    span = g * period
    mid = 0.5 * (prev.omega_rate + msg.omega_rate)
    # a sender frozen meanwhile (a realtime stall) kept its ω: a mean rate of 0 is allowed too
    return abs(d - span * mid) <= span * (0.5 * abs(msg.omega_rate - prev.omega_rate) + abs(mid) + GAP_RATE_SLACK) \
        + ulp


@dataclass
class _Neighbour:
    """What a receiver knows of one neighbour's liveness."""

    state: str = "live"
    since: int = 0  # tick of its newest (re)start: nothing it sent before is used
    changes: list[RosterChange] = field(default_factory=list)  # not yet applied, by tick
    change_ticks: list[int] = field(default_factory=list)  # ticks of every change heard of (newest RECENT)
    #: seq -> the messages heard with it that agreed with the sender's past (the one taken first),
    #: newest RECENT seqs: the past a new message must agree with, and what tells a copy from a forgery
    recent: dict[int, list[OmegaMsg]] = field(default_factory=dict)
    chain: list[OmegaMsg] = field(default_factory=list)  # implausible messages consistent with each other
    missing: set[int] = field(default_factory=set)  # seqs skipped by a newer one (lost in flight), newest GAP


class Intake:
    """The receiving half of :class:`cdus.core.node.VehicleNode` (a mixin: it uses the node's
    attributes, set in the node's ``__init__``)."""

    def on_message(self, msg: OmegaMsg, arrival: float | None = None) -> str | None:
        """Take a validated ω message from the wire; returns a reject reason or None.

        Checked in this order, every reject counted by reason: the sender is a neighbour; its
        send time is the one its seq implies (``inconsistent``); the seq is within what the
        sender can have sent (``future``: past :attr:`horizon` or the run's last tick); it is
        newer than the newest taken (``stale``: a copy, ``conflict``: the same seq with other
        content), unless it fills a seq a newer one skipped; and ω agrees with a message of
        the nearest older seq that agreed with the sender's past (``implausible``,
        :func:`omega_plausible`; every such message is kept as a candidate of its seq, so a
        forgery taken first cannot make the genuine sender implausible). A rejected message
        never advances the sender's newest seq, so nobody else's message can lock a sender out.
        """
        k = msg.sender
        peer = self._peers.get(k)
        if peer is None:
            return self._reject("not_a_neighbour")
        tick = msg.seq * self.every
        if msg.t_send != tick * self.period:  # Vehicle.t = tick * T exactly, tick = seq * every
            return self._reject("inconsistent")
        if tick > self.last_tick or (self.horizon is not None and tick > self.horizon):
            return self._reject("future")
        if tick < self._deaf_before:
            return None  # sent while this vehicle's process was gone: it never heard it (see rejoin)
        newest = self.seen_seq.get(k, -1)
        if msg.seq <= newest:
            if msg in peer.recent.get(msg.seq, ()):
                return self._reject("stale")  # a copy of what was taken or heard
            if msg.seq in peer.missing and self._plausible(peer, msg, tick):
                return self._fill(peer, msg, arrival)  # a message lost in flight, said again
            if msg.seq in peer.recent:
                # Someone else sends with this seq. Keep it as a candidate if it agrees with the
                # sender's past, so that if it is the genuine one its successor is not judged
                # against a forgery taken before it (that would lock the sender out).
                if self._plausible(peer, msg, tick):
                    taken = peer.recent[msg.seq][0]
                    if arrival is None and taken in self._inbox and not self._plausible(peer, taken, tick):
                        # The one taken first disagrees with the past as it is known now (it came
                        # before its predecessor): it was the forgery, and it is not decided yet.
                        self._inbox[self._inbox.index(taken)] = msg
                        peer.recent[msg.seq] = [msg]
                        return self._reject("implausible")  # counted for the forgery
                    self._remember(peer, msg)
                return self._reject("conflict")
            return self._reject("implausible" if msg.seq in peer.missing else "stale")
        if not self._plausible(peer, msg, tick):
            chain = peer.chain
            if chain and msg.seq > chain[-1].seq and omega_plausible(chain[-1], msg, self.period):
                chain.append(msg)
            else:
                chain[:] = [msg]
            if len(chain) < HEAL:
                return self._reject("implausible")
        peer.chain.clear()
        if newest >= 0 and msg.seq > newest + 1:  # skipped ones may still come (a resend after an outage)
            lo = max(newest + 1, msg.seq - GAP, -(-max(self.joined_at, self._deaf_before) // self.every))
            peer.missing.update(range(lo, msg.seq))
        if peer.missing:
            peer.missing = {g for g in peer.missing if g > msg.seq - GAP}
        self.seen_seq[k] = msg.seq
        self._take(peer, msg, arrival)
        return None

    def _plausible(self, peer: _Neighbour, msg: OmegaMsg, tick: int) -> bool:
        """Does ``msg`` agree with any message heard at the nearest older seq that itself agreed
        with the sender's past (or is there no such past, or does the roster explain a jump)?"""
        older = [q for q in peer.recent if q < msg.seq]
        if not older:
            return True
        return any(self._explained(peer, prev, tick) or omega_plausible(prev, msg, self.period)
                   for prev in peer.recent[max(older)])

    def _remember(self, peer: _Neighbour, msg: OmegaMsg) -> None:
        """Keep ``msg`` among its seq's candidates (at most CANDIDATES; the newest RECENT seqs)."""
        cands = peer.recent.setdefault(msg.seq, [])
        if msg not in cands and len(cands) < CANDIDATES:
            cands.append(msg)
        while len(peer.recent) > RECENT:
            del peer.recent[min(peer.recent)]

    def _take(self, peer: _Neighbour, msg: OmegaMsg, arrival: float | None) -> None:
        self._remember(peer, msg)
        if arrival is None:
            self._inbox.append(msg)
        else:
            for d in self._decide(msg):
                self._order += 1
                heapq.heappush(self._pending, (arrival + d, self._order, msg, d))

    def _fill(self, peer: _Neighbour, msg: OmegaMsg, arrival: float | None) -> str | None:
        """Take ``msg``, a seq that a newer message skipped (checked by the caller).

        A newer message was judged without ``msg``, against an older past. Deterministic
        runners re-judge every newer one not decided yet against the past as it is known now:
        one that disagrees came before its predecessor and was a forgery (the genuine sender's
        messages of one link arrive in send order, a resend after an outage excepted, and a
        resend agrees with what follows). It is withdrawn, so the node waits for its seq again
        instead of deciding the forgery in the genuine one's place (the Spoofer of
        tests/e2e/test_hostile.py under load: its seq s + 1, made from the genuine s, can reach a
        receiver before the genuine s, and passed the loose check over the 2-tick gap)."""
        peer.missing.discard(msg.seq)
        self._take(peer, msg, arrival)
        if arrival is None and self._rejudge(msg.sender, peer, msg.seq):
            return self._reject("implausible")  # counted for the forgery withdrawn
        return None

    def _rejudge(self, k: int, peer: _Neighbour, seq: int) -> int:
        """Deterministic runners, after the gap ``seq`` of sender ``k`` was filled: re-judge the
        undecided messages taken with a newer seq, oldest first, against the past as now known;
        withdraw those that disagree (another candidate of their seq that agrees takes their
        place). Returns how many were withdrawn."""
        withdrawn, emptied = 0, set()
        for q in sorted(s for s in peer.recent if s > seq):
            taken = peer.recent[q][0]
            if taken not in self._inbox or self._plausible(peer, taken, q * self.every):
                continue
            self._inbox.remove(taken)
            withdrawn += 1
            others = [m for m in peer.recent[q][1:] if self._plausible(peer, m, q * self.every)]
            if others:  # the genuine one came after it, as a conflict, and agrees with the past
                peer.recent[q] = [others[0]]
                self._inbox.append(others[0])
            else:
                del peer.recent[q]
                emptied.add(q)
        if emptied:  # the sender's newest is the newest seq still taken; a withdrawn one below it is a gap
            newest = max(peer.recent, default=seq)
            peer.missing = {g for g in peer.missing if g < newest} | {q for q in emptied if q < newest}
            self.seen_seq[k] = newest
        return withdrawn

    def _explained(self, peer: _Neighbour, last: OmegaMsg, tick: int) -> bool:
        """Does the roster explain a jump of ω between ``last`` and a message sent at ``tick``
        (a change of the sender's liveness in between: a restart, a pause, a resume)?"""
        t0 = send_tick(last.t_send, self.period)
        return any(t0 < c <= tick for c in peer.change_ticks)

    def _reject(self, reason: str) -> str:
        self.rejected[reason] += 1
        return reason

    def _decide(self, msg: OmegaMsg) -> tuple[float, ...]:
        """The link's decision on ``msg`` at this receiver (the delay of each copy), counted."""
        delays = self.link.decide(msg.sender, self.index, msg.seq, msg.t_send)
        c = self.counters
        c.sent += 1
        self.bursts.feed(msg.sender, self.index, not delays, msg.t_send)
        if not delays:
            c.dropped += 1
        elif len(delays) > 1:
            c.duplicated += len(delays) - 1
        return delays

    def _route(self, n: int) -> None:
        """Decide the messages sent before tick ``n`` (in the order received, which is send
        order per link); keep the others until their turn."""
        T = self.period
        early = []
        if len(self._inbox) > 1:  # in send order per link (a gap filled late arrives after newer ones)
            self._inbox.sort(key=lambda m: (m.t_send, m.sender))
        for msg in self._inbox:
            m = send_tick(msg.t_send, T)
            if m >= n:  # from a neighbour already at or past us: decide it when it can matter
                early.append(msg)
            else:
                for d in self._decide(msg):
                    self._due[delivery_tick(m, d, T)].append((msg, d))
        self._inbox = early

    def _offer(self, msg: OmegaMsg, now: float, delay: float) -> None:
        """A message becomes usable: into the table, unless its sender is gone or it was sent
        before the sender's current incarnation."""
        peer = self._peers[msg.sender]
        if peer.state == "gone" or send_tick(msg.t_send, self.period) < peer.since:
            self.counters.rejected += 1
            self.rejected["gone"] += 1
            return
        if self.table.offer(msg, now):
            self.counters.delivered += 1
            self.counters.record_latency(delay)
        else:
            self.counters.rejected += 1

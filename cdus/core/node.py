"""One vehicle's tick protocol: what it does with what it hears, and what one tick does.

A :class:`VehicleNode` is everything a vehicle process decides, without the process: the
in-process fleet drives one per vehicle in memory, the vehicle agent drives one from
Zenoh, and both therefore step the same ticks with the same inputs (docs/architecture.md,
"One tick protocol"). Its inputs:

- ``on_message(msg, arrival)``: a decoded ω message from a neighbour, checked at entry
  (send time implied by its seq, seq within :attr:`VehicleNode.horizon`, duplicates and
  conflicts, ω plausible against the sender's own past; docs/architecture.md, "What a
  vehicle accepts"); a reject is counted and never advances the sender's seq. The link model
  decides, at this receiver, whether and when the message becomes usable, from
  (seed, src, dst, seq) alone. Deterministic runners (in-process, lockstep) pass no
  arrival time: the message is decided at the first tick after the one it was sent at,
  in sequence order per link, and usable from its delivery tick (cdus.core.schedule).
  The realtime runner passes the simulated arrival time: usable at arrival + delay.
- ``on_roster(change)``: a neighbour (or this vehicle) is ``live``, ``paused`` or ``gone``
  from a tick on (cdus.core.events). A gone neighbour leaves the consensus sum and
  nothing it sent before is used any more, however late it arrives; only a ``live``
  change (its liveliness back: a restart or a resume) admits it again, and then only
  messages sent from that tick on.
- ``on_contacts(tick, contacts)``: what the world's proximity sensor saw around this
  vehicle at tick ``tick`` (cdus.core.proximity); usable from tick + ``sense_latency``.
  At tick n the safety filter uses the newest sample taken at or before n - latency
  (and not before this vehicle (re)joined); deterministic runners wait for it
  (``contacts_missing``), a realtime one uses what has arrived.
- ``on_geometry(tick, positions)``: with ``[radio]``, the world's radio geometry sample of
  tick ``tick`` (cdus.core.radiolink: the link model is then a RadioLink); a deterministic
  runner waits for the sample a tick's decisions need (``geometry_missing``).
- ``set_link(spec, at)``, ``set_policy(policy, timeout, tick)``, ``set_gains(k, c,
  tick)``, ``set_formation(phases, tick)`` and ``set_path(path, tick)``: run-time changes,
  applied in simulated time so every runner applies them alike (cdus.core.formation).
- ``waiting_for(n)``: the neighbours whose broadcast tick ``n`` needs and has not
  arrived (deterministic runners wait for them; a realtime one does not).
- ``step(n)``: the tick: usable messages into the neighbour table, the controller's
  update with the stale-neighbour policy, the telemetry row, the ω broadcast (on
  broadcast ticks), the safety filter on the velocity reference (if on), then the plant
  to the next tick. Returns the :class:`Outbox`.

Pure: no I/O, no clock; counters of what the link did are kept here.
"""

from __future__ import annotations

import bisect
import heapq
import math
from collections import defaultdict
from dataclasses import dataclass, field

from cdus.core.events import RosterChange
from cdus.core.formation import FormationSchedule
from cdus.core.gain_bounds import gains_problem_for_rate
from cdus.core.link import DropBursts, LinkCounters, LinkModel
from cdus.core.linkspec import LinkSpec
from cdus.core.neighbours import NeighbourLink, NeighbourTable, consensus_target
from cdus.core.policies import make_policy
from cdus.core.paths import Path, Vec
from cdus.core.safety import Contact
from cdus.core.schedule import delay_floor, delivery_tick, first_seq_at, needed_seq, send_tick
from cdus.core.vehicle import DivergedError, Telemetry, Vehicle
from cdus.wire.bounds import BOUNDS
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


def gains_problem(gains: dict, dim: int, *, control_hz: float | None = None, plant: str = "ideal",
                  physics_hz: float | None = None, weight_sum: float = 0.0) -> str | None:
    """What is wrong with a run-time gains command ``{"k": number | [per axis], "c": number}``
    for a vehicle of ``dim`` axes (None: nothing). Numbers must be finite and > 0, and, given
    the vehicle's rates, plant and edge-weight sum, within what the discrete controller takes
    (cdus.core.gain_bounds: the same bound the scenario's validation applies)."""
    problem = _gains_shape_problem(gains, dim)
    if problem is None and control_hz is not None:
        problem = gains_problem_for_rate(gains.get("k"), gains.get("c"), control_hz, plant=plant,
                                         physics_hz=physics_hz, weight_sum=weight_sum)
    return problem


def _schedule(changes: list[tuple], change: tuple) -> None:
    """Put ``change`` (a tuple whose first item is the tick it applies from) into ``changes``, kept
    in tick order: appended when it is the latest, as the world's always are (O(1); a sort at each
    made a flood of gains changes quadratic, and a restarted vehicle sent 18,000 of them spent
    10 s of CPU on them); one at the tick of a change already there replaces it (a step applies
    every change due, in order: the later is the one that shows)."""
    i = bisect.bisect_right(changes, change[0], key=lambda g: g[0])
    if i and changes[i - 1][0] == change[0]:
        changes[i - 1] = change
    else:
        changes.insert(i, change)


def _due(changes: list[tuple], n: int) -> tuple | None:
    """Take the changes of ``changes`` (in tick order) due at tick ``n`` out: the last of them (the
    one in force from ``n``), or None."""
    i = 0
    while i < len(changes) and changes[i][0] <= n:
        i += 1
    if i == 0:
        return None
    last = changes[i - 1]
    del changes[:i]
    return last


def _gains_shape_problem(gains: dict, dim: int) -> str | None:
    def ok(x) -> bool:
        return BOUNDS["gains.k"].holds(x)

    extra = sorted(set(gains) - {"k", "c"})
    if extra or not gains:
        return f"gains are k and c, got {sorted(gains)}"
    k = gains.get("k", 1.0)
    if isinstance(k, (list, tuple)):
        if len(k) != dim or not all(ok(x) for x in k):
            return f"k must be {dim} numbers > 0 for this vehicle, got {list(k)}"
    elif not ok(k):
        return f"k must be a number > 0, got {k!r}"
    if "c" in gains and not BOUNDS["gains.c"].holds(gains["c"]):
        return f"c must be a number > 0, got {gains['c']!r}"
    return None


@dataclass(frozen=True)
class Outbox:
    """What one tick produces: the telemetry row and, on broadcast ticks, the ω message."""

    tick: int
    telemetry: Telemetry
    omega: OmegaMsg | None


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


class VehicleNode:
    """The tick protocol of vehicle ``index`` (see the module docstring).

    ``period`` is the control period (s), ``every`` the control ticks per ω broadcast,
    ``last_tick`` the run's last tick (its broadcast would never be used, so it is not sent).
    """

    def __init__(self, index: int, vehicle: Vehicle, links: tuple[NeighbourLink, ...], link: LinkModel,
                 *, period: float, every: int, last_tick: int, policy: str = "hold", timeout: float = 1.5,
                 joined_at: int = 0, sense_every: int | None = None, sense_latency: int = 1):
        self.index = index
        self.vehicle = vehicle
        self.table = NeighbourTable(links, policy, timeout)
        self.link = link
        self.period = period
        self.every = every
        self.last_tick = last_tick
        self.joined_at = joined_at  # broadcasts sent before this tick were never heard
        self.neighbours = tuple(sorted({ln.k for ln in links}))
        self._peers = {k: _Neighbour() for k in self.neighbours}
        self.seen_seq: dict[int, int] = {}  # newest sequence number physically received, per sender
        self.counters = LinkCounters()
        self.rejected = {r: 0 for r in REJECT_REASONS}
        #: the newest send tick a genuine sender can have reached, set by the runner (the fleet's
        #: current tick, a lockstep grant plus its window, a realtime wall tick plus slack);
        #: None: no bound but the run's last tick
        self.horizon: int | None = None
        self.bursts = DropBursts()
        self._inbox: list[OmegaMsg] = []  # deterministic: received, not yet decided (send order)
        self._due: dict[int, list[tuple[OmegaMsg, float]]] = defaultdict(list)  # by delivery tick
        self._pending: list[tuple[float, int, OmegaMsg, float]] = []  # realtime: (usable at, order, msg, delay)
        self._deaf_before = 0  # messages sent before this tick are not heard (a pause that lapsed)
        self._order = 0
        self._self_changes: list[RosterChange] = []
        #: every roster change told so far, applied or not: one said again is not news (the world
        #: says a process's catch-up again while it has reported no tick: it may have stepped past)
        self._heard: set[RosterChange] = set()
        self._gains: list[tuple[int, tuple[float, ...], float]] = []  # (tick, k, c), by tick
        self._policies: list[tuple[int, str, float]] = []  # (tick, policy, timeout), by tick
        self._paths: list[tuple[int, Path]] = []  # (tick, path), by tick
        #: the fleet's phases over ticks (cdus.core.formation); None: the links' Δs never change.
        #: Set by whoever builds the node (cdus.sim.build) with the scenario's phases in force.
        self.formation: FormationSchedule | None = None
        self._base_links = links
        self._formation_at = 0  # formation updates applied to the links (those due by the last tick)
        self.state = "live"  # this vehicle's own: live | paused | gone
        self.tick = joined_at  # the next tick to step
        if sense_latency < 1:
            raise ValueError(f"sense_latency must be >= 1 tick, got {sense_latency}")
        self.sense_every = sense_every  # control ticks between proximity samples; None: no sensor
        self.sense_latency = sense_latency
        self._contacts: dict[int, tuple[Contact, ...]] = {}  # by sample tick, not yet superseded
        self._contacts_used = -1  # newest sample tick used (older ones are dropped)
        self._floors: dict[int, tuple[tuple[int, float], ...]] = {}  # per neighbour: (first seq, least delay)
        #: with [radio], the link model is a cdus.core.radiolink.RadioLink: it holds the geometry samples
        self.radio = link if hasattr(link, "on_geometry") else None

    # ------------------------------------------------------------------ inputs
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

    def on_roster(self, change: RosterChange) -> bool:
        """A liveness change of a neighbour or of this vehicle, effective at ``change.tick``
        (or at the next tick stepped, if that has passed). A change told again is ignored: applied
        once more after its tick it would forget the neighbour's ω (a gone) or its start (a live).
        Returns whether it was news."""
        if change in self._heard:
            return False
        self._heard.add(change)
        if change.vehicle == self.index:
            _insert(self._self_changes, change)
        elif change.vehicle in self._peers:
            peer = self._peers[change.vehicle]
            _insert(peer.changes, change)
            peer.change_ticks.append(change.tick)
            del peer.change_ticks[:-RECENT]
        return True

    def on_contacts(self, tick: int, contacts: tuple[Contact, ...]) -> None:
        """The proximity sensor's contacts of this vehicle sampled at ``tick``."""
        if tick < 0 or tick in self._contacts:
            return
        self._contacts[tick] = tuple(contacts)

    def contacts_missing(self, n: int) -> bool:
        """Does tick ``n`` need a proximity sample that has not arrived? (deterministic runners
        wait for it: the world sends the contacts of tick s before granting s + latency)"""
        s = self._sample_for(n)
        return s is not None and s >= self.joined_at and s > self._contacts_used and s not in self._contacts

    def _sample_for(self, n: int) -> int | None:
        """The sample tick whose contacts tick ``n`` uses on schedule: the newest ``s`` with
        s % every == 0 and s <= n - latency."""
        if self.sense_every is None or n - self.sense_latency < 0:
            return None
        return (n - self.sense_latency) // self.sense_every * self.sense_every

    def contacts_at(self, n: int) -> tuple[Contact, ...]:
        """The contacts the filter uses at tick ``n``: the newest sample received that was taken
        at or before n - latency and not before this vehicle (re)joined; older ones are dropped."""
        usable = [s for s in self._contacts if self.joined_at <= s <= n - self.sense_latency]
        if not usable:
            return ()
        s = max(usable)
        self._contacts_used = s
        for old in [k for k in self._contacts if k < s]:
            del self._contacts[old]
        return self._contacts[s]

    def on_geometry(self, tick: int, positions) -> bool:
        """The radio geometry sample of ``tick`` (every vehicle's position, None if not live);
        False if there is no radio or it was not taken (not a sample tick, or already held)."""
        return self.radio is not None and self.radio.on_geometry(tick, positions)

    def geometry_missing(self, n: int) -> bool:
        """Does stepping tick ``n`` need a radio geometry sample that has not arrived? The messages
        decided at ``n`` were sent before it, so the sample in force at ``n - 1`` (deterministic
        runners wait for it; the world sends it before granting past it)."""
        return self.radio is not None and n - 1 >= self.joined_at and self.radio.missing(n - 1)

    def set_link(self, spec: LinkSpec, at: float) -> float:
        """New link faults for messages sent from simulated time ``at`` on (not before the
        newest change). Returns the time they apply from."""
        epochs = getattr(self.link, "epochs", None)
        if epochs is None:
            raise ValueError("this vehicle's link model cannot change at run time")
        at = max(at, epochs[-1][0])
        self.link.update(spec, at)
        self._floors.clear()  # the lookahead's delay bounds (waiting_for)
        return at

    def set_policy(self, policy: str, timeout: float, tick: int) -> None:
        """A new stale-neighbour policy (and its timeout, s) from tick ``tick`` on."""
        make_policy(policy, timeout)  # an unknown name is refused here, naming the known ones
        if not timeout > 0:
            raise ValueError(f"the policy's timeout must be > 0 s, got {timeout}")
        _schedule(self._policies, (tick, policy, float(timeout)))

    def set_gains(self, k: tuple[float, ...], c: float, tick: int) -> None:
        """New guidance gains from tick ``tick`` (or the next tick stepped)."""
        if len(k) != self.vehicle.dim or not all(x > 0 for x in k) or not c > 0:
            raise ValueError(f"gains need k > 0 ({self.vehicle.dim} values) and c > 0, got k = {k}, c = {c}")
        _schedule(self._gains, (tick, tuple(float(x) for x in k), float(c)))

    def set_formation(self, phases: dict[int, float], tick: int) -> None:
        """Phases ``{vehicle index: θ}`` (ω units) from tick ``tick`` (or the next tick
        stepped); every other vehicle keeps its phase. Δ_ik becomes θ_i - θ_k on every link."""
        if self.formation is None:  # built without the scenario's phases: derive this node's own
            self.formation = FormationSchedule(self._local_phases())
        self.formation.add(tick, phases)

    def _local_phases(self) -> list[float]:
        """Phases that reproduce this node's Δs, θ_i = 0 and θ_k = -Δ_ik (a node built alone)."""
        n = max((ln.k for ln in self._base_links), default=0)
        theta = [0.0] * (max(n, self.index) + 1)
        for ln in self._base_links:
            theta[ln.k] = -ln.delta
        return theta

    def set_path(self, path: Path, tick: int) -> None:
        """A new path (of this vehicle's dimension) from tick ``tick`` (or the next tick stepped);
        ω carries on."""
        if path.dim != self.vehicle.dim:
            raise ValueError(f"a {self.vehicle.dim}-D vehicle needs a {self.vehicle.dim}-D path, got {path.dim}-D")
        self._paths.append((tick, path))
        self._paths.sort(key=lambda g: g[0])

    def _apply_changes(self, n: int) -> None:
        """The path and formation changes due at tick ``n``."""
        while self._paths and self._paths[0][0] <= n:
            self.vehicle.path = self._paths.pop(0)[1]
        f = self.formation
        if f is None:
            return
        count = f.count_by(n)
        if count == self._formation_at:
            return
        self._formation_at = count
        theta = f.phases_at(n)
        me = self.index
        self.table.links = tuple(NeighbourLink(ln.k, ln.weight, theta[me] - theta[ln.k]) for ln in self._base_links)

    # ------------------------------------------------------------------ the schedule
    def live_at(self, k: int, n: int) -> bool:
        """Was (or will) neighbour ``k``, as far as this node has been told, step tick ``n``
        in its current incarnation? Changes already applied are behind ``since``."""
        peer = self._peers[k]
        state, since = peer.state, peer.since
        for ch in peer.changes:
            if ch.tick > n:
                break
            state = ch.state
            if ch.state == "live":
                since = ch.tick
        return state == "live" and n >= since

    def waiting_for(self, n: int) -> list[int]:
        """The neighbours whose newest broadcast that tick ``n`` can use has not arrived yet,
        though they were live when they should have sent it (and after this vehicle joined).

        The lookahead: tick n needs of neighbour k only its broadcasts sent before n that the
        link k -> this vehicle can have delivered by n, given the link's least delay in force at
        their send time (:meth:`needed_seq`). Broadcasts every ``every`` ticks, or a least delay
        of D ticks, let a vehicle step that many ticks with what it holds. Every message a tick
        uses is among those waited for, so the run is the in-process one whatever the timing."""
        out = []
        seen = self.seen_seq
        for k in self.neighbours:
            seq = self.needed_seq(k, n)
            if seq < 0:
                continue
            sent = seq * self.every
            if sent < self.joined_at:
                continue
            if (seen.get(k, -1) < seq and self.live_at(k, sent)) or self._peers[k].missing and self._gap_before(k, seq):
                out.append(k)
        return out

    def needed_seq(self, k: int, n: int) -> int:
        """The newest broadcast seq of neighbour ``k`` that tick ``n`` can use (-1: none):
        cdus.core.schedule.needed_seq over the link's epochs (run-time changes included)."""
        floors = self._floors.get(k)
        if floors is None:
            floors = self._floors[k] = self._link_floors(k)
        if n >= self.last_tick or len(floors) == 1 and floors[0][1] == 0.0:
            # everything sent before n: no delay, or the run's last tick (so every message is
            # decided, and the link's counters are the in-process run's)
            return -1 if n <= 0 else (n - 1) // self.every
        return needed_seq(n, self.every, self.period, floors)

    def _link_floors(self, k: int) -> tuple[tuple[int, float], ...]:
        """The link k -> this vehicle per epoch: (first seq sent under it, least delay s)."""
        epochs = getattr(self.link, "epochs", None)
        ids = getattr(self.link, "ids", None)
        if epochs is None or ids is None:  # a model without a spec (IdealLink): no delay
            return ((0, 0.0),)
        src, dst = ids[k], ids[self.index]
        return tuple((first_seq_at(at, self.every, self.period), delay_floor(spec.for_link(src, dst).delay))
                     for at, spec in epochs)

    def _gap_before(self, k: int, seq: int) -> bool:
        """Is a broadcast of ``k`` up to ``seq``, sent while it was live, skipped (lost in flight)?"""
        return any(g <= seq and self.joined_at <= g * self.every and g * self.every >= self._deaf_before
                   and self.live_at(k, g * self.every) for g in self._peers[k].missing)

    def own_state_at(self, n: int) -> tuple[str, bool]:
        """This vehicle's state at tick ``n`` from the changes it has been told of, and whether
        it comes back fresh (a restart) at ``n``."""
        state, fresh = self.state, False
        for ch in self._self_changes:
            if ch.tick > n:
                break
            state = ch.state
            fresh = ch.state == "live" and ch.fresh and ch.tick == n
        return state, fresh

    def resume_tick(self, n: int) -> int | None:
        """The first tick >= ``n`` at which this vehicle is live again (None if not known yet)."""
        for ch in self._self_changes:
            if ch.tick >= n and ch.state == "live":
                return ch.tick
        state, _ = self.own_state_at(n)
        return n if state == "live" else None

    # ------------------------------------------------------------------ the tick
    def step(self, n: int) -> Outbox:
        """Step tick ``n`` (>= the last one stepped + 1; ticks skipped while paused are fine)."""
        self._apply_roster(n)
        self._apply_self(n)
        T = self.period
        if self._inbox:
            self._route(n)
        delivered = self._due.pop(n, ())
        for msg, d in delivered:
            self._offer(msg, n * T, d)
        pend = self._pending
        while pend and pend[0][0] <= n * T + 1e-12:
            _, _, msg, d = heapq.heappop(pend)
            self._offer(msg, n * T, d)
        gains = _due(self._gains, n)
        if gains is not None:
            _, self.vehicle.k, self.vehicle.c = gains
        policy = _due(self._policies, n)
        if policy is not None:
            self.table.set_policy(policy[1], policy[2])
        self._apply_changes(n)
        v = self.vehicle
        try:
            v.control(self.table.consensus((n - 1) * T))
            tel = v.telemetry()
            out = None
            if n % self.every == 0 and n < self.last_tick:
                out = OmegaMsg(self.index, n // self.every, v.t, v.omega, v.omega_rate)
            if v.safety is not None:
                v.guard(self.contacts_at(n), self._contacts_used)
            v.advance()
        except DivergedError:
            raise
        except (OverflowError, ValueError, ZeroDivisionError) as e:  # float overflow, math domain
            raise DivergedError(f"vehicle {v.id}: its numbers overflowed at t = {n * T:.2f} s (the vehicle "
                                f"diverged; gains k = {v.k}, c = {v.c}): {e}") from e
        if not (math.isfinite(v.omega) and all(math.isfinite(x) for x in v.q)):
            raise DivergedError(f"vehicle {v.id}: its state is no longer finite at t = {(n + 1) * T:.2f} s "
                                f"(the vehicle diverged; gains k = {v.k}, c = {v.c})")
        self.tick = n + 1
        return Outbox(n, tel, out)

    def rejoin(self, n: int, q: Vec | None, heading: float | None, omega_hint: float | None,
               neighbour_omegas: dict[int, float] | None = None) -> None:
        """Join a run under way at tick ``n`` (a restarted process, or a resumed one), at rest at
        ``q``. ω is taken near what the neighbours' consensus asks (``neighbour_omegas``) if
        any is known, else near ``omega_hint``, so it does not have to make up laps."""
        self._apply_changes(n)  # the path and offsets in force at n
        target = consensus_target(self.table.links, neighbour_omegas or {})
        if n > 0 and self.own_state_at(n - 1)[0] == "gone":
            # Back from a pause that outlasted the lease: in a fleet of processes its session was
            # closed and what was sent to it meanwhile is lost or not, depending on wall time.
            # Hear none of it, in every runner alike (what was decided before the pause stays).
            self._deaf_before = n
            self._inbox = [m for m in self._inbox if send_tick(m.t_send, self.period) >= n]
        self.vehicle.rejoin(n, q, heading, target if target is not None else omega_hint)
        for peer in self._peers.values():  # what it missed meanwhile cannot be checked against
            peer.recent.clear()
            peer.chain.clear()
            peer.missing = {g for g in peer.missing if g * self.every >= max(n, self._deaf_before)}
        self.joined_at = n
        self.tick = n
        self.state = "live"

    # ------------------------------------------------------------------ internals
    def _reject(self, reason: str) -> str:
        self.rejected[reason] += 1
        return reason

    def _apply_roster(self, n: int) -> None:
        for k, peer in self._peers.items():
            while peer.changes and peer.changes[0].tick <= n:
                ch = peer.changes.pop(0)
                peer.state = ch.state
                if ch.state == "live":
                    peer.since = ch.tick
                elif ch.state == "gone":
                    self.table.forget(k)

    def _apply_self(self, n: int) -> None:
        while self._self_changes and self._self_changes[0].tick <= n:
            self.state = self._self_changes.pop(0).state

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


def _insert(changes: list[RosterChange], change: RosterChange) -> None:
    """Keep ``changes`` sorted by tick (each change comes once: on_roster keeps what it heard)."""
    changes.append(change)
    changes.sort(key=lambda c: c.tick)

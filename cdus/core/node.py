"""What does one vehicle do with what it hears, and what does one tick do? Its tick protocol.

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
  applied in simulated time so every runner applies them alike (cdus.core.formation); each
  returns its outcome, ``Applied(tick)`` or ``Refused(reason)`` (cdus.core.changes).
- ``waiting_for(n)``: the neighbours whose broadcast tick ``n`` needs and has not
  arrived (deterministic runners wait for them; a realtime one does not).
- ``step(n)``: the tick: usable messages into the neighbour table, the controller's
  update with the stale-neighbour policy, the telemetry row, the ω broadcast (on
  broadcast ticks), the safety filter on the velocity reference (if on), then the plant
  to the next tick. Returns the :class:`Outbox`.

Pure: no I/O, no clock; counters of what the link did are kept here. The node is three
rooms: this one (its state, the roster, the sensors, the schedule of what a tick waits for,
the tick), cdus.core.intake (what it takes from the wire: ``on_message`` and the link's
decisions) and cdus.core.changes (the run-time changes and their outcomes).
"""

from __future__ import annotations

import heapq
import math
from collections import defaultdict
from dataclasses import dataclass

from cdus.core.changes import (  # noqa: F401 (Applied, Refused, Outcome: importable from here too)
    Applied, Outcome, Refused, RunTimeChanges, _due,
)
from cdus.core.events import RosterChange
from cdus.core.formation import FormationSchedule
from cdus.core.intake import (  # noqa: F401 (the intake's vocabulary, importable from here too)
    CANDIDATES, GAP, GAP_RATE_SLACK, HEAL, HOSTILE_REASONS, RECENT, REJECT_REASONS, Intake, _Neighbour,
    omega_plausible,
)
from cdus.core.link import DropBursts, LinkCounters, LinkModel
from cdus.core.neighbours import NeighbourLink, NeighbourTable, consensus_target
from cdus.core.paths import Path, Vec
from cdus.core.safety import Contact
from cdus.core.schedule import delay_floor, first_seq_at, needed_seq, send_tick
from cdus.core.vehicle import DivergedError, Telemetry, Vehicle
from cdus.wire.messages import OmegaMsg


@dataclass(frozen=True)
class Outbox:
    """What one tick produces: the telemetry row and, on broadcast ticks, the ω message."""

    tick: int
    telemetry: Telemetry
    omega: OmegaMsg | None


class VehicleNode(Intake, RunTimeChanges):
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


def _insert(changes: list[RosterChange], change: RosterChange) -> None:
    """Keep ``changes`` sorted by tick (each change comes once: on_roster keeps what it heard)."""
    changes.append(change)
    changes.sort(key=lambda c: c.tick)

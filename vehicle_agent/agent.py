"""The vehicle process: one vehicle's tick protocol (cdus.core.node) wired to Zenoh.

Everything addressed to this vehicle (its neighbours' ω, the world's clock, roster and
relayed commands) arrives through one subscription into one channel, and the main
thread waits on that channel alone: no callbacks, no locks, one wake-up per message
(docs/architecture.md, "The agent"). In realtime, where the main thread polls at least
every MAX_NAP, each neighbour's ω has a bounded ring channel of its own instead, so a
flood on one key is cut by Zenoh before it costs Python anything. It publishes its ω to the vehicles listening to
it, its telemetry in batches and its counters to the world, and declares a liveliness
token once it is ready.

- lockstep: it steps tick n once the world has granted it (a grant is a horizon, often
  hundreds of ticks) and it holds every live neighbour's newest broadcast that tick n can
  use (cdus.core.node.VehicleNode.waiting_for: with broadcasts slower than the control loop
  or a least link delay, several ticks ahead of what the neighbours have sent), so each
  vehicle steps as far as its inputs allow, and the run is deterministic and equal to the
  in-process one, whatever the scheduling.
  Scheduled faults are the roster every runner derives from the scenario; the world
  relays the unscheduled ones (a crash, a ground station's kill) with their tick.
- realtime: it steps on the wall clock from the world's start time t0, tick n at
  t0 + n T, with whatever has arrived; a tick finishing after the next was due is a
  missed deadline. A small waker thread pokes the channel at each tick time (and on
  SIGTERM/SIGINT, so a signal is never stuck behind a blocking wait).

Everything received is validated (cdus.wire.messages, then cdus.core.node for ω and
:meth:`Agent._ctl_problem` for the world's control maps) and counted by reason when
rejected (stale duplicates too), with one log line per sender and reason. ω is accepted
only within a window of what its sender can have sent (:meth:`Agent._horizon`). Work per
sender is bounded: in realtime, ω beyond what a sender can send (its broadcast rate times
:data:`RATE_MARGIN`, bursts of :data:`RATE_BURST`) is dropped before it is decoded
(``rate``); the inbox is a bounded channel (:data:`INBOX_CAPACITY`).
"""

from __future__ import annotations

import random
import signal
import sys
import time
from collections import Counter, deque
from typing import Any, Callable

import zenoh

from cdus.core.link import burst_events
from cdus.core.node import VehicleNode
from cdus.core.radiolink import as_point
from cdus.core.vehicle import DivergedError
from cdus.scenario.model import Scenario
from cdus.sim.build import build_node, link_emulator_for, link_faults_of, listeners_of, with_radio
from cdus.sim.sensing import contacts_of
from cdus.core.schedule import total_ticks
from cdus.sim.lockstep import MAX_GRANT_WINDOW
from cdus.wire.text import printable
from cdus.wire import keys
from cdus.wire.messages import (
    MAX_STATE_ROWS, StateMsg, decode_contacts, decode_geometry, decode_omega,
    decode_states, encode_omega, encode_states,
)
from cdus.wire.schemas import AgentStats, encode_stats
from cdus.wire.transport import Transport, open_session
from vehicle_agent.clocks import Clock, pick
from vehicle_agent.control import Control
from vehicle_agent.lockstep import LOG_WAIT
from vehicle_agent.realtime import OMEGA_RING
from vehicle_agent.waker import Waker

STATS_PERIOD = 1.0  # s of wall time between counter reports
BURSTS_PER_STATS = 100  # drop bursts one report carries; a report goes early once half as many wait
END_WAIT = 10.0  # s to wait for the world's stop after the last tick
_KINDS = ("omega", "state", "stats", "ctl", "contacts", "cmd", "wake", "last")  # named in a reject reason
MAX_LOGGED = 256  # (sender, reason) pairs logged; past that, rejects are only counted
#: lockstep: when this session was cut off from the router (the world's liveliness token went and
#: came back: a router frozen or restarted, a network cut), what was in flight may be lost and
#: the fleet would wait for it: the agent says its newest ω and telemetry again (receivers take
#: what they missed and drop what they have as a duplicate)
#: the newest ω said again, at least: a sender runs ahead of what a listener holds by up to its
#: lookahead (a least link delay of D ticks lets it step D ticks past its neighbours' newest ω) and,
#: on a one-way link, a grant window; the agent keeps 2 x MAX_GRANT_WINDOW ticks' worth (Agent.__init__)
RESEND_OMEGAS = 16
#: said again every lockstep.RESEND_EVERY s while stuck, for RESEND_FOR s after the world's token came back:
#: the token can arrive before the router knows the neighbours' subscriptions again, and what is
#: said before that is lost too
RESEND_FOR = 10.0
WORLD_BACK = "the world's token is back after every world token went (an outage)"  # logged when taken
PING_TIMEOUT = 1.0  # s for a link check's reply (it is immediate when nobody answers)
PING_RETRY = 0.02  # s between link checks
#: the ω publisher's express flag (Zenoh: sent at once, never held for a batch); compared in the
#: same run by bench/omega_latency.py
OMEGA_EXPRESS = False


class Agent:
    def __init__(self, scenario: Scenario, vid: str, fleet: str, transport: Transport, clock: str = "realtime",
                 policy: str | None = None, duration: float | None = None, log: Callable[[str], None] | None = None,
                 rejoin: bool = False):
        self.scenario = scenario
        self.id = vid
        self.fleet = keys.check_fleet(fleet)
        self.transport = transport
        self.loop = pick(clock, scenario.rates.broadcast)  # the clock's strategy: chosen here, once
        self.rejoin = rejoin  # a restart: listeners that are not alive are not waited for
        self.listeners = listeners_of(scenario, vid)
        self.ids = list(scenario.ids)
        self._dims = [v.dim for v in scenario.vehicles]  # the world sends a boat 2 coordinates, a drone 3
        self.index = self.ids.index(vid)
        self.period = 1.0 / scenario.rates.control
        self.last_tick = total_ticks(scenario.duration if duration is None else duration, self.period)
        link = with_radio(scenario, link_emulator_for(scenario))  # [radio]: the channel under the link faults
        self.node: VehicleNode = build_node(scenario, vid, link, policy=policy, last_tick=self.last_tick)
        self.loop.plan(self)
        self.clock = Clock()
        self.control = Control(self)  # the world's control messages: clock, roster, run-time commands
        self.rejected: Counter = Counter()  # by reason, every reject (the node's ω ones too, but "gone")
        self._rings: list[tuple[int, Any]] = []  # realtime: (neighbour, its ω subscription: a ring channel)
        self._logged: set[tuple[str, str]] = set()
        self._states: list[StateMsg] = []
        self._resend_until = 0.0  # lockstep, monotonic s: back from an outage, say recent messages again till then
        self._resent_at = 0.0
        self._world_seen = None
        self._token_news: deque[tuple[str, bool]] = deque()  # the world's liveliness (Zenoh's thread -> main)
        self._world_tokens: set[str] = set()  # the session ids of the world's tokens up
        self._world_left = False  # every world token went (this session was cut off): their return is news
        self._last_omegas: deque[bytes] = deque(  # lockstep: said again after an outage
            maxlen=max(RESEND_OMEGAS, 2 * MAX_GRANT_WINDOW // self.node.every + 2))
        #: telemetry sent, newest last: as much as the world can lack after an outage (this vehicle
        #: runs up to a grant window past the world's newest row of the slowest vehicle)
        self._recent: deque[StateMsg] = deque(maxlen=MAX_GRANT_WINDOW + MAX_STATE_ROWS)
        self.missed_deadlines = 0
        self.ticks_done = 0
        self._lat_sent = 0
        self._last_stats = 0.0
        self._stats_tick = -1  # ticks_done when the counters were last published
        self.log = log or (lambda s: print(f"[{vid}] {s}", flush=True))
        self.session: Any = None
        self.token: Any = None
        self.waker: Waker | None = None
        self.stop_requested = False  # by a signal
        self.cpu_s = 0.0  # CPU time of the process over the run (start to last tick)
        self.incarnation = random.SystemRandom().getrandbits(31)  # tells the world a restart's counters apart

    # ------------------------------------------------------------------ zenoh wiring
    def open(self) -> None:
        s = self.session = open_session(self.transport)
        f, me = self.fleet, self.id
        # the exact key each neighbour's ω arrives on (its listener set is known): no parsing
        self._omega_from = {keys.omega(f, self.ids[k], listeners_of(self.scenario, self.ids[k])): k
                            for k in self.node.neighbours}
        self.inbox, self._rings = self.loop.subscribe(s, f, me, self._omega_from)
        # declared after the subscriptions, on the same session: whoever gets a reply holds them
        self.pinged = s.declare_queryable(keys.ping(f, me), lambda q: q.reply(keys.ping(f, me), b""))
        # Block rather than drop under congestion: losses are the link emulator's job, and a
        # lockstep neighbour waits for every broadcast.
        block = zenoh.CongestionControl.BLOCK
        self.pub_omega = s.declare_publisher(keys.omega(f, me, listeners_of(self.scenario, me)),
                                             congestion_control=block, express=OMEGA_EXPRESS)
        self.pub_state = s.declare_publisher(keys.state(f, me), congestion_control=block)
        self.pub_stats = s.declare_publisher(keys.stats(f, me), congestion_control=block)  # the last one is the metrics'
        wake = s.declare_publisher(keys.wake(f, me), allowed_destination=zenoh.Locality.SESSION_LOCAL)
        self.waker = Waker(lambda: wake.put(b""), self.period)
        self.waker.start()
        self._await_links()
        # Ready: the subscription is in place and every listener can hear us. The token tells
        # the world and the launcher.
        self.token = s.liveliness().declare_token(keys.alive(f, me, str(s.zid())))
        self._world_seen = self.loop.watch_world(s, f, self._on_world_token)
        spec = self.scenario.vehicle(me)
        self.log(f"ready: {spec.kind} on a {dict(spec.path)['family']} path, "
                 f"neighbours {[self.ids[k] for k in self.node.neighbours]}, clock {self.loop.name}")

    def _await_links(self) -> None:
        """Wait until every vehicle listening to this one can hear it.

        With direct links between neighbours (peer sessions, ``cdus launch --links direct``) a
        message only reaches a neighbour once the link is up and the neighbour's subscription
        has crossed it; the router does not relay between peers. A ping reply from the
        neighbour's queryable, declared after its subscription on the same session, proves
        both. Through the router it costs one round trip. A restarted process (``--rejoin``)
        does not wait for listeners that are not alive (their liveliness token is absent).
        """
        s, f = self.session, self.fleet
        waiting = list(self.listeners)
        since = time.monotonic()
        while waiting and not self.stop_requested:
            for vid in list(waiting):
                if any(r.ok is not None for r in s.get(keys.ping(f, vid), timeout=PING_TIMEOUT)):
                    waiting.remove(vid)
                elif self.rejoin and not any(r.ok is not None and keys.alive_name(str(r.ok.key_expr)) == vid for r in
                                             s.liveliness().get(keys.alive_of(f, vid), timeout=PING_TIMEOUT)):
                    self.log(f"listener {vid} is not alive: not waiting for it")
                    waiting.remove(vid)
            if waiting:
                if time.monotonic() - since > LOG_WAIT:
                    since = time.monotonic()
                    self.log(f"waiting for the link to {', '.join(waiting)}"
                             + ("" if self.rejoin else " (a process joining a run under way takes --rejoin)"))
                time.sleep(PING_RETRY)

    def close(self) -> None:
        if self.waker is not None:
            self.waker.close()
            self.waker = None
        if self.session is None:
            return
        try:
            self.publish_stats()
            if self.token is not None:
                self.token.undeclare()
            self.session.close()
        except zenoh.ZError as e:  # closing must never hide the run's own outcome
            self.log(f"while closing the session: {e}")
        self.session = None

    def request_stop(self) -> None:
        """From a signal handler: the main loop ends at its next wake-up (the waker makes one)."""
        self.stop_requested = True

    # ------------------------------------------------------------------ receiving
    def _reject(self, sender: str, reason: str) -> None:
        self.rejected[reason] += 1
        if (sender, reason) not in self._logged and len(self._logged) < MAX_LOGGED:  # once per sender, reason
            self._logged.add((sender, reason))
            self.log(f"rejected a message from {printable(sender, 64)!r}: {reason} (counted; logged once)")

    def _handle(self, sample: Any, now: float | None) -> None:
        """One sample from the inbox. ``now``: simulated arrival time (realtime) or None."""
        key = str(sample.key_expr)
        k = self._omega_from.get(key)
        if k is not None:
            return self._omega(k, sample, now)
        if key.endswith("/ctl"):
            return self._on_ctl(sample.payload.to_bytes())
        if key.endswith("/contacts"):
            return self._on_contacts(sample.payload.to_bytes())
        if key.endswith("/radio"):
            return self._on_geometry(sample.payload.to_bytes())
        if key.endswith("/wake"):
            return
        kind, src = keys.leaf(key)
        self._reject(src or key, "unexpected_" + (kind if kind in _KINDS else "key"))

    def _omega(self, k: int, sample: Any, now: float | None) -> None:
        """An ω sample on neighbour ``k``'s key (the inbox's, or its realtime ring's)."""
        if self.loop.over_rate(k):  # before decoding: a flood costs a lookup and a subtraction
            return self._reject(self.ids[k], "rate")
        msg = decode_omega(sample.payload.to_bytes(), expected_sender=k, n_vehicles=len(self.ids))
        if isinstance(msg, str):
            return self._reject(self.ids[k], msg)
        self.node.horizon = self.loop.horizon(self.clock, self.period, self.rejoin)
        reason = self.node.on_message(msg, now)
        if reason is not None:
            self._reject(self.ids[k], reason)
        else:
            self.loop.refund(k)

    def _on_ctl(self, payload: bytes) -> None:
        """A control message from the world (vehicle_agent.control): a refusal counted by its reason."""
        outcome = self.control.take(payload)
        if outcome.reason is None:
            return
        if outcome.detail is None:
            return self._reject("world", outcome.reason)
        self.rejected[outcome.reason] += 1
        self.log(printable(outcome.detail, 240))

    def _on_contacts(self, payload: bytes) -> None:
        """The world's proximity sensor: this vehicle's contacts of a sample tick (counted and
        dropped if malformed)."""
        msg = decode_contacts(payload, len(self.ids), self.index, self.node.vehicle.dim)
        if isinstance(msg, str):
            return self._reject("world", f"contacts_{msg}")
        if msg.tick > self.last_tick:  # no sample is taken past the run's end: kept, it would never be freed
            return self._reject("world", "contacts_range")
        self.node.on_contacts(msg.tick, contacts_of(msg, self.ids))

    def _on_geometry(self, payload: bytes) -> None:
        """The world's radio geometry sample (cdus.sim.radio): counted and dropped if malformed, out
        of the run, not on the sample schedule, without [radio], or a second one for its tick
        (the first stands: ``radio_stale`` if it is the same, ``radio_conflict`` if not)."""
        radio = self.node.radio
        if radio is None:
            return self._reject("world", "radio_unexpected")
        msg = decode_geometry(payload, len(self.ids), self._dims)
        if isinstance(msg, str):
            return self._reject("world", f"radio_{msg}")
        if msg.tick > self.last_tick:
            return self._reject("world", "radio_range")
        if msg.tick % radio.every:
            return self._reject("world", "radio_tick")
        if not self.node.on_geometry(msg.tick, msg.positions):
            # the world says a sample again only to a (re)joining process, with the same bytes: a
            # second, different sample for a tick is someone else's (an open fleet): the first stands
            held = radio.held(msg.tick)
            same = held is not None and held.positions == tuple(None if q is None else as_point(q)
                                                                for q in msg.positions)
            self._reject("world", "radio_stale" if same else "radio_conflict")

    def _recv(self, now: Callable[[], float | None]) -> None:
        """Block for the next sample, then take everything else that is waiting."""
        handle = self._handle
        handle(self.inbox.recv(), now())
        self._drain(now)

    def _drain(self, now: Callable[[], float | None]) -> None:
        while (sample := self.inbox.try_recv()) is not None:
            self._handle(sample, now())
        if self._token_news:
            self._world_token_news()
        omega = self._omega
        for k, ring in self._rings:  # realtime ω: at most OMEGA_RING each, the sender known by its ring
            for _ in range(OMEGA_RING):
                if (sample := ring.try_recv()) is None:
                    break
                omega(k, sample, now())

    def _stopping(self) -> bool:
        return self.clock.stop or self.stop_requested

    # ------------------------------------------------------------------ the loop
    def run(self) -> int:
        """Step to the last tick (or a stop). Returns the number of ticks stepped."""
        cpu0 = time.process_time()
        self.loop.run(self)
        self.cpu_s = time.process_time() - cpu0  # every thread of the process, Zenoh's included
        self._await_stop()
        return self.ticks_done

    def _tick(self, n: int) -> None:
        out = self.node.step(n)
        if out.omega is not None:  # ω before telemetry: whoever saw tick n can count on it
            wire = encode_omega(out.omega)
            self._last_omegas.append(wire)
            self.pub_omega.put(wire)
        tel = out.telemetry
        self._states.append(StateMsg(self.index, n, tel.t, tuple(tel.q), tel.heading, tel.speed,
                                     tel.omega, tel.omega_rate, tel.path_error))
        if len(self._states) >= self.loop.state_batch or n >= self.last_tick:
            self.flush_states()
        self.ticks_done = n + 1
        now = time.monotonic()
        bursts = self.node.bursts
        if now - self._last_stats > STATS_PERIOD or len(bursts.done) - bursts.reported >= BURSTS_PER_STATS // 2:
            self._last_stats = now
            self.publish_stats()

    def _rejoin(self, tick: int) -> None:
        """Join a run under way at ``tick``: where the world last saw this vehicle, with ω near
        what its neighbours' consensus asks (not laps away)."""
        last: dict[int, StateMsg] = {}
        for j in [self.index, *self.node.neighbours]:
            for reply in self.session.get(keys.world_last(self.fleet, self.ids[j]), timeout=2.0):
                if reply.ok is None:
                    continue
                rows = decode_states(reply.ok.payload.to_bytes(), len(self.ids))
                if not isinstance(rows, str) and rows[0].sender == j:
                    last[j] = rows[-1]
        mine = last.pop(self.index, None)
        omegas = {k: m.omega for k, m in last.items()}
        self.node.rejoin(tick, mine.q if mine else None, mine.heading if mine else None,
                         mine.omega if mine else None, omegas)
        where = (f"its last known state q = {tuple(round(x, 2) for x in mine.q)}" if mine
                 else "the configured start (no last state known)")
        self.log(f"rejoining at tick {tick} (t = {tick * self.period:.2f} s) from {where}, "
                 f"ω = {self.node.vehicle.omega:.3f}" + (" (near its neighbours' consensus)" if omegas else ""))

    def _report_rows(self) -> None:
        """Lockstep, waiting for the world: the counters, then the rows held. The world carries out
        a vehicle fault at tick K once every live vehicle has reported K - 1, so a killed process's
        counters then cover the messages its node decided (those sent before K - 1, as the
        in-process fleet's node decides them): the run's per-link counters are whole after a kill.
        Once per wait with ticks stepped since the last report: a grant wait is rare (the grant
        runs a window ahead of the slowest vehicle), the once-a-second report the rest."""
        if self._stats_tick != self.ticks_done:
            self.publish_stats()
        self.flush_states()

    def flush_states(self) -> None:
        if self._states and self.session is not None:
            self.pub_state.put(encode_states(self._states))
            self._recent.extend(self._states)
        self._states = []

    def _on_world_token(self, sample: Any) -> None:
        """Liveliness of the world as this session sees it (Zenoh's thread): handed to the main
        thread (:meth:`_world_token_news`), which a wake fetches."""
        self._token_news.append((str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))
        self._wake()

    def _world_token_news(self) -> None:
        """The world's tokens coming back after every one of them went means this session was
        cut off from the router and is back, and what was in flight then may be lost: the
        recent messages are said again (RESEND_FOR). Only a token on exactly the world's key
        (``alive/world/<zid>``) counts: one on a key expression that intersects it (``alive/**``,
        anyone's) is counted (``token_key``) and ignored, and so is a second world token while
        one is up (``token_extra``: its coming and going is no news of this session's link)."""
        while self._token_news:
            key, up = self._token_news.popleft()
            token = keys.alive_token(key)
            if token is None or token[0] != keys.WORLD:
                if up:  # counted once, when it comes
                    self._reject(key, "token_key")
                continue
            zid, tokens = token[1], self._world_tokens
            if not up:
                if zid in tokens:
                    tokens.discard(zid)
                    self._world_left |= not tokens
                continue
            if zid in tokens:
                continue
            if tokens:
                self._reject("world", "token_extra")
            elif self._world_left:
                self._world_left = False
                self._resend_until = time.monotonic() + RESEND_FOR
                self.log(f"{WORLD_BACK}: saying recent messages again for {RESEND_FOR:g} s")
            tokens.add(zid)

    def _wake(self) -> None:
        if self.waker is not None:
            self.waker.poke()

    def _resend(self) -> None:
        """Lockstep, back from an outage: say the last ω messages and the recent telemetry again:
        a receiver that lost one in flight (a router outage) takes it as a gap filled, the
        others drop the copies as stale."""
        if self.session is None:
            return
        for wire in self._last_omegas:
            self.pub_omega.put(wire)
        rows = list(self._recent)
        for first in range(0, len(rows), MAX_STATE_ROWS):  # in messages the world takes
            self.pub_state.put(encode_states(rows[first:first + MAX_STATE_ROWS]))

    def stats(self) -> AgentStats:
        node, c = self.node, self.node.counters
        by_reason = dict(self.rejected)
        if node.rejected["gone"]:  # counted by the node when a message is offered (in c.rejected)
            by_reason["gone"] = node.rejected["gone"]
        emulator = link_faults_of(node.link)
        faults = emulator.counters_summary() if emulator is not None else None
        if faults is not None:
            faults["state_changes"] = faults["state_changes"][-50:]  # the newest; the world keeps the history
        new = c.latencies[min(self._lat_sent, len(c.latencies)):]  # the sample list may have been thinned
        self._lat_sent = len(c.latencies)
        step = max(1, len(new) // 100)
        return AgentStats(
            id=self.id, tick=self.ticks_done, sent_to_me=c.sent, delivered=c.delivered, dropped=c.dropped,
            duplicated=c.duplicated, rejected=c.rejected + sum(self.rejected.values()),
            rejected_by_reason=by_reason, missed_deadlines=self.missed_deadlines, joined_at=node.joined_at,
            latencies_ms=tuple(x * 1000.0 for x in new[::step][:100]), faults=faults,
            bursts=tuple(e.as_dict() for e in burst_events(node.bursts, self.ids)[-BURSTS_PER_STATS:]),
            interventions=node.vehicle.interventions, incarnation=self.incarnation,
            radio=None if node.radio is None else node.radio.counters.as_dict())

    def publish_stats(self) -> None:
        if self.session is not None:
            self.pub_stats.put(encode_stats(self.stats()))
            self._stats_tick = self.ticks_done

    def _await_stop(self) -> None:
        """After the last tick, wait for the world's stop so it has received everything."""
        self.flush_states()
        self.publish_stats()
        assert self.waker is not None
        deadline = time.time() + END_WAIT
        self.waker.alarm = deadline
        self.waker.interrupt()
        never: Callable[[], None] = lambda: None
        while not self._stopping() and time.time() < deadline:
            self._recv(never)




def run_agent(agent: Agent) -> int:
    """Open, run, close; SIGTERM and SIGINT end the run cleanly."""
    def _stop(signum, frame):
        agent.request_stop()

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    try:
        agent.open()
        assert agent.waker is not None
        signal.set_wakeup_fd(agent.waker.wfd)  # a signal wakes the waker, which wakes the main loop
        try:
            ticks = agent.run()
        except DivergedError as e:  # the simulation cannot go on: say so once, plainly, and fail
            agent.log(f"error: {e}")
            return 1
        per_tick = f" ({agent.cpu_s / ticks * 1e6:.0f} µs per tick)" if ticks else ""
        agent.log(f"done after {ticks} ticks; missed deadlines {agent.missed_deadlines}; "
                  f"rejected {dict(agent.rejected) or 0}; CPU in the run {agent.cpu_s:.2f} s{per_tick}")
        return 0
    finally:
        signal.set_wakeup_fd(-1)
        agent.close()
        sys.stdout.flush()

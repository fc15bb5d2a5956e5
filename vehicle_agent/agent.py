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

import math
import os
import random
import select
import signal
import sys
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass
from typing import Any, Callable

import zenoh

from cdus.core.events import RosterChange, event_tick, plan_roster
from cdus.core.link import burst_events
from cdus.core.node import VehicleNode, gains_problem
from cdus.core.radiolink import as_point
from cdus.core.vehicle import DivergedError
from cdus.scenario.config import ConfigError, nesting_problem
from cdus.scenario.model import Scenario
from cdus.scenario.link import merge_link_tables, validate_link
from cdus.scenario.events import check_path, check_phases
from cdus.sim.build import build_node, link_emulator_for, link_faults_of, listeners_of, with_radio
from cdus.sim.radio import apply_radio_change, radio_change_problem
from cdus.sim.sensing import contacts_of
from cdus.core.schedule import CLOCKS, total_ticks
from cdus.sim.lockstep import GRANT_WINDOW, MAX_GRANT_WINDOW
from cdus.wire.text import printable
from cdus.wire import keys
from cdus.wire.rejected import Rejected
from cdus.wire.messages import (
    CTL_OPS, MAX_LINK_AT, MAX_STATE_ROWS, StateMsg, decode_contacts, decode_control, decode_geometry, decode_omega,
    decode_states, encode_omega, encode_states,
)
from cdus.wire.schemas import AgentStats, encode_stats
from cdus.wire.transport import Transport, open_session

#: telemetry rows per message. Lockstep: at most GRANT_WINDOW, the least grant window: a vehicle
#: waiting for a neighbour's ω holds fewer unsent rows than the window, so that neighbour is
#: always granted its tick (and one waiting for a grant sends what it holds at once)
STATE_BATCH = {"lockstep": 50, "realtime": 5}
assert STATE_BATCH["lockstep"] <= GRANT_WINDOW
STATS_PERIOD = 1.0  # s of wall time between counter reports
BURSTS_PER_STATS = 100  # drop bursts one report carries; a report goes early once half as many wait
STALL_TICKS = 10  # realtime: this many periods late means the process was frozen, not just slow
END_WAIT = 10.0  # s to wait for the world's stop after the last tick
INBOX_CAPACITY = 4096  # samples; when full, Zenoh's delivery to this session waits (nothing grows)
OMEGA_RING = 16  # realtime: ω samples kept per neighbour between drains (<= MAX_NAP apart), newest first
#: lockstep: a neighbour may have a grant this agent has not received yet; one grant moves at
#: most MAX_GRANT_WINDOW past the slowest live vehicle's acknowledged tick, which is <= ours
LOCKSTEP_SEQ_MARGIN = 2 * MAX_GRANT_WINDOW
REALTIME_SLACK = 0.25  # s: a realtime ω may be stamped this far past this agent's wall-clock tick
T0_PAST = 86400.0  # s: a realtime t0 (start, resume) older than the run's duration plus this is not ours
T0_AHEAD = 60.0  # s: ... nor one further in the future than this
RATE_MARGIN = 4.0  # realtime: a sender's ω rate allowed, in multiples of its broadcast rate
RATE_BURST = 64  # realtime: ω a sender may send back to back (a stall's catch-up is < STALL_TICKS)
_KINDS = ("omega", "state", "stats", "ctl", "contacts", "cmd", "wake", "last")  # named in a reject reason
MAX_LOGGED = 256  # (sender, reason) pairs logged; past that, rejects are only counted
MAX_COMMAND_NESTING = 2  # a link or gains table nests its containers at most this deep (delay = {...})
LOG_WAIT = 5.0  # s of waiting before saying what for
#: lockstep: when this session was cut off from the router (the world's liveliness token went and
#: came back: a router frozen or restarted, a network cut), what was in flight may be lost and
#: the fleet would wait for it: the agent says its newest ω and telemetry again (receivers take
#: what they missed and drop what they have as a duplicate)
#: the newest ω said again, at least: a sender runs ahead of what a listener holds by up to its
#: lookahead (a least link delay of D ticks lets it step D ticks past its neighbours' newest ω) and,
#: on a one-way link, a grant window; the agent keeps 2 x MAX_GRANT_WINDOW ticks' worth (Agent.__init__)
RESEND_OMEGAS = 16
#: said again every RESEND_EVERY s while stuck, for RESEND_FOR s after the world's token came back:
#: the token can arrive before the router knows the neighbours' subscriptions again, and what is
#: said before that is lost too
RESEND_EVERY = 1.0
RESEND_FOR = 10.0
WORLD_BACK = "the world's token is back after every world token went (an outage)"  # logged when taken
#: lockstep: granted and still waiting for a neighbour's ω this long (s), the agent says its recent
#: messages again every RESEND_EVERY s (receivers drop copies as stale): a router frozen for
#: seconds can lose messages in flight without any session seeing the world's token go and come back
STUCK_RESEND = 2.0
MAX_NAP = 0.05  # s: realtime sleeps at most this long between checks for a stop or a pause
PING_TIMEOUT = 1.0  # s for a link check's reply (it is immediate when nobody answers)
PING_RETRY = 0.02  # s between link checks
#: the ω publisher's express flag (Zenoh: sent at once, never held for a batch); compared in the
#: same run by bench/omega_latency.py
OMEGA_EXPRESS = False


@dataclass
class Clock:
    """What the world has said about time: grants (lockstep) or t0 (realtime)."""

    begun: bool = False  # lockstep: the run started (at tick 0) or we were told where to join
    join: int = 0
    granted: int = -1
    t0: float | None = None
    paused: bool = False
    stop: bool = False


class Waker(threading.Thread):
    """Pokes the agent's own inbox (a session-local put) so its blocking wait returns: at every
    tick time ``t0 + n T`` of the realtime clock (when ``t0`` is set), at an ``alarm``, and
    when a signal arrives (``signal.set_wakeup_fd(waker.wfd)``)."""

    def __init__(self, put: Callable[[], None], period: float):
        super().__init__(daemon=True, name="waker")
        self.put = put
        self.period = period
        self.t0: float | None = None  # the realtime clock's origin (wall s), None: no ticking
        self.alarm: float | None = None
        self.closed = False
        self.rfd, self.wfd = os.pipe()
        os.set_blocking(self.wfd, False)

    def interrupt(self) -> None:
        """Re-read t0 and the alarm now."""
        os.write(self.wfd, b"\xff")

    def close(self) -> None:
        self.closed = True
        self.interrupt()

    def _deadline(self, now: float) -> float | None:
        t0, alarm = self.t0, self.alarm
        tick = None if t0 is None else t0 + (math.floor((now - t0) / self.period) + 1) * self.period
        return min((d for d in (tick, alarm) if d is not None), default=None)

    def run(self) -> None:
        while not self.closed:
            now = time.time()
            deadline = self._deadline(now)
            ready, _, _ = select.select([self.rfd], [], [], None if deadline is None else max(0.0, deadline - now))
            if ready:
                data = os.read(self.rfd, 64)
                if data.strip(b"\xff") and not self.poke():  # a signal number: wake the main thread
                    return
                continue
            while time.time() < deadline:  # never early: the main loop compares with the same clock
                time.sleep(deadline - time.time())
            if self.alarm is not None and time.time() >= self.alarm:
                self.alarm = None
            if not self.poke():
                return

    def poke(self) -> bool:
        """Wake the main loop; False once the session is closed (the agent is exiting)."""
        try:
            self.put()
        except zenoh.ZError:
            return False
        return True


class Agent:
    def __init__(self, scenario: Scenario, vid: str, fleet: str, transport: Transport, clock: str = "realtime",
                 policy: str | None = None, duration: float | None = None, log: Callable[[str], None] | None = None,
                 rejoin: bool = False):
        if clock not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {clock!r}")
        self.scenario = scenario
        self.id = vid
        self.fleet = keys.check_fleet(fleet)
        self.transport = transport
        self.clock_mode = clock
        self.rejoin = rejoin  # a restart: listeners that are not alive are not waited for
        self.listeners = listeners_of(scenario, vid)
        self.ids = list(scenario.ids)
        self._dims = [v.dim for v in scenario.vehicles]  # the world sends a boat 2 coordinates, a drone 3
        self.index = self.ids.index(vid)
        self.period = 1.0 / scenario.rates.control
        self.last_tick = total_ticks(scenario.duration if duration is None else duration, self.period)
        link = with_radio(scenario, link_emulator_for(scenario))  # [radio]: the channel under the link faults
        self.node: VehicleNode = build_node(scenario, vid, link, policy=policy, last_tick=self.last_tick)
        if clock == "lockstep":  # scheduled faults land on their ticks; realtime hears of them by liveliness
            for change in plan_roster(scenario.events, self.ids, self.period):
                self.node.on_roster(change)
        self.link_table: dict = scenario.link_table
        self.clock = Clock()
        self.state_batch = STATE_BATCH[clock]
        self.rejected: Counter = Counter()  # by reason, every reject (the node's ω ones too, but "gone")
        self._commands_seen: set[int] = set()  # the world's run-time commands applied, by their seq
        self.commands_heard_again = 0  # replays of those (a catch-up said again): not applied twice
        self._rings: list[tuple[int, Any]] = []  # realtime: (neighbour, its ω subscription: a ring channel)
        self._bucket: dict[int, tuple[float, float]] = {}  # realtime ω rate per neighbour: (tokens, when)
        self._rate = RATE_MARGIN * scenario.rates.broadcast  # ω per s a neighbour may send
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
        if self.clock_mode == "lockstep":  # one FIFO for everything: a genuine message is never lost
            self.inbox = s.declare_subscriber(keys.inbox(f, me), zenoh.handlers.FifoChannel(INBOX_CAPACITY))
        else:
            # Realtime: the world's one-chunk keys (ctl, contacts, wake) through the FIFO, each
            # neighbour's ω through a ring of its own that Zenoh overwrites oldest first, so a
            # flood on one key costs this process at most OMEGA_RING samples per drain, not one
            # Python wake-up per message (the newest ω is the one that matters).
            self.inbox = s.declare_subscriber(keys.inbox(f, me)[:-2] + "*", zenoh.handlers.FifoChannel(INBOX_CAPACITY))
            self._rings = [(k, s.declare_subscriber(key, zenoh.handlers.RingChannel(OMEGA_RING)))
                           for key, k in self._omega_from.items()]
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
        if self.clock_mode == "lockstep":  # the world's token back: this session was cut off (an outage)
            self._world_seen = s.liveliness().declare_subscriber(keys.alive_of(f, keys.WORLD), self._on_world_token,
                                                                 history=True)
        spec = self.scenario.vehicle(me)
        self.log(f"ready: {spec.kind} on a {dict(spec.path)['family']} path, "
                 f"neighbours {[self.ids[k] for k in self.node.neighbours]}, clock {self.clock_mode}")

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

    def _horizon(self) -> int | None:
        """The newest tick a genuine neighbour can have broadcast at, as this agent knows time:
        lockstep, its grant (or join) plus :data:`LOCKSTEP_SEQ_MARGIN`; realtime, its wall-clock
        tick plus :data:`REALTIME_SLACK` (from tick 0 while the start is not known)."""
        clock = self.clock
        if self.rejoin and not (clock.begun if self.clock_mode == "lockstep" else clock.t0 is not None):
            return None  # a restart that does not know where the run is yet: the run's last tick bounds
        if self.clock_mode == "lockstep":
            return max(clock.granted, clock.join) + LOCKSTEP_SEQ_MARGIN
        slack = math.ceil(REALTIME_SLACK / self.period)
        if clock.t0 is None:
            return slack
        return max(0, math.floor((time.time() - clock.t0) / self.period)) + slack

    def _over_rate(self, k: int) -> bool:
        """Realtime: has neighbour ``k`` sent more than it can (a token bucket at RATE_MARGIN times
        its broadcast rate, RATE_BURST deep)? Lockstep takes everything: a genuine message is
        never dropped there, and a sender's ω is bounded by the grant window."""
        if self.clock_mode != "realtime":
            return False
        now = time.monotonic()
        tokens, last = self._bucket.get(k, (float(RATE_BURST), now))
        tokens = min(float(RATE_BURST), tokens + (now - last) * self._rate)
        if tokens < 1.0:
            self._bucket[k] = (tokens, now)
            return True
        self._bucket[k] = (tokens - 1.0, now)
        return False

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
        if self._over_rate(k):  # before decoding: a flood costs a lookup and a subtraction
            return self._reject(self.ids[k], "rate")
        msg = decode_omega(sample.payload.to_bytes(), expected_sender=k, n_vehicles=len(self.ids))
        if isinstance(msg, Rejected):
            return self._reject(self.ids[k], msg.reason)
        self.node.horizon = self._horizon()
        reason = self.node.on_message(msg, now)
        if reason is not None:
            self._reject(self.ids[k], reason)
        elif k in self._bucket:  # only what is rejected spends a sender's budget
            tokens, when = self._bucket[k]
            self._bucket[k] = (min(float(RATE_BURST), tokens + 1.0), when)

    def _ctl_problem(self, op: str, f: dict) -> str | None:
        """What is out of range in a control message from the world (None: nothing): ticks within
        the run, a grant not past its last tick, a realtime t0 near now, a known roster vehicle."""
        last = self.last_tick
        if op == "grant" and not 0 <= f["until"] <= last:
            return "grant_range"
        if op == "join" and not 0 <= f["tick"] <= last:
            return "join_range"
        if op == "gains" and not 0 <= f["tick"] < 2**31:  # past the run's end it never applies: harmless
            return "gains_range"
        if op == "roster" and (f["vehicle"] not in self.ids or f["state"] not in ("live", "paused", "gone")
                               or not 0 <= f["tick"] <= last + 1):
            return "bad_roster"
        if op in ("start", "resume"):
            now = time.time()
            if not now - T0_PAST - last * self.period <= f["t0"] <= now + T0_AHEAD:
                return "t0_range"
        # a radio command's own reason: radio_range is the geometry's (a coordinate or a tick out of range)
        name = "radio_command" if op == "radio" else op
        if op in ("link", "radio") and not 0.0 <= f["at"] <= MAX_LINK_AT:
            return f"{name}_range"
        if op in ("link", "gains", "radio") and nesting_problem(f[op], MAX_COMMAND_NESTING):
            return f"{name}_range"
        if op in ("formation", "path"):
            return self._change_problem(op, f)
        return None

    def _change_problem(self, op: str, f: dict) -> str | None:
        """A formation or path change's tick and shape (its contents: :meth:`_set_formation`,
        :meth:`_set_path`)."""
        if not 0 <= f["tick"] < 2**31:  # past the run's end it never applies: harmless
            return f"{op}_range"
        if nesting_problem(f[op if op == "path" else "phases"], MAX_COMMAND_NESTING):
            return f"{op}_range"
        if op == "path" and f["vehicle"] != self.id:
            return "path_vehicle"  # the world sends a path to its vehicle only
        return None

    def _on_ctl(self, payload: bytes) -> None:
        c = decode_control(payload, CTL_OPS)
        if isinstance(c, str):
            return self._reject("world", c)
        op, f = c.op, c.fields
        problem = self._ctl_problem(op, f)
        if problem is not None:
            return self._reject("world", problem)
        seq = f.get("seq")
        if seq is not None:  # a numbered run-time command: once, however often it is heard
            if seq in self._commands_seen:
                self.commands_heard_again += 1
                return None
            # only a command applied uses its number: a refused one (counted) would else lock the
            # world's own command with that number out (an open fleet: anyone may publish first)
            refused = sum(self.rejected.values())
            self._apply_ctl(op, f)
            if sum(self.rejected.values()) == refused:
                self._commands_seen.add(seq)
            return None
        self._apply_ctl(op, f)

    def _apply_ctl(self, op: str, f: dict) -> None:
        clock = self.clock
        if op == "grant":
            clock.granted = max(clock.granted, f["until"])
        elif op == "join":
            clock.begun, clock.join = True, f["tick"]
        elif op == "start":
            clock.t0 = f["t0"]
        elif op == "roster":
            self._on_roster(f)
        elif op == "pause":
            clock.paused = True
        elif op == "resume":
            clock.paused = False
            if self.clock_mode == "realtime":
                clock.t0 = f["t0"]
        elif op == "link":
            self._update_link(f["link"], f["at"])
        elif op == "gains":
            self._set_gains(f["gains"], f["tick"])
        elif op == "formation":
            self._set_formation(f["phases"], f["tick"])
        elif op == "path":
            self._set_path(f["path"], f["tick"])
        elif op == "radio":
            self._update_radio(f["radio"], f["at"])
        elif op == "stop":
            clock.stop = True

    def _on_contacts(self, payload: bytes) -> None:
        """The world's proximity sensor: this vehicle's contacts of a sample tick (counted and
        dropped if malformed)."""
        msg = decode_contacts(payload, len(self.ids), self.index, self.node.vehicle.dim)
        if isinstance(msg, Rejected):
            return self._reject("world", f"contacts_{msg.reason}")
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
        if isinstance(msg, Rejected):
            return self._reject("world", f"radio_{msg.reason}")
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

    def _update_radio(self, change: dict, at: float) -> None:
        """A run-time radio change (tx_power, station) for messages sent from ``at`` on."""
        problem = "this scenario has no [radio] table" if self.node.radio is None else radio_change_problem(change)
        if problem is None:
            try:
                apply_radio_change(self.node.radio.channel, change, at)
            except ValueError as e:
                problem = str(e)
        if problem is not None:
            self.rejected["bad_radio_command"] += 1
            self.log(f"radio command rejected: {printable(problem, 200)}")
            return
        self.log(f"radio changed from t = {at:.2f} s: {printable(change, 200)}")

    def _on_roster(self, f: dict) -> None:
        j = self.ids.index(f["vehicle"])
        news = self.node.on_roster(RosterChange(f["tick"], j, f["state"], f["fresh"]))
        if news and j in self.node.neighbours:  # a catch-up said again is not logged again
            self.log(f"neighbour {f['vehicle']} {f['state']} from tick {f['tick']}")

    def _update_link(self, table: dict, at: float) -> None:
        """Merge ``table`` over the current [link] table (sub-tables key by key: ``delay.jitter``
        keeps ``delay.base``); it applies to messages sent from ``at`` on. A ``policy`` or
        ``timeout`` in it changes the stale-neighbour policy from the first tick at or after ``at``."""
        merged = merge_link_tables(self.link_table, table)
        try:
            spec = validate_link(merged, self.ids, "link command")
            at = self.node.set_link(spec, at)
            if "policy" in table or "timeout" in table:
                self.node.set_policy(spec.policy, spec.timeout, event_tick(at, self.period))
        except (ConfigError, ValueError) as e:
            self.rejected["bad_link_command"] += 1
            self.log(f"link command rejected: {e}")
            return
        self.link_table = merged
        self.log(f"link faults changed from t = {at:.2f} s: {table}")

    def _set_gains(self, gains: dict, tick: int) -> None:
        v = self.node.vehicle
        problem = gains_problem(gains, v.dim, **self.scenario.gain_context(self.id))  # as the world checked
        if problem is not None:
            self.rejected["bad_gains_command"] += 1
            self.log(f"gains command rejected: {problem}")
            return
        k = gains.get("k", v.k)
        k = tuple(float(x) for x in k) if isinstance(k, (list, tuple)) else (float(k),) * v.dim
        c = float(gains.get("c", v.c))
        self.node.set_gains(k, c, tick)
        self.log(f"gains k = {tuple(k)}, c = {c} from tick {tick}")

    def _set_formation(self, phases: dict, tick: int) -> None:
        """New phases from ``tick`` (checked as the world and the config check them)."""
        checked = check_phases(phases, self.ids)
        if isinstance(checked, tuple):
            self.rejected["bad_formation_command"] += 1
            self.log(f"formation command rejected: {printable(' '.join(checked), 200)}")
            return
        self.node.set_formation({self.ids.index(vid): theta for vid, theta in checked.items()}, tick)
        self.log(f"formation phases {printable(checked, 200)} from tick {tick}")

    def _set_path(self, table: dict, tick: int) -> None:
        """A new path for this vehicle from ``tick`` (checked as the config's paths are)."""
        path = check_path(table, self.node.vehicle.dim)
        if isinstance(path, tuple):
            self.rejected["bad_path_command"] += 1
            self.log(f"path command rejected: {printable(' '.join(path), 200)}")
            return
        self.node.set_path(path, tick)
        self.log(f"path {printable(table, 200)} from tick {tick}")

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
        if self.clock_mode == "lockstep":
            self._run_lockstep()
        else:
            self._run_realtime()
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
        if len(self._states) >= self.state_batch or n >= self.last_tick:
            self.flush_states()
        self.ticks_done = n + 1
        now = time.monotonic()
        bursts = self.node.bursts
        if now - self._last_stats > STATS_PERIOD or len(bursts.done) - bursts.reported >= BURSTS_PER_STATS // 2:
            self._last_stats = now
            self.publish_stats()

    def _run_lockstep(self) -> None:
        clock, node = self.clock, self.node
        never: Callable[[], None] = lambda: None
        while not clock.begun and not self._stopping():
            self._recv(never)
        if self._stopping():
            return
        n = clock.join
        if n > 0:  # the run is under way: a restarted process
            self._rejoin(n)
        # the first tick stepped after a join or a resume is reported at once, not in a batch: the
        # world says a caught-up process's catch-up again while it has reported nothing (what it
        # would hear again after stepping past it is a replay that must not change the run)
        report_next = True
        waited_since = time.monotonic()
        while n <= self.last_tick:
            state, fresh = node.own_state_at(n)
            if state != "live":  # paused (or gone) by the roster: skip to where it resumes
                back = node.resume_tick(n)
                if back is None:
                    if self._states:  # its last rows: the world records (and carries out a kill) only with them
                        self.flush_states()
                    if self._stopping():
                        return
                    self._recv(never)
                    continue
                v = node.vehicle
                node.rejoin(back, v.q, v.heading, v.omega)
                self.log(f"paused from tick {n}; resuming at tick {back} where the vehicle was")
                n = back
                report_next = True
                continue
            stuck_since = time.monotonic()
            while clock.granted < n or node.waiting_for(n) or self._samples_missing(n):
                if self._stopping():
                    return
                if clock.granted < n and (self._states or self._stats_tick != self.ticks_done):
                    self._report_rows()  # the world may be waiting for these rows to grant (or for a fault)
                self._recv(never)
                now_m = time.monotonic()
                # back from an outage (the world's token came back), or granted and still waiting for
                # ω after STUCK_RESEND s (an outage this session did not see as one: a frozen router
                # that kept the leases): what was in flight may be lost, say it again
                stuck = clock.granted >= n and now_m - stuck_since > STUCK_RESEND
                if (now_m < self._resend_until or stuck) and now_m - self._resent_at >= RESEND_EVERY:
                    self._resent_at = now_m
                    self._resend()
                if now_m - stuck_since > 0.5 and self.waker is not None and self.waker.alarm is None:
                    # a long wait (rare): make sure the loop wakes to resend even if nothing arrives
                    self.waker.alarm = time.time() + max(RESEND_EVERY, STUCK_RESEND - (now_m - stuck_since)) + 0.05
                    self.waker.interrupt()
                if time.monotonic() - waited_since > LOG_WAIT:
                    waited_since = time.monotonic()
                    missing = node.waiting_for(n)
                    why = ("the world's grant" if clock.granted < n else f"ω from {[self.ids[k] for k in missing]}"
                           if missing else "the world's samples (proximity contacts, radio geometry)")
                    self.log(f"tick {n}: still waiting for {why}")
            if self._stopping():
                return
            self._tick(n)
            if report_next:
                report_next = False
                self.flush_states()
            waited_since = time.monotonic()
            n += 1

    def _samples_missing(self, n: int) -> bool:
        """Lockstep: does tick ``n`` need a sample of the world's that has not arrived? The proximity
        sensor's contacts in force at n, the radio geometry in force at n - 1 (the messages
        decided at n were sent before it). The world sends both before it grants that far, so
        this never waits on the world for the tick at hand (docs/radio.md, "Integration")."""
        node = self.node
        return node.contacts_missing(n) or node.geometry_missing(n)

    def _run_realtime(self) -> None:
        clock, node, T = self.clock, self.node, self.period
        assert self.waker is not None
        never: Callable[[], None] = lambda: None
        while clock.t0 is None and not self._stopping():
            self._recv(never)
        if self._stopping():
            return
        arrival = lambda: time.time() - clock.t0  # noqa: E731 (simulated time of arrival)
        n = max(0, math.ceil((time.time() - clock.t0) / T))
        if n > 0:  # the run is under way: a restarted process
            self._rejoin(n)
        while n <= self.last_tick:
            if clock.paused:
                while clock.paused and not self._stopping():
                    self._recv(arrival)
                continue
            target = clock.t0 + n * T
            # Sleep to the tick, then take what arrived: one wake-up per tick, not one per
            # message (arrivals are stamped when taken, so within one period of the truth).
            drained = False  # the drain after the last nap is the tick's: no second one at once
            while (rest := target - time.time()) > 0 and not self._stopping() and not clock.paused:
                time.sleep(min(rest, MAX_NAP))
                self._drain(arrival)
                drained = True
            if self._stopping():
                return
            if clock.paused:
                continue
            if not drained:  # late: no nap before this tick
                self._drain(arrival)
            late = time.time() - target
            if late > STALL_TICKS * T:  # frozen (SIGSTOP) or starved: skip to now, where we were
                n = math.ceil((time.time() - clock.t0) / T)
                v = node.vehicle
                node.rejoin(n, v.q, v.heading, v.omega)
                self.log(f"stalled for {late:.2f} s: resuming at tick {n} from where the vehicle was")
                if n > self.last_tick:
                    break
            self._tick(n)
            if time.time() > clock.t0 + (n + 1) * T:
                self.missed_deadlines += 1
            n += 1

    def _rejoin(self, tick: int) -> None:
        """Join a run under way at ``tick``: where the world last saw this vehicle, with ω near
        what its neighbours' consensus asks (not laps away)."""
        last: dict[int, StateMsg] = {}
        for j in [self.index, *self.node.neighbours]:
            for reply in self.session.get(keys.world_last(self.fleet, self.ids[j]), timeout=2.0):
                if reply.ok is None:
                    continue
                rows = decode_states(reply.ok.payload.to_bytes(), len(self.ids))
                if not isinstance(rows, Rejected) and rows[0].sender == j:
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

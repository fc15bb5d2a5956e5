"""What is one vehicle process? One vehicle's tick protocol (cdus.core.node) wired to Zenoh.

Everything addressed to this vehicle (its neighbours' ω, the world's clock, roster and
relayed commands) arrives through one subscription into one channel, and the main thread
waits on that channel alone: no callbacks, no locks, one wake-up per message
(docs/architecture.md, "The agent"). It publishes its ω to the vehicles listening to it, its
telemetry in batches and its counters to the world, and declares a liveliness token once it is
ready. The rooms, each answering one question:

- vehicle_agent.clocks: which clock, picked once here (lockstep.py, realtime.py: the run loops);
- vehicle_agent.intake: what is taken from what arrives, what is refused (by reason);
- vehicle_agent.control: what a control message from the world does, and its outcome;
- vehicle_agent.report: what is told to the world, and when;
- vehicle_agent.outage: whether this session was cut off, and what to say again;
- vehicle_agent.rejoin: where a restarted vehicle picks up the run;
- vehicle_agent.waker: when the main thread must wake.

The public door (as dora's ``testing.py`` feeds a node): :meth:`Agent.feed` takes one message
by its key, :meth:`Agent.drain` takes everything waiting, :meth:`Agent.step` steps one tick.
"""

from __future__ import annotations

import random
import signal
import sys
import time
from typing import Any, Callable

import zenoh

from cdus.core.node import VehicleNode
from cdus.core.schedule import total_ticks
from cdus.core.vehicle import DivergedError
from cdus.scenario.model import Scenario
from cdus.sim.build import build_node, link_emulator_for, listeners_of, with_radio
from cdus.wire import keys
from cdus.wire.transport import Transport, open_session
from vehicle_agent.clocks import Clock, pick
from vehicle_agent.control import Control
from vehicle_agent.intake import Intake
from vehicle_agent.lockstep import LOG_WAIT
from vehicle_agent.outage import WORLD_BACK, Outage  # noqa: F401 (WORLD_BACK: the line tests look for)
from vehicle_agent.realtime import OMEGA_RING
from vehicle_agent.report import Report
from vehicle_agent.waker import Waker

END_WAIT = 10.0  # s to wait for the world's stop after the last tick
PING_TIMEOUT = 1.0  # s for a link check's reply (it is immediate when nobody answers)
PING_RETRY = 0.02  # s between link checks
#: the ω publisher's express flag (Zenoh: sent at once, never held for a batch); compared in the
#: same run by bench/omega_latency.py
OMEGA_EXPRESS = False
NEVER: Callable[[], None] = lambda: None  # noqa: E731 (lockstep: no arrival time)


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
        self.index = self.ids.index(vid)
        self.period = 1.0 / scenario.rates.control
        self.last_tick = total_ticks(scenario.duration if duration is None else duration, self.period)
        link = with_radio(scenario, link_emulator_for(scenario))  # [radio]: the channel under the link faults
        self.node: VehicleNode = build_node(scenario, vid, link, policy=policy, last_tick=self.last_tick)
        self.loop.plan(self)
        self.log = log or (lambda s: print(f"[{vid}] {s}", flush=True))
        self.clock = Clock()
        self.control = Control(self)  # the world's control messages: clock, roster, run-time commands
        self.intake = Intake(self)
        self.rejected = self.intake.rejected  # by reason, every reject (the node's ω ones too, but "gone")
        self.report = Report(self)
        self.outage = Outage(self)
        self.inbox: Any = None
        self._rings: list[tuple[int, Any]] = []  # realtime: (neighbour, its ω subscription: a ring channel)
        self._world_seen = None
        self.missed_deadlines = 0
        self.ticks_done = 0
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
        self.inbox, self._rings = self.loop.subscribe(s, f, me, self.intake.omega_from)
        # declared after the subscriptions, on the same session: whoever gets a reply holds them
        self.pinged = s.declare_queryable(keys.ping(f, me), lambda q: q.reply(keys.ping(f, me), b""))
        # Block rather than drop under congestion: losses are the link emulator's job, and a
        # lockstep neighbour waits for every broadcast.
        block = zenoh.CongestionControl.BLOCK
        r = self.report
        r.pub_omega = s.declare_publisher(keys.omega(f, me, listeners_of(self.scenario, me)),
                                          congestion_control=block, express=OMEGA_EXPRESS)
        r.pub_state = s.declare_publisher(keys.state(f, me), congestion_control=block)
        r.pub_stats = s.declare_publisher(keys.stats(f, me), congestion_control=block)  # the last one is the metrics'
        wake = s.declare_publisher(keys.wake(f, me), allowed_destination=zenoh.Locality.SESSION_LOCAL)
        self.waker = Waker(lambda: wake.put(b""))
        self.waker.start()
        self._await_links()
        # Ready: the subscription is in place and every listener can hear us. The token tells
        # the world and the launcher.
        self.token = s.liveliness().declare_token(keys.alive(f, me, str(s.zid())))
        self._world_seen = self.loop.watch_world(s, f, self.outage.on_token)
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
            self.report.publish_stats(final=True)  # its last word: the world waits for it before the metrics
            if self.token is not None:
                self.token.undeclare()
            self.session.close()
        except zenoh.ZError as e:  # closing must never hide the run's own outcome
            self.log(f"while closing the session: {e}")
        r = self.report
        r.pub_omega = r.pub_state = r.pub_stats = None
        self.session = None

    def request_stop(self) -> None:
        """From a signal handler: the main loop ends at its next wake-up (the waker makes one)."""
        self.stop_requested = True

    def wake(self) -> None:
        """Wake the main loop (from another thread)."""
        if self.waker is not None:
            self.waker.poke()

    # ------------------------------------------------------------------ the public door
    def feed(self, key: str, payload: bytes, now: float | None = None) -> None:
        """One message as the inbox delivers it: its key, its payload, its simulated arrival time
        (realtime) or None (lockstep). Whatever it is, it is taken or counted, never raised."""
        self.intake.take(key, payload, now)

    def drain(self, now: Callable[[], float | None] = NEVER) -> None:
        """Take everything waiting: the inbox, the world's token news, the realtime ω rings (at most
        OMEGA_RING each, the sender known by its ring). ``now()``: each sample's arrival time."""
        take = self.intake.take
        while (sample := self.inbox.try_recv()) is not None:
            take(str(sample.key_expr), sample.payload, now())
        if self.outage.news:
            self.outage.take_news()
        omega = self.intake.omega
        for k, ring in self._rings:
            for _ in range(OMEGA_RING):
                if (sample := ring.try_recv()) is None:
                    break
                omega(k, sample.payload, now())

    def wait(self, now: Callable[[], float | None] = NEVER) -> None:
        """Block for the next sample, then take everything else that is waiting."""
        sample = self.inbox.recv()
        self.intake.take(str(sample.key_expr), sample.payload, now())
        self.drain(now)

    def step(self, n: int) -> None:
        """Step tick ``n`` and tell the world (vehicle_agent.report)."""
        out = self.node.step(n)
        self.ticks_done = n + 1
        self.report.tick(n, out)

    def stats(self):
        """The agent's counters (vehicle_agent.report.Report.stats)."""
        return self.report.stats()

    def stopping(self) -> bool:
        return self.clock.stop or self.stop_requested

    # ------------------------------------------------------------------ the run
    def run(self) -> int:
        """Step to the last tick (or a stop). Returns the number of ticks stepped."""
        cpu0 = time.process_time()
        self.loop.run(self)
        self.cpu_s = time.process_time() - cpu0  # every thread of the process, Zenoh's included
        self._await_stop()
        return self.ticks_done

    def _await_stop(self) -> None:
        """After the last tick, wait for the world's stop so it has received everything."""
        self.report.flush()
        self.report.publish_stats()
        assert self.waker is not None
        deadline = time.time() + END_WAIT
        self.waker.alarm = deadline
        self.waker.interrupt()
        while not self.stopping() and time.time() < deadline:
            self.wait()


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

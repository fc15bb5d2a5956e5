"""How does a realtime agent step? On the wall clock from the world's start time t0, tick n at
t0 + n T, with whatever has arrived; a tick finishing after the next was due is a missed
deadline. Each neighbour's ω has a bounded ring channel of its own, and ω beyond what a sender
can send is dropped before it is decoded (``rate``).
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any, Callable

import zenoh

from cdus.wire import keys
from vehicle_agent.rejoin import rejoin

if TYPE_CHECKING:
    from vehicle_agent.agent import Agent
    from vehicle_agent.clocks import Clock

STATE_BATCH = 5  # telemetry rows per message
INBOX_CAPACITY = 4096  # samples; when full, Zenoh's delivery to this session waits (nothing grows)
OMEGA_RING = 16  # ω samples kept per neighbour between drains (<= MAX_NAP apart), newest first
STALL_TICKS = 10  # this many periods late means the process was frozen, not just slow
REALTIME_SLACK = 0.25  # s: an ω may be stamped this far past this agent's wall-clock tick
RATE_MARGIN = 4.0  # a sender's ω rate allowed, in multiples of its broadcast rate
RATE_BURST = 64  # ω a sender may send back to back (a stall's catch-up is < STALL_TICKS)
MAX_NAP = 0.05  # s: the loop sleeps at most this long between checks for a stop or a pause


class Realtime:
    """The realtime clock: a start time t0 from the world, pauses and resumes with a new t0."""

    name = "realtime"
    state_batch = STATE_BATCH

    def __init__(self, rate: float):
        self._rate = RATE_MARGIN * rate  # ω per s a neighbour may send
        self._bucket: dict[int, tuple[float, float]] = {}  # ω rate per neighbour: (tokens, when)

    def plan(self, agent: Agent) -> None:
        """Nothing: realtime hears of faults by liveliness."""

    def subscribe(self, session: Any, fleet: str, me: str, omega_from: dict[str, int]) -> tuple[Any, list]:
        """The world's one-chunk keys (ctl, contacts, radio, wake) through a FIFO, each neighbour's
        ω through a ring of its own that Zenoh overwrites oldest first, so a flood on one key costs
        this process at most OMEGA_RING samples per drain, not one Python wake-up per message (the
        newest ω is the one that matters)."""
        inbox = session.declare_subscriber(keys.inbox_leaves(fleet, me), zenoh.handlers.FifoChannel(INBOX_CAPACITY))
        rings = [(k, session.declare_subscriber(key, zenoh.handlers.RingChannel(OMEGA_RING)))
                 for key, k in omega_from.items()]
        return inbox, rings

    def watch_world(self, session: Any, fleet: str, callback: Callable[[Any], None]) -> Any:
        """Nothing: nothing a realtime agent sent is said again after an outage."""
        return None

    def horizon(self, clock: Clock, period: float, rejoin: bool) -> int | None:
        """The newest tick a genuine neighbour can have broadcast at: this agent's wall-clock tick
        plus :data:`REALTIME_SLACK` (from tick 0 while the start is not known); None for a
        restart that has not heard where the run is."""
        if rejoin and clock.t0 is None:
            return None
        slack = math.ceil(REALTIME_SLACK / period)
        if clock.t0 is None:
            return slack
        return max(0, math.floor((time.time() - clock.t0) / period)) + slack

    def over_rate(self, k: int) -> bool:
        """Has neighbour ``k`` sent more than it can (a token bucket at RATE_MARGIN times its
        broadcast rate, RATE_BURST deep)?"""
        now = time.monotonic()
        tokens, last = self._bucket.get(k, (float(RATE_BURST), now))
        tokens = min(float(RATE_BURST), tokens + (now - last) * self._rate)
        if tokens < 1.0:
            self._bucket[k] = (tokens, now)
            return True
        self._bucket[k] = (tokens - 1.0, now)
        return False

    def refund(self, k: int) -> None:
        """An ω taken: only what is rejected spends a sender's budget."""
        if k in self._bucket:
            tokens, when = self._bucket[k]
            self._bucket[k] = (min(float(RATE_BURST), tokens + 1.0), when)

    def resume(self, clock: Clock, t0: float) -> None:
        clock.paused = False
        clock.t0 = t0

    def run(self, agent: Agent) -> None:
        clock, node, T = agent.clock, agent.node, agent.period
        while clock.t0 is None and not agent.stopping():
            agent.wait()
        if agent.stopping():
            return
        arrival = lambda: time.time() - clock.t0  # noqa: E731 (simulated time of arrival)
        n = max(0, math.ceil((time.time() - clock.t0) / T))
        if n > 0:  # the run is under way: a restarted process
            rejoin(agent, n)
        while n <= agent.last_tick:
            if clock.paused:
                while clock.paused and not agent.stopping():
                    agent.wait(arrival)
                continue
            target = clock.t0 + n * T
            # Sleep to the tick, then take what arrived: one wake-up per tick, not one per
            # message (arrivals are stamped when taken, so within one period of the truth).
            drained = False  # the drain after the last nap is the tick's: no second one at once
            while (rest := target - time.time()) > 0 and not agent.stopping() and not clock.paused:
                time.sleep(min(rest, MAX_NAP))
                agent.drain(arrival)
                drained = True
            if agent.stopping():
                return
            if clock.paused:
                continue
            if not drained:  # late: no nap before this tick
                agent.drain(arrival)
            late = time.time() - target
            if late > STALL_TICKS * T:  # frozen (SIGSTOP) or starved: skip to now, where we were
                n = math.ceil((time.time() - clock.t0) / T)
                v = node.vehicle
                node.rejoin(n, v.q, v.heading, v.omega)
                agent.log(f"stalled for {late:.2f} s: resuming at tick {n} from where the vehicle was")
                if n > agent.last_tick:
                    break
            agent.step(n)
            if time.time() > clock.t0 + (n + 1) * T:
                agent.missed_deadlines += 1
            n += 1

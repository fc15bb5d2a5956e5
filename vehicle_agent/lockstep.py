"""How does a lockstep agent step? Tick n once the world has granted it (a grant is a horizon,
often hundreds of ticks) and it holds every live neighbour's newest broadcast that tick n can
use (cdus.core.node.VehicleNode.waiting_for), so the run is deterministic and equal to the
in-process one, whatever the scheduling. Scheduled faults are the roster every runner derives
from the scenario; the world relays the unscheduled ones with their tick.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Callable

import zenoh

from cdus.core.events import plan_roster
from cdus.sim.lockstep import GRANT_WINDOW, MAX_GRANT_WINDOW
from cdus.wire import keys
from vehicle_agent.outage import RESEND_EVERY
from vehicle_agent.rejoin import rejoin

if TYPE_CHECKING:
    from vehicle_agent.agent import Agent
    from vehicle_agent.clocks import Clock

#: telemetry rows per message: at most GRANT_WINDOW, the least grant window: a vehicle waiting for
#: a neighbour's ω holds fewer unsent rows than the window, so that neighbour is always granted its
#: tick (and one waiting for a grant sends what it holds at once)
STATE_BATCH = 50
assert STATE_BATCH <= GRANT_WINDOW
INBOX_CAPACITY = 4096  # samples; when full, Zenoh's delivery to this session waits (nothing grows)
#: a neighbour may have a grant this agent has not received yet; one grant moves at most
#: MAX_GRANT_WINDOW past the slowest live vehicle's acknowledged tick, which is <= ours
LOCKSTEP_SEQ_MARGIN = 2 * MAX_GRANT_WINDOW
#: granted and still waiting for a neighbour's ω this long (s), the agent says its recent messages
#: again every RESEND_EVERY s (receivers drop copies as stale): a router frozen for seconds can lose
#: messages in flight without any session seeing the world's token go and come back
STUCK_RESEND = 2.0
LOG_WAIT = 5.0  # s of waiting before saying what for


class Lockstep:
    """The lockstep clock: grants, joins and the roster the scenario schedules."""

    name = "lockstep"
    state_batch = STATE_BATCH

    def __init__(self, rate: float):
        """``rate`` (a neighbour's broadcast rate) bounds nothing here: every message is taken."""

    def plan(self, agent: Agent) -> None:
        """Scheduled faults land on their ticks (realtime hears of them by liveliness)."""
        for change in plan_roster(agent.scenario.events, agent.ids, agent.period):
            agent.node.on_roster(change)

    def subscribe(self, session: Any, fleet: str, me: str, omega_from: dict[str, int]) -> tuple[Any, list]:
        """One FIFO for everything: a genuine message is never lost."""
        return session.declare_subscriber(keys.inbox(fleet, me), zenoh.handlers.FifoChannel(INBOX_CAPACITY)), []

    def watch_world(self, session: Any, fleet: str, callback: Callable[[Any], None]) -> Any:
        """The world's token back means this session was cut off (an outage, vehicle_agent.outage)."""
        return session.liveliness().declare_subscriber(keys.alive_of(fleet, keys.WORLD), callback, history=True)

    def horizon(self, clock: Clock, period: float, rejoin: bool) -> int | None:
        """The newest tick a genuine neighbour can have broadcast at: the grant (or join) plus
        :data:`LOCKSTEP_SEQ_MARGIN`; None for a restart that has not heard where the run is."""
        if rejoin and not clock.begun:
            return None
        return max(clock.granted, clock.join) + LOCKSTEP_SEQ_MARGIN

    def over_rate(self, k: int) -> bool:
        """Lockstep takes everything: a genuine message is never dropped here, and a sender's ω is
        bounded by the grant window."""
        return False

    def refund(self, k: int) -> None:
        pass

    def resume(self, clock: Clock, t0: float) -> None:
        clock.paused = False

    def run(self, agent: Agent) -> None:
        clock, node = agent.clock, agent.node
        while not clock.begun and not agent.stopping():
            agent.wait()
        if agent.stopping():
            return
        n = clock.join
        if n > 0:  # the run is under way: a restarted process
            rejoin(agent, n)
        # the first tick stepped after a join or a resume is reported at once, not in a batch: the
        # world says a caught-up process's catch-up again while it has reported nothing (what it
        # would hear again after stepping past it is a replay that must not change the run)
        report_next = True
        waited_since = time.monotonic()
        while n <= agent.last_tick:
            state, fresh = node.own_state_at(n)
            if state != "live":  # paused (or gone) by the roster: skip to where it resumes
                back = node.resume_tick(n)
                if back is None:
                    if agent.report.states:  # its last rows: the world records (and carries out a kill) only with them
                        agent.report.flush()
                    if agent.stopping():
                        return
                    agent.wait()
                    continue
                v = node.vehicle
                node.rejoin(back, v.q, v.heading, v.omega)
                agent.log(f"paused from tick {n}; resuming at tick {back} where the vehicle was")
                n = back
                report_next = True
                continue
            stuck_since = time.monotonic()
            while clock.granted < n or node.waiting_for(n) or self.samples_missing(agent, n):
                if agent.stopping():
                    return
                if clock.granted < n and agent.report.behind():
                    agent.report.catch_up()  # the world may be waiting for these rows to grant (or for a fault)
                agent.wait()
                now_m = time.monotonic()
                # back from an outage (the world's token came back), or granted and still waiting for
                # ω after STUCK_RESEND s (an outage this session did not see as one: a frozen router
                # that kept the leases): what was in flight may be lost, say it again
                stuck = clock.granted >= n and now_m - stuck_since > STUCK_RESEND
                if agent.outage.resend_due(now_m, stuck_since, stuck):
                    agent.report.resend()
                if now_m - stuck_since > 0.5 and agent.waker is not None and agent.waker.alarm is None:
                    # a long wait (rare): make sure the loop wakes to resend even if nothing arrives
                    agent.waker.alarm = time.time() + max(RESEND_EVERY, STUCK_RESEND - (now_m - stuck_since)) + 0.05
                    agent.waker.interrupt()
                if time.monotonic() - waited_since > LOG_WAIT:
                    waited_since = time.monotonic()
                    missing = node.waiting_for(n)
                    why = ("the world's grant" if clock.granted < n else f"ω from {[agent.ids[k] for k in missing]}"
                           if missing else "the world's samples (proximity contacts, radio geometry)")
                    agent.log(f"tick {n}: still waiting for {why}")
            if agent.stopping():
                return
            agent.step(n)
            if report_next:
                report_next = False
                agent.report.flush()
            waited_since = time.monotonic()
            n += 1

    @staticmethod
    def samples_missing(agent: Agent, n: int) -> bool:
        """Does tick ``n`` need a sample of the world's that has not arrived? The proximity
        sensor's contacts in force at n, the radio geometry in force at n - 1 (the messages
        decided at n were sent before it). The world sends both before it grants that far, so
        this never waits on the world for the tick at hand (docs/radio.md, "Integration")."""
        node = agent.node
        return node.contacts_missing(n) or node.geometry_missing(n)

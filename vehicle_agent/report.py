"""What does the agent tell the world, and when? Its ω to the vehicles listening to it (each
tick it broadcasts), its telemetry rows in batches (the clock's batch size), its counters
(:class:`cdus.wire.schemas.AgentStats`) about once a second, and, after an outage, its recent
ω and telemetry again (receivers take what they missed and drop the rest as stale).
"""

from __future__ import annotations

import time
from collections import deque
from typing import TYPE_CHECKING, Any

from cdus.core.link import burst_events
from cdus.sim.build import link_faults_of
from cdus.sim.lockstep import MAX_GRANT_WINDOW
from cdus.wire.messages import MAX_STATE_ROWS, StateMsg, encode_omega, encode_states
from cdus.wire.schemas import AgentStats, encode_stats

if TYPE_CHECKING:
    from vehicle_agent.agent import Agent

STATS_PERIOD = 1.0  # s of wall time between counter reports
BURSTS_PER_STATS = 100  # drop bursts one report carries; a report goes early once half as many wait
#: the newest ω said again after an outage, at least: a sender runs ahead of what a listener holds
#: by up to its lookahead (a least link delay of D ticks lets it step D ticks past its neighbours'
#: newest ω) and, on a one-way link, a grant window; 2 x MAX_GRANT_WINDOW ticks' worth are kept
RESEND_OMEGAS = 16


class Report:
    """One agent's publications: set ``pub_omega``, ``pub_state``, ``pub_stats`` (the agent's
    Zenoh publishers) before the first tick; without them (no session) nothing is sent."""

    def __init__(self, agent: Agent):
        self.agent = agent
        self.pub_omega: Any = None
        self.pub_state: Any = None
        self.pub_stats: Any = None
        self.states: list[StateMsg] = []  # telemetry rows not sent yet
        self.last_omegas: deque[bytes] = deque(  # said again after an outage
            maxlen=max(RESEND_OMEGAS, 2 * MAX_GRANT_WINDOW // agent.node.every + 2))
        #: telemetry sent, newest last: as much as the world can lack after an outage (this vehicle
        #: runs up to a grant window past the world's newest row of the slowest vehicle)
        self.recent: deque[StateMsg] = deque(maxlen=MAX_GRANT_WINDOW + MAX_STATE_ROWS)
        self._lat_sent = 0
        self._last_stats = 0.0
        self.stats_tick = -1  # ticks_done when the counters were last published

    def tick(self, n: int, out: Any) -> None:
        """What tick ``n`` stepped to (``out``: cdus.core.node's step output): ω before telemetry
        (whoever saw tick n can count on it), the rows in batches, the counters once a second or
        once half a report's drop bursts wait."""
        a = self.agent
        if out.omega is not None:
            wire = encode_omega(out.omega)
            self.last_omegas.append(wire)
            if self.pub_omega is not None:
                self.pub_omega.put(wire)
        tel = out.telemetry
        self.states.append(StateMsg(a.index, n, tel.t, tuple(tel.q), tel.heading, tel.speed,
                                    tel.omega, tel.omega_rate, tel.path_error))
        if len(self.states) >= a.loop.state_batch or n >= a.last_tick:
            self.flush()
        now = time.monotonic()
        bursts = a.node.bursts
        if now - self._last_stats > STATS_PERIOD or len(bursts.done) - bursts.reported >= BURSTS_PER_STATS // 2:
            self._last_stats = now
            self.publish_stats()

    def flush(self) -> None:
        """Send the telemetry rows held."""
        if self.states and self.pub_state is not None:
            self.pub_state.put(encode_states(self.states))
            self.recent.extend(self.states)
        self.states = []

    def behind(self) -> bool:
        """Is there something the world has not heard (rows held, or ticks since the counters)?"""
        return bool(self.states) or self.stats_tick != self.agent.ticks_done

    def catch_up(self) -> None:
        """Lockstep, waiting for the world: the counters, then the rows held. The world carries out
        a vehicle fault at tick K once every live vehicle has reported K - 1, so a killed process's
        counters then cover the messages its node decided (those sent before K - 1, as the
        in-process fleet's node decides them): the run's per-link counters are whole after a kill.
        Once per wait with ticks stepped since the last report: a grant wait is rare (the grant
        runs a window ahead of the slowest vehicle), the once-a-second report the rest."""
        if self.stats_tick != self.agent.ticks_done:
            self.publish_stats()
        self.flush()

    def resend(self) -> None:
        """Back from an outage: say the last ω messages and the recent telemetry again: a receiver
        that lost one in flight (a router outage) takes it as a gap filled, the others drop the
        copies as stale."""
        if self.pub_omega is None:
            return
        for wire in self.last_omegas:
            self.pub_omega.put(wire)
        rows = list(self.recent)
        for first in range(0, len(rows), MAX_STATE_ROWS):  # in messages the world takes
            self.pub_state.put(encode_states(rows[first:first + MAX_STATE_ROWS]))

    def stats(self, final: bool = False) -> AgentStats:
        """The agent's counters; the latency samples since the last call only. ``final``: the
        last report, sent as the agent closes (the world waits for no more from it)."""
        a = self.agent
        node, c = a.node, a.node.counters
        by_reason = dict(a.rejected)
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
            id=a.id, tick=a.ticks_done, sent_to_me=c.sent, delivered=c.delivered, dropped=c.dropped,
            duplicated=c.duplicated, rejected=c.rejected + sum(a.rejected.values()),
            rejected_by_reason=by_reason, missed_deadlines=a.missed_deadlines, joined_at=node.joined_at,
            latencies_ms=tuple(x * 1000.0 for x in new[::step][:100]), faults=faults,
            bursts=tuple(e.as_dict() for e in burst_events(node.bursts, a.ids)[-BURSTS_PER_STATS:]),
            interventions=node.vehicle.interventions, incarnation=a.incarnation, deflected=node.vehicle.deflected,
            radio=None if node.radio is None else node.radio.counters.as_dict(), final=final)

    def publish_stats(self, final: bool = False) -> None:
        if self.pub_stats is not None:
            self.pub_stats.put(encode_stats(self.stats(final)))
            self.stats_tick = self.agent.ticks_done

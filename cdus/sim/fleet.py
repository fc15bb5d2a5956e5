"""The in-process fleet: every vehicle's own code, stepped together, over an in-memory link.

It is the fast path for tests and sweeps and the reference the multi-process lockstep
mode reproduces: the schedule below is exactly the lockstep protocol.

At control tick n (t_n = n T), for every vehicle:
  1. deliver the ω messages due by tick n (sent at a tick m < n, usable at the first tick
     at or after t_m + delay), then ``control`` with its neighbour table's consensus
     over the period [t_{n-1}, t_n];
  2. record telemetry (metrics are sampled after the controller's update);
  3. on broadcast ticks, send ω: encoded and decoded exactly as on the wire, with the
     link model deciding per (src, dst, seq) whether and when it arrives;
  4. ``advance`` the plant to t_{n+1}.

Scheduled vehicle faults (the scenario's ``[[event]]``, cdus.scenario.events) are emulated with
the effects they have on the multi-process fleet: a killed vehicle stops and its
neighbours drop it from their sums (its liveliness token is gone); a paused one freezes
and is dropped after the liveliness lease; a resumed or restarted one rejoins at the
current tick where it was, with ω continued from its last value.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Any, Callable

from cdus.core.link import DropBursts, LinkCounters, LinkEmulator, LinkModel, burst_text
from cdus.sim.build import build_vehicle, link_model_for, links_of, metric_edges
from cdus.wire.messages import OmegaMsg, decode_omega, encode_omega
from cdus.core.neighbours import NeighbourTable, consensus_target
from cdus.core.schedule import broadcast_every, delivery_tick, total_ticks
from cdus.core.vehicle import Vehicle
from cdus.core.metrics import Recorder, percentile_ms
from cdus.sim.sink import UPDATE_EVERY, NullSink, Sink


LEASE_S = 1.0  # the liveliness lease the launcher sets: a frozen vehicle is gone after this


@dataclass
class RunResult:
    metrics: dict
    recorder: Recorder
    vehicles: list[Vehicle]


class InProcessFleet:
    def __init__(self, scenario: Any, link: LinkModel | None = None, policy: str | None = None,
                 timeout: float | None = None, mode: str = "inproc", sink: Sink | None = None,
                 clock: Callable[[], float] = lambda: 0.0):
        """``clock``: the caller's wall clock (e.g. ``time.perf_counter``), for the metrics'
        wall_s and realtime_factor; the fleet itself reads no clock."""
        self.scenario = scenario
        self.mode = mode
        self.sink = sink or NullSink()
        spec = scenario.link
        self.link = link or link_model_for(scenario)
        self.policy = policy or spec.policy
        self.timeout = spec.timeout if timeout is None else timeout
        self.vehicles = [build_vehicle(v, scenario.rates, scenario.seed) for v in scenario.vehicles]
        self.tables = [self._table(v.id) for v in scenario.vehicles]
        self.listeners: list[list[int]] = [[] for _ in self.vehicles]
        for dst, table in enumerate(self.tables):
            for ln in table.links:
                self.listeners[ln.k].append(dst)
        self.period = 1.0 / scenario.rates.control
        self.every = broadcast_every(scenario.rates)
        self.recorder = Recorder([v.id for v in self.vehicles], [v.dim for v in self.vehicles],
                                 metric_edges(scenario))
        self.counters = LinkCounters()
        # deliveries by the tick they become usable at, in send order: (dst, message, latency)
        self._due: dict[int, list[tuple[int, OmegaMsg, float]]] = defaultdict(list)
        self.events = list(scenario.events)
        self.dead: set[int] = set()  # killed: not stepping, gone for the neighbours
        self.frozen: dict[int, float] = {}  # paused: since when (simulated s)
        self._lease_out: dict[int, float] = {}  # paused vehicles already dropped, by pause start
        self.event_log: list[str] = []
        self._last_tel: list[Any] = [None] * len(self.vehicles)
        self._changes_seen = 0
        self.bursts = DropBursts()
        self._bursts_seen = 0
        self.tick = 0
        self.clock = clock
        self._t0 = clock()
        self.end_tick = total_ticks(scenario.duration, self.period)

    def _table(self, vid: str) -> NeighbourTable:
        return NeighbourTable(links_of(self.scenario, vid), self.policy, self.timeout)

    def _note(self, t: float, text: str, level: str = "info") -> None:
        self.event_log.append(f"t = {t:.2f} s: {text}")
        self.sink.event(t, text, level)

    def _apply_events(self, n: int) -> None:
        t = n * self.period
        ids = [v.id for v in self.vehicles]
        while self.events and self.events[0].at <= t + 1e-9:
            ev = self.events.pop(0)
            j = ids.index(ev.vehicle)
            v = self.vehicles[j]
            if ev.action == "kill" and j not in self.dead:
                self.dead.add(j)
                self.frozen.pop(j, None)
                self._gone(j)
                self._note(t, f"vehicle {ev.vehicle} killed", "warn")
            elif ev.action == "pause" and j not in self.dead and j not in self.frozen:
                self.frozen[j] = t
                self._note(t, f"vehicle {ev.vehicle} paused", "warn")
            elif ev.action == "resume" and j in self.frozen:
                del self.frozen[j]
                v.rejoin(n, v.q, v.heading, v.omega)
                self._note(t, f"vehicle {ev.vehicle} resumed")
            elif ev.action == "restart":
                self.dead.discard(j)
                self.frozen.pop(j, None)
                self.tables[j] = self._table(ev.vehicle)  # a new process knows nothing yet
                live = {k: self.vehicles[k].omega for k in range(len(self.vehicles))
                        if k not in self.dead and k not in self.frozen and k != j}
                target = consensus_target(self.tables[j].links, live)
                v.rejoin(n, v.q, v.heading, v.omega if target is None else target)
                self._note(t, f"vehicle {ev.vehicle} restarted where it was, ω = {v.omega:.2f}")
        for j, since in self.frozen.items():
            if t - since >= LEASE_S and self._lease_out.get(j) != since:  # the lease ran out
                self._lease_out[j] = since
                self._gone(j)

    def _gone(self, j: int) -> None:
        """j's liveliness token is gone: every neighbour drops it from its sum."""
        for dst in self.listeners[j]:
            self.tables[dst].mark_absent(j)

    def step(self) -> None:
        n = self.tick
        T = self.period
        t_prev = (n - 1) * T
        if self.events or self.frozen:
            self._apply_events(n)
        stopped = self.dead.union(self.frozen) if (self.dead or self.frozen) else ()
        tables, counters = self.tables, self.counters
        for dst, msg, latency in self._due.pop(n, ()):
            if dst in stopped or not tables[dst].offer(msg, n * T):
                counters.rejected += dst not in stopped
                continue
            counters.delivered += 1
            counters.record_latency(latency)
        rows = self._last_tel
        for j, (v, table) in enumerate(zip(self.vehicles, self.tables)):
            if j not in stopped:
                v.control(table.consensus(t_prev))
                rows[j] = v.telemetry()
        self.recorder.record(n * T, rows)
        if n % UPDATE_EVERY == 0:
            self._report_link_changes()
            self.sink.update(self.recorder)
        if n % self.every == 0 and n < self.end_tick:  # a last-tick broadcast would never be used
            for src, v in enumerate(self.vehicles):
                if src not in stopped:
                    self._send(src, v, n)
        for j, v in enumerate(self.vehicles):
            if j not in stopped:
                v.advance()
        self.tick += 1

    def _report_link_changes(self) -> None:
        ids = [v.id for v in self.vehicles]
        for burst in self.bursts.done[self._bursts_seen:]:
            self._note(burst[1], burst_text(burst, ids), "warn")
        self._bursts_seen = len(self.bursts.done)
        changes = getattr(self.link, "state_changes", None)
        if not changes or len(changes) == self._changes_seen:
            return
        for t, s, d, state in changes[self._changes_seen:]:
            self.sink.link_state(t, ids[s], ids[d], state)
        self._changes_seen = len(changes)

    def _send(self, src: int, v: Vehicle, n: int) -> None:
        seq = n // self.every  # as the agents number them, restarts included
        # Through the wire format once, so every listener sees exactly what a remote one would.
        msg = decode_omega(encode_omega(OmegaMsg(src, seq, v.t, v.omega, v.omega_rate)))
        if isinstance(msg, str):  # a diverged vehicle (non-finite ω): receivers would reject it
            self.counters.sent += len(self.listeners[src])
            self.counters.rejected += len(self.listeners[src])
            return
        for dst in self.listeners[src]:
            self.counters.sent += 1
            delays = self.link.decide(src, dst, seq, v.t)
            self.bursts.feed(src, dst, not delays, v.t)
            if not delays:
                self.counters.dropped += 1
            self.counters.duplicated += max(0, len(delays) - 1)
            for d in delays:
                self._due[delivery_tick(n, d, self.period)].append((dst, msg, d))

    def run(self, duration: float | None = None, progress: Callable[[float, float], None] | None = None
            ) -> RunResult:
        """Step to ``duration`` (default: the scenario's), inclusive of the last instant."""
        duration = self.scenario.duration if duration is None else duration
        ticks = self.end_tick = total_ticks(duration, self.period)
        self._t0 = self.clock()
        if self.tick == 0:
            self.sink.start(self.scenario)
        while self.tick <= ticks:
            self.step()
            if progress is not None and self.tick % 250 == 0:
                progress(self.tick * self.period, duration)
        self._report_link_changes()
        self.sink.update(self.recorder)
        return RunResult(self.partial_metrics(), self.recorder, self.vehicles)

    def partial_metrics(self) -> dict:
        """The metrics JSON of what has run so far (also after an interruption)."""
        sc = self.scenario
        wall = self.clock() - self._t0
        link = link_summary(self.counters)
        if isinstance(self.link, LinkEmulator):
            link["faults"] = self.link.counters_summary()
        metrics = self.recorder.summary(
            scenario=sc.name, mode=self.mode, seed=sc.seed, path_tol=sc.path_tol, coord_tol=sc.coord_tol,
            link=link, wall_s=wall)
        metrics["policy"] = self.policy
        if self.event_log:
            metrics["events"] = list(self.event_log)
        return metrics


def link_summary(c: LinkCounters) -> dict:
    return {
        "sent": c.sent, "delivered": c.delivered, "dropped": c.dropped, "duplicated": c.duplicated,
        "rejected": c.rejected,
        "latency_ms_p50": percentile_ms(c.latencies, 50), "latency_ms_p99": percentile_ms(c.latencies, 99),
    }

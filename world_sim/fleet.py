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
"""

from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass
from typing import Any, Callable

from vehicle_agent.link import IdealLink, LinkCounters, LinkModel
from vehicle_agent.messages import OmegaMsg, decode_omega, encode_omega
from vehicle_agent.neighbours import NeighbourTable, links_of
from vehicle_agent.schedule import broadcast_every, delivery_tick, total_ticks
from vehicle_agent.vehicle import Vehicle
from world_sim.metrics import Recorder, metric_edges, percentile_ms
from world_sim.recording import UPDATE_EVERY, NullSink, Sink


@dataclass
class RunResult:
    metrics: dict
    recorder: Recorder
    vehicles: list[Vehicle]


class InProcessFleet:
    def __init__(self, scenario: Any, link: LinkModel | None = None, policy: str = "hold",
                 timeout: float = 1.5, mode: str = "inproc", sink: Sink | None = None):
        self.scenario = scenario
        self.mode = mode
        self.sink = sink or NullSink()
        self.link = link or IdealLink()
        self.vehicles = [Vehicle.from_spec(v, scenario.rates, scenario.seed) for v in scenario.vehicles]
        self.tables = [NeighbourTable(links_of(scenario, v.id), policy, timeout) for v in scenario.vehicles]
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
        self._seq = [0] * len(self.vehicles)
        self.tick = 0

    def step(self) -> None:
        n = self.tick
        T = self.period
        t_prev = (n - 1) * T
        tables, counters = self.tables, self.counters
        for dst, msg, latency in self._due.pop(n, ()):
            if not tables[dst].offer(msg, n * T):
                counters.rejected += 1
                continue
            counters.delivered += 1
            counters.record_latency(latency)
        for v, table in zip(self.vehicles, self.tables):
            v.control(table.consensus(t_prev))
        self.recorder.record(n * T, [v.telemetry() for v in self.vehicles])
        if n % UPDATE_EVERY == 0:
            self.sink.update(self.recorder)
        if n % self.every == 0:
            for src, v in enumerate(self.vehicles):
                self._send(src, v, n)
        for v in self.vehicles:
            v.advance()
        self.tick += 1

    def _send(self, src: int, v: Vehicle, n: int) -> None:
        seq = self._seq[src]
        self._seq[src] += 1
        # Through the wire format once, so every listener sees exactly what a remote one would.
        msg = decode_omega(encode_omega(OmegaMsg(src, seq, v.t, v.omega, v.omega_rate)))
        if isinstance(msg, str):  # a diverged vehicle (non-finite ω): receivers would reject it
            self.counters.sent += len(self.listeners[src])
            self.counters.rejected += len(self.listeners[src])
            return
        for dst in self.listeners[src]:
            self.counters.sent += 1
            delays = self.link.decide(src, dst, seq, v.t)
            if not delays:
                self.counters.dropped += 1
            self.counters.duplicated += max(0, len(delays) - 1)
            for d in delays:
                self._due[delivery_tick(n, d, self.period)].append((dst, msg, d))

    def run(self, duration: float | None = None, progress: Callable[[float, float], None] | None = None
            ) -> RunResult:
        """Step to ``duration`` (default: the scenario's), inclusive of the last instant."""
        duration = self.scenario.duration if duration is None else duration
        ticks = total_ticks(duration, self.period)
        self._t0 = time.perf_counter()
        last_report = self._t0
        if self.tick == 0:
            self.sink.start(self.scenario)
        while self.tick <= ticks:
            self.step()
            if progress is not None and self.tick % 50 == 0:
                now = time.perf_counter()
                if now - last_report > 0.5:
                    last_report = now
                    progress(self.tick * self.period, duration)
        self.sink.update(self.recorder)
        return RunResult(self.partial_metrics(), self.recorder, self.vehicles)

    def partial_metrics(self) -> dict:
        """The metrics JSON of what has run so far (also after an interruption)."""
        sc = self.scenario
        wall = time.perf_counter() - getattr(self, "_t0", time.perf_counter())
        return self.recorder.summary(
            scenario=sc.name, mode=self.mode, seed=sc.seed, path_tol=sc.path_tol, coord_tol=sc.coord_tol,
            link=link_summary(self.counters), wall_s=wall)


def link_summary(c: LinkCounters) -> dict:
    return {
        "sent": c.sent, "delivered": c.delivered, "dropped": c.dropped, "duplicated": c.duplicated,
        "rejected": c.rejected,
        "latency_ms_p50": percentile_ms(c.latencies, 50), "latency_ms_p99": percentile_ms(c.latencies, 99),
    }

"""How does `cdus sim` run a fleet in one process? Every vehicle's tick protocol, stepped together,
over an in-memory link.

It is the fast path for tests and sweeps and the reference the multi-process lockstep
mode reproduces. Each vehicle is a :class:`cdus.core.node.VehicleNode`, the same object a
vehicle agent drives from Zenoh; this runner only moves messages between them:

at control tick n, for every vehicle that is live at n (in index order): ``step(n)``
(it decides and takes the messages usable by n, runs the controller, samples its
telemetry and advances its plant); its ω broadcast goes through the wire format once and
into each listener's ``on_message``, to be decided at the listener's next tick, exactly as
a lockstep agent receives it. The row of tick n is recorded once every vehicle has stepped.
With the safety filter on, the proximity sensor samples the positions of tick n on its
ticks and hands each vehicle that stepped n its contacts, usable from n + latency, as the
world does (cdus.sim.sensing).

Scheduled vehicle faults (the scenario's events) become the roster of
:func:`cdus.core.events.plan_roster`, which every node is given up front, as every
lockstep agent computes it: a killed vehicle stops and leaves its neighbours' sums; a
paused one freezes and is dropped after the liveliness lease; a resumed one carries on
where it was; a restarted one is a new node that rejoins where it was last seen, with ω
near its neighbours' consensus.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from cdus.commands.base import Rejected, freeze
from cdus.commands.changes import Formation, Path
from cdus.core.events import RosterChange, event_tick, plan_roster
from cdus.core.link import LinkModel, burst_events
from cdus.core.metrics import Recorder
from cdus.core.node import VehicleNode
from cdus.core.schedule import broadcast_every, total_ticks
from cdus.core.vehicle import Telemetry, Vehicle
from cdus.scenario.model import Scenario
from cdus.sim.build import (
    build_node, formation_schedule, link_faults_of, link_model_for, metric_edges, radio_schedule,
    sensor_schedule, with_radio,
)
from cdus.sim.sensing import contacts_of, sense_tick
from cdus.sim.reports import (
    formation_changed, graph_event, link_state_event, path_changed, scheduled_change_events, scheduled_fault,
    vehicle_back,
)
from cdus.sim.sink import UPDATE_EVERY, NullSink, Sink
from cdus.sim.runmetrics import Metrics
from cdus.sim.summary import link_faults, link_metrics, run_metrics, sum_counters
from cdus.sim.radio import RadioWatch, apply_radio_change, geometry_sample, radio_change_problem, radio_metrics
from cdus.wire.rejected import Rejected
from cdus.wire.messages import (
    decode_contacts, decode_geometry, decode_omega, encode_contacts, encode_geometry, encode_omega,
)
from cdus.wire.schemas import FleetEvent


@dataclass
class RunResult:
    metrics: Metrics
    recorder: Recorder
    vehicles: list[Vehicle]


class InProcessFleet:
    def __init__(self, scenario: Scenario, link: LinkModel | None = None, policy: str | None = None,
                 timeout: float | None = None, mode: str = "inproc", sink: Sink | None = None,
                 clock: Callable[[], float] = lambda: 0.0):
        """``clock``: the caller's wall clock (e.g. ``time.perf_counter``), for the metrics'
        wall_s and realtime_factor; the fleet itself reads no clock."""
        self.scenario = scenario
        self.mode = mode
        self.sink = sink or NullSink()
        self.link = link_model_for(scenario) if link is None else (
            link if link.radio is not None else with_radio(scenario, link))  # a given model under [radio]
        spec = scenario.link
        self.policy = policy or spec.policy
        self.timeout = spec.timeout if timeout is None else timeout
        self.ids = list(scenario.ids)
        self.period = 1.0 / scenario.rates.control
        self.every = broadcast_every(scenario.rates)
        self.end_tick = total_ticks(scenario.duration, self.period)
        self.roster = plan_roster(scenario.events, self.ids, self.period)
        self._scheduled = sorted((event_tick(e.at, self.period), self.ids.index(e.vehicle), e.action)
                                 for e in scenario.events)
        self._pairs = [(e.i, e.k) for e in scenario.edges]
        self._alive = set(self.ids)  # whose process would hold a liveliness token (a lapsed pause does not)
        self.sensing = sensor_schedule(scenario)  # (every, latency) ticks, None: no proximity sensor
        self.radio = radio_schedule(scenario)  # (every, lag) ticks, None: no [radio]
        self.radio_watch = None if self.radio is None else RadioWatch(
            self.ids, [(e.i, e.k) for e in scenario.edges], self.link.channel, self.period)
        self.nodes = [self._node(j) for j in range(len(self.ids))]
        self.listeners: list[list[int]] = [[] for _ in self.ids]
        for dst, node in enumerate(self.nodes):
            for k in node.neighbours:
                self.listeners[k].append(dst)
        self.recorder = Recorder(self.ids, [v.dim for v in scenario.vehicles], metric_edges(scenario))
        self.recorder.set_formation(formation_schedule(scenario), self.period)
        #: changes to report at their tick: tick -> events (the scenario's, then set_formation/set_path's)
        self._change_events = scheduled_change_events(scenario, self.period)
        self._commanded: list[tuple[Formation | Path, int]] = []  # run-time changes, for restarted nodes
        self.events: list[FleetEvent] = []
        self._last: list[Telemetry] = [node.vehicle.telemetry() for node in self.nodes]  # newest of each vehicle
        self._was_live = [True] * len(self.ids)
        self._retired: list[VehicleNode] = []  # nodes replaced by a restart (their counters still count)
        self._retired_interventions = [0] * len(self.ids)  # per vehicle, its replaced nodes' interventions
        self._changes_seen = 0
        self.tick = 0
        self.clock = clock
        self._t0 = clock()

    @property
    def vehicles(self) -> list[Vehicle]:
        return [node.vehicle for node in self.nodes]

    def _node(self, j: int, joined_at: int = 0) -> VehicleNode:
        node = build_node(self.scenario, self.ids[j], self.link, policy=self.policy, timeout=self.timeout,
                          last_tick=self.end_tick, joined_at=joined_at)
        for change in self.roster:
            node.on_roster(change)
        for command, tick in getattr(self, "_commanded", ()):  # a restart hears them again, in order
            self._apply(node, command, tick)
        return node

    def _apply(self, node: VehicleNode, command: Formation | Path, tick: int) -> None:
        """A formation for every node, a path for its vehicle's (cdus.commands.changes)."""
        if isinstance(command, Path) and command.vehicle != self.ids[node.index]:
            return
        out = command.apply(node, tick, self.ids)
        if isinstance(out, Rejected):  # the caller validated it: a refusal here is a bug, said as one
            raise ValueError(f"{command.NAMES.cli} command refused: {out}")

    def set_formation(self, phases: dict[str, float], tick: int, by: str | None = None) -> None:
        """New phases (θ, ω units) for the vehicles named, from ``tick`` (not before the next
        tick stepped), on every node and in the metrics, as a ground station's change is in a
        fleet of processes. The phases are taken as validated (cdus.scenario.events.check_phases)."""
        tick = max(tick, self.tick)
        index = {vid: j for j, vid in enumerate(self.ids)}
        command = Formation(tuple((vid, float(theta)) for vid, theta in phases.items()))
        update = {index[vid]: theta for vid, theta in command.phases}
        self._commanded.append((command, tick))
        for node in self.nodes:
            self._apply(node, command, tick)
        self.recorder.formation.add(tick, update)
        ordered = sorted(update.items())
        self._change_events.setdefault(tick, []).append(
            formation_changed(tick, self.period, [(self.ids[j], x) for j, x in ordered], by))

    def set_path(self, vid: str, table: dict, tick: int, by: str | None = None) -> None:
        """Vehicle ``vid`` follows the path ``table`` (validated: cdus.scenario.events.check_path)
        from ``tick`` (not before the next tick stepped)."""
        tick = max(tick, self.tick)
        j = self.ids.index(vid)
        command = Path(vid, freeze(dict(table)))
        self._commanded.append((command, tick))
        self._apply(self.nodes[j], command, tick)
        self._change_events.setdefault(tick, []).append(
            path_changed(tick, self.period, vid, sorted(dict(table).items()), by))

    def _note(self, event: FleetEvent) -> None:
        self.events.append(event)
        self.sink.event(event)

    def _faults_at(self, n: int) -> None:
        """Carry out tick n's scheduled faults and report them as the world does in lockstep
        (cdus.sim.reports): ``fault`` for each, ``vehicle_back`` when a vehicle's process is
        back (a restart, or a resume after its lease lapsed), and ``graph`` when the set of
        live processes changed."""
        t = n * self.period
        for tick, j, action in self._scheduled:
            if tick == n:
                self._note(scheduled_fault(n, self.period, action, self.ids[j]))
        before = set(self._alive)
        back: list[str] = []
        for ch in self.roster:
            if ch.tick != n:
                continue
            vid = self.ids[ch.vehicle]
            if ch.state == "gone":
                self._alive.discard(vid)
            elif ch.state == "live" and (ch.fresh or vid not in self._alive):
                if ch.fresh:
                    self._restart(ch, n)
                self._alive.add(vid)
                back.append(vid)
        for vid in back:
            self._note(vehicle_back(t, vid))
        if back or self._alive != before:
            self._note(graph_event(t, self.ids, self._pairs, self._alive))

    def _restart(self, ch: RosterChange, n: int) -> None:
        """A new process for vehicle j: a fresh node at the last telemetry seen of it."""
        j = ch.vehicle
        self._retired.append(self.nodes[j])
        self._retired_interventions[j] += self.nodes[j].vehicle.interventions
        node = self.nodes[j] = self._node(j, joined_at=n)
        last = self._last[j]
        omegas = {k: self._last[k].omega for k in node.neighbours if self.nodes[k].own_state_at(n)[0] == "live"}
        node.rejoin(n, last.q, last.heading, last.omega, omegas)
        self._was_live[j] = True  # rejoined: not again from its own ω as a resumed one (a process does it once)

    def step(self) -> None:
        n = self.tick
        if self.roster:
            self._faults_at(n)
        for event in self._change_events.pop(n, ()):
            self._note(event)
        rows = self._last
        stepped = []
        for node in self.nodes:  # nobody can have sent anything later than this tick
            node.horizon = n
        for j, node in enumerate(self.nodes):
            state, _ = node.own_state_at(n)
            if state != "live":
                self._was_live[j] = False
                continue
            stepped.append(j)
            if not self._was_live[j]:  # resumed: carry on where it was
                v = node.vehicle
                node.rejoin(n, v.q, v.heading, v.omega)
                self._was_live[j] = True
            out = node.step(n)
            rows[j] = out.telemetry
            if out.omega is not None:
                self._send(j, out.omega, n)
        if self.sensing is not None and n % self.sensing[0] == 0:
            live = set(stepped)
            self._sense(n, {j: rows[j].q for j in stepped}, {j: rows[j].q for j in range(len(rows)) if j not in live})
        if self.radio is not None and n % self.radio[0] == 0:
            self._radio_sample(n, {j: rows[j].q for j in stepped})
        live = [False] * len(self.nodes)
        for j in stepped:
            live[j] = True
        counts = None if self.sensing is None else [
            r + node.vehicle.interventions for r, node in zip(self._retired_interventions, self.nodes)]
        self.recorder.record(n * self.period, rows, live, counts)
        if n % UPDATE_EVERY == 0:
            self._report_link_changes()
            self.sink.update(self.recorder)
        self.tick += 1

    def _send(self, src: int, msg, n: int) -> None:
        # Through the wire format once, so every listener sees exactly what a remote one would.
        # A listener whose process is gone at tick n (killed, or paused past its lease) hears
        # nothing, as in a fleet of processes: its counters do not count it.
        wire = decode_omega(encode_omega(msg))
        for dst in self.listeners[src]:
            if self.ids[dst] not in self._alive:
                continue
            if isinstance(wire, Rejected):  # a diverged vehicle (non-finite ω): receivers reject it
                self.nodes[dst].counters.sent += 1
                self.nodes[dst].counters.rejected += 1
            else:
                self.nodes[dst].on_message(wire)

    def _sense(self, n: int, positions: dict, gone: dict) -> None:
        """The proximity sensor at tick n, as the world runs it: contacts through the wire
        format once, to every vehicle that stepped n; the others stay obstacles where they
        were last seen (cdus.sim.sensing)."""
        for j, msg in sense_tick(self.scenario, n, positions, gone).items():
            wire = decode_contacts(encode_contacts(msg), len(self.ids))
            if not isinstance(wire, Rejected):
                self.nodes[j].on_contacts(n, contacts_of(wire, self.ids))

    def _radio_sample(self, n: int, positions: dict) -> None:
        """The radio geometry of tick n, as the world samples it (cdus.sim.radio): through the wire
        format once, into the shared RadioLink (in force from n + lag), and watched (events)."""
        dims = [v.dim for v in self.scenario.vehicles]
        wire = decode_geometry(encode_geometry(geometry_sample(n, positions, len(self.ids), dims)), len(self.ids), dims)
        if isinstance(wire, Rejected):  # a diverged vehicle's position (non-finite): the step raises first
            return
        self.link.on_geometry(wire.tick, wire.positions)
        for ev in self.radio_watch.observe(wire):
            self._note(ev)
        self.sink.radio(n * self.period, self.radio_watch)

    def set_radio(self, change: dict, at: float) -> None:
        """A run-time radio change (tx_power, station) for messages sent from ``at`` on, as a
        ground station's relayed by the world (a scheduled ``radio`` event)."""
        if self.radio is None:
            raise ValueError("this scenario has no [radio] table")
        problem = radio_change_problem(change, self.scenario.radio.topology)
        if problem is not None:
            raise ValueError(problem)
        apply_radio_change(self.link.channel, change, at)

    @property
    def interventions(self) -> int:
        """Control steps at which a safety filter changed a velocity reference, over the fleet."""
        return sum(node.vehicle.interventions for node in [*self._retired, *self.nodes])

    def _report_link_changes(self) -> None:
        for node in self.nodes:
            for ev in burst_events(node.bursts, self.ids):
                self._note(ev)
        emulator = self.link.faults
        changes = emulator.state_changes if emulator is not None else None
        if not changes or len(changes) == self._changes_seen:
            return
        for t, s, d, state in changes[self._changes_seen:]:
            self.sink.link_state(t, self.ids[s], self.ids[d], state)
            self._note(link_state_event(t, f"{self.ids[s]}->{self.ids[d]}", state))  # as the world reports them
        self._changes_seen = len(changes)

    def run(self, duration: float | None = None, progress: Callable[[float, float], None] | None = None
            ) -> RunResult:
        """Step to ``duration`` (default: the scenario's), inclusive of the last instant."""
        duration = self.scenario.duration if duration is None else duration
        ticks = total_ticks(duration, self.period)
        if ticks != self.end_tick:
            self.end_tick = ticks
            for node in self.nodes:
                node.last_tick = ticks
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

    def partial_metrics(self) -> Metrics:
        """The metrics of what has run so far (also after an interruption)."""
        counters = sum_counters(node.counters for node in [*self._retired, *self.nodes])
        emulator = link_faults_of(self.link)
        faults = None if emulator is None else link_faults(emulator.counters_summary())
        radio = None if self.radio is None else radio_metrics(self.link.counters, self.radio_watch)
        return run_metrics(self.scenario, self.recorder, mode=self.mode, link=link_metrics(counters, faults),
                           wall_s=self.clock() - self._t0, policy=self.policy, events=self.events,
                           completed=self.tick > self.end_tick, interventions=self.interventions, radio=radio,
                           deflected=[sum(x.vehicle.deflected for x in [*self._retired, *self.nodes] if x.index == j)
                                      for j in range(len(self.nodes))])

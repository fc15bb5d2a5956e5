"""What does the run leave behind: its record, its metrics and its trace?

Tick n is recorded with each vehicle's own row of n (a vehicle that did not step it repeats
its last), as the in-process fleet records it; at the end the metrics are built with the
same builder as `cdus sim` (cdus.sim.summary) from every process's counters, and their JSON
written where asked, or where a full disk lets it be (cdus.files.metrics_fallbacks)."""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections import Counter
from pathlib import Path

from cdus.core.link import LinkCounters, merge_link_summaries
from cdus.core.radiolink import RadioCounters
from cdus.files import keep_json, metrics_fallbacks
from cdus.sim.build import build_vehicle
from cdus.sim.radio import radio_metrics
from cdus.sim.runmetrics import LinkMetrics, Metrics, RadioMetrics, RejectedByReason
from cdus.sim.sink import UPDATE_EVERY
from cdus.sim.summary import COMPLETED, link_faults, link_metrics, run_metrics
from cdus.wire.messages import StateMsg, encode_control
from cdus.wire.schemas import AgentStats
from world_sim.limits import FINAL_WAIT_S
from world_sim.status import _say


class Finishing:
    """The World's record of each tick and, at the end, its metrics and trace (a mixin of
    World)."""

    def _record(self, n: int) -> bool:
        """Record tick n: each vehicle's own row of tick n; one that did not step it (not live, or
        realtime: its row is late) repeats the row it was last recorded with, or its newest at or
        before n. Never a row of another tick as n's, never one nobody sent."""
        st = self.st
        row = st.rows.get(n, {})
        states = []
        for j in range(len(self.ids)):
            m = row.get(j)
            if m is None:
                latest, last = st.latest.get(j), self._recorded.get(j)
                m = max((x for x in (latest, last) if x is not None and x.tick <= n), key=lambda x: x.tick,
                        default=last)
            if m is None and self.clock.starts_unseen(j, n, latest):
                m = self._initial_row(j)  # paused or killed from tick 0: where it starts, as cdus sim has it
            if m is None:
                return False  # a vehicle never reported: nothing to record yet
            states.append(m)
        st.rows.pop(n, None)
        for j, m in enumerate(states):
            self._recorded[j] = m
        self.recorder.record(n * self.period, states, self.clock.live_at(n), self._interventions)
        self.next_tick = n + 1
        for event in self._change_events.pop(n, ()):
            self._note(event)
        if n % UPDATE_EVERY == 0:
            self.sink.update(self.recorder)
        return True

    def _initial_row(self, j: int) -> StateMsg:
        """Vehicle j's state before its first tick (a scheduled pause or kill at t = 0 keeps it
        from ever reporting one until it is back; the world recorded nothing and waited for ever)."""
        if j not in self._initial:
            tel = build_vehicle(self.scenario.vehicles[j], self.scenario.rates, self.scenario.seed,
                                self.scenario.safety).telemetry()
            self._initial[j] = StateMsg(j, 0, tel.t, tuple(tel.q), tel.heading, tel.speed, tel.omega, tel.omega_rate,
                                        tel.path_error)
        return self._initial[j]

    def _processes(self) -> list[AgentStats]:
        """The last stats of every agent process of the run, restarted ones' included."""
        return [*self.st.retired, *self.st.stats.values()]

    def link_metrics(self) -> LinkMetrics:
        """``link`` of the metrics, as the in-process fleet builds it (cdus.sim.summary): every
        process's counters, every latency sample, and ``faults`` only when the scenario's link
        has faults or a ground station set some (the agents' summaries, checked where they came in
        with their stats, merged)."""
        total = LinkCounters(latencies=list(self.st.latencies.latencies))
        missed = 0
        rejected = self.st.rejected
        for s in self._processes():
            total.add(LinkCounters(sent=s.sent_to_me, delivered=s.delivered, dropped=s.dropped,
                                   duplicated=s.duplicated))
            rejected += s.rejected
            missed += s.missed_deadlines
        total.rejected = rejected
        faults = [s.faults for s in self._processes() if isinstance(s.faults, dict)]
        merged = None
        if faults and (not self.scenario.link.is_ideal or self.st.link_commanded):
            try:
                summary = merge_link_summaries(faults)
                # every change seen during the run, not just each agent's newest
                summary["state_changes"] = [{"t": t, "link": link, "state": state}
                                            for t, link, state in sorted(self.st.link_changes)]
                merged = link_faults(summary)
            except (KeyError, TypeError) as e:  # an agent's summary that does not parse
                self.log(f"link fault summaries could not be merged: {e!r}")
        return link_metrics(total, merged, missed_deadlines=missed)

    def _radio_metrics(self) -> RadioMetrics | None:
        """``radio`` of the metrics (with [radio] only): every process's radio counters summed,
        the utilisation and splits the world saw."""
        if self.radio is None or self.radio_watch is None:
            return None
        total = RadioCounters()
        for s in self._processes():
            if isinstance(s.radio, dict):
                total.add(RadioCounters.from_dict(s.radio))
        return radio_metrics(total, self.radio_watch)

    def _completion(self) -> str:
        """COMPLETED if every tick to the end was stepped by the live fleet, else why not
        (docs/metrics.md, ``completion``)."""
        if not self.started:  # whatever stopped it (the launcher gave up waiting, a signal): nothing ran
            return "not_started"
        if self.completion is not None:
            return self.completion
        lost = self.clock.lost()
        if self.next_tick > self.last_tick and not self.stop_requested:
            return "vehicles_lost" if lost else COMPLETED
        return "vehicles_lost" if lost else "interrupted"

    def rejects_by_reason(self) -> RejectedByReason:
        """What was dropped, by reason: by the world, and by the vehicles (every process's last counters)."""
        vehicles: Counter = Counter()
        for s in self._processes():
            vehicles.update(s.rejected_by_reason)
        return RejectedByReason(world=dict(sorted(self.st.rejects.items())), vehicles=dict(sorted(vehicles.items())))

    def finish(self) -> Metrics:
        """Tell the agents to stop, write the metrics (and trace). Safe to call after a stop."""
        self.finished = True
        # before the stop: the vehicles up then leave with it (a run that never began: who never came)
        never_up = None if self.started else [v for v in self.ids if v not in self.st.alive]
        completion = self._completion()  # decided by the run, not by the vehicles leaving at the stop
        if self.session is not None:
            self._publish_status(completion)  # first: a console reads the vehicles' leaving as the run's end
            self.st.finals = set()
            up = set(self.st.alive)
            self.pub_ctl.put(encode_control("stop"))
            # let the agents' last counters arrive: every vehicle up sends its last report as it
            # closes (AgentStats.final); one that does not (frozen, cut off) is waited for FINAL_WAIT_S
            deadline = time.monotonic() + FINAL_WAIT_S
            while time.monotonic() < deadline and not up <= self.st.finals:
                self._drain(block=False, until=deadline)  # a flood that never lets the inbox empty: no longer
                time.sleep(0.005)
            self._drain(block=False, until=max(deadline, time.monotonic() + 0.005))
        wall = time.perf_counter() - self._t_start if self.started else 0.0
        metrics = run_metrics(self.scenario, self.recorder, mode=self.clock.name, link=self.link_metrics(),
                              wall_s=wall, policy=self.policy, events=self.events,
                              interventions=sum(s.interventions for s in self._processes()),
                              deflected=[sum(s.deflected for s in self._processes() if s.id == v) for v in self.ids],
                              completed=completion == COMPLETED, completion=completion,
                              rejected_by_reason=self.rejects_by_reason(), integrity=self.integrity_block(),
                              never_up=never_up, radio=self._radio_metrics())
        if self.metrics_out:
            self._keep_metrics(metrics)
        if self.trace_out and len(self.recorder):
            try:
                self.recorder.save_trace(self.trace_out)
            except OSError as e:  # a full disk: said, the metrics (written first) are kept
                self.not_written.append("the trace")
                self.log(f"error: could not write the trace to {self.trace_out}: {e.strerror or e}")
                with contextlib.suppress(OSError):  # no half a trace that looks like one
                    if os.path.isfile(self.trace_out):
                        os.unlink(self.trace_out)
        self.sink.update(self.recorder)
        self.sink.close()
        return metrics

    def _keep_metrics(self, metrics: Metrics) -> None:
        """The metrics at metrics_out, or (a full disk, a read-only directory: which file and why
        said) at the first of :func:`cdus.files.metrics_fallbacks` that takes them, the launcher
        looking there too; where nothing takes them, printed whole as JSON on stdout."""
        fallbacks = metrics_fallbacks(self.metrics_out, self.run_dir, f"{self.fleet}-{os.getpid()}")
        at = keep_json(self.metrics_out, metrics.to_dict(), fallbacks, self.log)
        if at is not None and at == Path(self.metrics_out):
            self.log(f"metrics written to {self.metrics_out}")
            return
        self.not_written.append("the metrics")
        if at is None:
            self.log("the metrics could be written nowhere; here they are:")
            _say(json.dumps(metrics.to_dict(), default=str), prefix="")

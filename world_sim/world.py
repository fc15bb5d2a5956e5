"""The world process: sees every vehicle, owns the lockstep clock, computes the metrics.

It subscribes to every vehicle's telemetry and counters, watches liveliness (who is
alive, whether the live graph still has a spanning tree), drives the clock and, at the
end or on a stop, writes the metrics JSON with the same Recorder as `cdus sim`.

Lockstep: the world grants ticks ahead of the slowest vehicle by a window W; it does not
need to wait for each tick itself, because what couples vehicles is their ω messages and
each agent waits for its neighbours' (see vehicle_agent.agent). It records tick n once
every live vehicle has reported it.

Realtime: the world publishes a start time t0 once every vehicle is alive and records
tick n a little after it is due, with each vehicle's newest telemetry at or before n.
"""

from __future__ import annotations

import json
import math
import signal
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import msgpack
import zenoh

from cdus.core import graph as graphs
from cdus.wire import keys
from cdus.files import write_json
from cdus.wire.transport import Transport, open_session
from cdus.core.link import LinkCounters, merge_link_summaries
from cdus.wire.messages import (
    COMMAND_OPS, StateMsg, decode_control, decode_states, encode_control, encode_states,
)
from cdus.core.schedule import total_ticks
from cdus.sim.fleet import link_summary
from cdus.core.metrics import Recorder
from cdus.sim.build import metric_edges
from cdus.sim.sink import UPDATE_EVERY, NullSink, Sink

GRANT_WINDOW = 50  # ticks the fastest vehicle may run ahead of the slowest (lockstep)
REALTIME_LAG = 8  # ticks the world waits before recording a realtime tick (> the telemetry batch)
STATUS_PERIOD = 1.0


@dataclass
class Shared:
    cond: threading.Condition = field(default_factory=threading.Condition)
    rows: dict[int, dict[int, StateMsg]] = field(default_factory=dict)  # tick -> sender -> state
    latest: dict[int, StateMsg] = field(default_factory=dict)
    acked: dict[int, int] = field(default_factory=dict)  # sender -> newest tick reported
    alive: set[str] = field(default_factory=set)
    stats: dict[str, dict] = field(default_factory=dict)
    events: list[str] = field(default_factory=list)
    first_tick: dict[int, int] = field(default_factory=dict)  # sender -> first tick since it (re)joined
    fault_done: set[str] = field(default_factory=set)  # vehicles the launcher has acted on
    paused_at: float | None = None  # wall time of a fleet pause, while paused
    paused_for: float = 0.0  # wall seconds the fleet has been paused in all
    came_back: set[str] = field(default_factory=set)  # vehicles whose token (re)appeared
    stop: bool = False
    rejected: int = 0


class World:
    def __init__(self, scenario: Any, fleet: str, transport: Transport, clock: str = "lockstep",
                 duration: float | None = None, metrics_out: str | None = None, trace_out: str | None = None,
                 start_timeout: float = 60.0, log: Callable[[str], None] | None = None, sink: Sink | None = None):
        self.scenario = scenario
        self.fleet = keys.check_fleet(fleet)
        self.transport = transport
        self.clock = clock
        self.ids = [v.id for v in scenario.vehicles]
        self.index = {vid: j for j, vid in enumerate(self.ids)}
        self.period = 1.0 / scenario.rates.control
        self.duration = scenario.duration if duration is None else duration
        self.last_tick = total_ticks(self.duration, self.period)
        self.metrics_out = metrics_out
        self.trace_out = trace_out
        self.start_timeout = start_timeout
        self.sink = sink or NullSink()
        self.recorder = Recorder(self.ids, [v.dim for v in scenario.vehicles], metric_edges(scenario))
        self.sh = Shared()
        self.pairs = [(e.i, e.k) for e in scenario.edges]
        self.log = log or (lambda s: print(f"[world] {s}", flush=True))
        self.next_tick = 0  # next tick to record
        self.started = False
        self.finished = False
        self.events = list(scenario.events)  # scheduled vehicle faults
        self._link_changes_seen: set[tuple] = set()
        self.session = None
        self._t_start = time.perf_counter()

    # ------------------------------------------------------------------ wiring
    def open(self) -> None:
        s = self.session = open_session(self.transport)
        f = self.fleet
        self._subs = [
            s.declare_subscriber(keys.any_vehicle(f, "state"), self._on_state),
            s.declare_subscriber(keys.any_vehicle(f, "stats"), self._on_stats),
            s.declare_subscriber(keys.cmd(f, keys.WORLD), self._on_command),
            s.liveliness().declare_subscriber(keys.any_alive(f), self._on_liveliness, history=True),
            s.declare_queryable(keys.world_last(f, "*"), self._on_last_query),
            s.declare_subscriber(keys.cmd(f, keys.ALL), self._on_fleet_command),
        ]
        self.pub_launcher = s.declare_publisher(keys.cmd(f, "launcher"))
        self.pub_clock = s.declare_publisher(keys.clock(f), congestion_control=zenoh.CongestionControl.BLOCK)
        self.pub_status = s.declare_publisher(keys.world_status(f))
        self.pub_events = s.declare_publisher(keys.world_events(f))
        self.token = s.liveliness().declare_token(keys.alive(f, keys.WORLD))
        self.log(f"ready: fleet {f!r}, {len(self.ids)} vehicles, clock {self.clock}, "
                 f"{self.duration:g} s at {self.scenario.rates.control:g} Hz")

    def close(self) -> None:
        if self.session is None:
            return
        try:
            self.token.undeclare()
            self.session.close()
        except Exception as e:
            self.log(f"while closing the session: {e}")
        self.session = None

    def _on_state(self, sample: Any) -> None:
        vid = keys.vehicle_of(str(sample.key_expr))
        rows = decode_states(sample.payload.to_bytes(), len(self.ids))
        sh = self.sh
        with sh.cond:
            if isinstance(rows, str) or vid not in self.index or self.index[vid] != rows[0].sender:
                sh.rejected += 1
                return
            sh.first_tick.setdefault(rows[0].sender, rows[0].tick)
            for m in rows:
                if m.tick >= self.next_tick:
                    sh.rows.setdefault(m.tick, {})[m.sender] = m
                prev = sh.latest.get(m.sender)
                if prev is None or m.tick >= prev.tick:
                    sh.latest[m.sender] = m
                sh.acked[m.sender] = max(sh.acked.get(m.sender, -1), m.tick)
            sh.cond.notify_all()

    def _on_last_query(self, query: Any) -> None:
        """A restarted agent asks where its vehicle was: reply with its newest telemetry."""
        vid = str(query.key_expr).rsplit("/", 1)[-1]
        with self.sh.cond:
            m = self.sh.latest.get(self.index[vid]) if vid in self.index else None
        if m is not None:
            query.reply(str(query.key_expr), encode_states([m]))

    def _on_stats(self, sample: Any) -> None:
        vid = keys.vehicle_of(str(sample.key_expr))
        try:
            st = msgpack.unpackb(sample.payload.to_bytes(), raw=False, max_str_len=256, max_array_len=1024,
                                 max_map_len=64, max_bin_len=0)
        except Exception:
            st = None
        with self.sh.cond:
            if vid in self.index and isinstance(st, dict):
                self.sh.stats[vid] = st
                self._forward_link_changes(st.get("faults"))
                for text in st.get("bursts") or []:
                    if isinstance(text, str) and self.started:
                        self._event(text[:200])
            else:
                self.sh.rejected += 1

    def _forward_link_changes(self, faults: Any) -> None:
        """New link state changes an agent reports: to the event log and the recording."""
        if not isinstance(faults, dict):
            return
        for ch in faults.get("state_changes") or []:
            try:
                key = (float(ch["t"]), str(ch["link"]), str(ch["state"]))
            except (KeyError, TypeError, ValueError):
                continue
            if key in self._link_changes_seen:
                continue
            self._link_changes_seen.add(key)
            src, _, dst = key[1].partition("->")
            self.sink.link_state(key[0], src, dst, key[2])
            if self.started:
                self._event(f"link {key[1]} {key[2]} (from t = {key[0]:.2f} s)")

    def _on_command(self, sample: Any) -> None:
        c = decode_control(sample.payload.to_bytes(), COMMAND_OPS)
        with self.sh.cond:
            if isinstance(c, str):
                self.sh.rejected += 1
                return
            if c.op == "stop":
                self.sh.stop = True
            elif c.op == "fault_done":
                self.sh.fault_done.add(c.fields["vehicle"])
            self.sh.cond.notify_all()

    def _on_fleet_command(self, sample: Any) -> None:
        """Commands to every vehicle: note the ones that change the experiment."""
        c = decode_control(sample.payload.to_bytes(), COMMAND_OPS)
        if isinstance(c, str):
            return
        with self.sh.cond:
            if c.op == "link":
                self._event(f"link faults changed from t = {c.fields['at']:.2f} s: {c.fields['link']}")
            elif c.op in ("pause", "resume", "set_gains"):
                if c.op == "pause" and self.sh.paused_at is None:
                    self.sh.paused_at = time.time()
                elif c.op == "resume" and self.sh.paused_at is not None:
                    self.sh.paused_for += time.time() - self.sh.paused_at  # the realtime clock stood still
                    self.sh.paused_at = None
                self._event(f"fleet command {c.op} {c.fields or ''}".strip())
            self.sh.cond.notify_all()

    def _on_liveliness(self, sample: Any) -> None:
        vid = keys.vehicle_of(str(sample.key_expr))
        if vid not in self.index:
            return
        gone = str(sample.kind).endswith("DELETE")
        sh = self.sh
        with sh.cond:
            if self.finished:  # agents leaving after the stop are not news
                sh.alive.discard(vid)
                return
            if gone and vid in sh.alive:
                sh.alive.discard(vid)
                sh.first_tick.pop(self.index[vid], None)
                sh.acked.pop(self.index[vid], None)
                self._event(f"vehicle {vid} lost")
                self._check_graph()
            elif not gone and vid not in sh.alive:
                sh.alive.add(vid)
                sh.came_back.add(vid)
                if self.started:
                    self._event(f"vehicle {vid} back")
                    self._check_graph()
            sh.cond.notify_all()

    def _event(self, text: str) -> None:
        t = self.next_tick * self.period
        line = f"t = {t:.2f} s: {text}"
        self.sh.events.append(line)
        self.sink.event(t, text, "warn" if "lost" in text or "no spanning" in text else "info")
        self.log(line)
        if self.session is not None:
            try:
                self.pub_events.put(line.encode())
            except Exception:
                pass

    def _check_graph(self) -> None:
        alive = [v for v in self.ids if v in self.sh.alive]
        pairs = [(i, k) for i, k in self.pairs if i in self.sh.alive and k in self.sh.alive]
        cut = graphs.unreachable(alive, pairs) if alive else []
        if cut:
            self._event(f"the live graph has no spanning tree: {', '.join(cut)} cut off")
        else:
            self._event(f"the live graph ({len(alive)} vehicles) still has a spanning tree")

    # ------------------------------------------------------------------ the run
    def run(self) -> dict:
        sh = self.sh
        deadline = time.monotonic() + self.start_timeout
        with sh.cond:
            while len(sh.alive) < len(self.ids) and not sh.stop:
                if time.monotonic() > deadline:
                    missing = [v for v in self.ids if v not in sh.alive]
                    raise TimeoutError(f"vehicles not up after {self.start_timeout:g} s: {', '.join(missing)}")
                sh.cond.wait(timeout=0.5)
        self.started = True
        self._t_start = time.perf_counter()
        self.sink.start(self.scenario)
        if self.clock == "lockstep":
            self._run_lockstep()
        else:
            self._run_realtime()
        return self.finish()

    def _run_lockstep(self) -> None:
        sh = self.sh
        granted = -1
        last_status = last_grant = 0.0
        while self.next_tick <= self.last_tick:
            with sh.cond:
                if sh.stop:
                    return
                # vehicles that have not reported since they (re)joined do not hold the grant back
                slowest = min((sh.acked[self.index[v]] for v in sh.alive if self.index[v] in sh.first_tick),
                              default=self.next_tick - 1)
                want = min(self.last_tick, max(slowest, self.next_tick - 1) + GRANT_WINDOW)
                if self.events:  # hold the fleet at a scheduled fault until it is carried out
                    ev_tick = math.ceil(self.events[0].at / self.period - 1e-9)
                    want = min(want, ev_tick - 1)
                    if self.next_tick >= ev_tick:
                        self._carry_out(self.events.pop(0), wait=True)
                        continue
                front = max(sh.acked.values(), default=-1) + 1  # where a late joiner starts
            now = time.monotonic()
            if sh.paused_at is not None:  # a paused fleet gets no new ticks
                want = granted
            if want > granted or now - last_grant > 0.5:  # re-sent now and then for late joiners
                granted, last_grant = max(granted, want), now
                self.pub_clock.put(encode_control("grant", until=granted, front=front))
            with sh.cond:
                self._record_complete()
                if self.next_tick <= self.last_tick and not sh.stop:
                    sh.cond.wait(timeout=0.5)
            if now - last_status > STATUS_PERIOD:
                last_status = now
                self._publish_status()

    def _record_complete(self) -> None:
        """Record every tick all live vehicles have reported (caller holds the lock)."""
        sh = self.sh
        live = [self.index[v] for v in sh.alive]
        while self.next_tick <= self.last_tick:
            n = self.next_tick
            row = sh.rows.get(n, {})
            # a vehicle that (re)joined later than n, or has not reported since, is not waited for
            if any(j not in row and sh.first_tick.get(j, n + 1) <= n for j in live):
                return
            self._record(n)
            if self.next_tick == n:
                return

    def _record(self, n: int) -> None:
        sh = self.sh
        row = sh.rows.get(n, {})
        states = []
        for j in range(len(self.ids)):
            m = row.get(j) or sh.latest.get(j)
            if m is None:
                return  # a vehicle never reported: nothing to record yet
            states.append(m)
        sh.rows.pop(n, None)
        self.recorder.record(n * self.period, states)
        self.next_tick = n + 1
        if n % UPDATE_EVERY == 0:
            self.sink.update(self.recorder)

    def _run_realtime(self) -> None:
        sh = self.sh
        T = self.period
        t0 = time.time() + 0.5
        self.t0 = t0
        self.pub_clock.put(encode_control("start", t0=t0))
        last_status = 0.0
        while self.next_tick <= self.last_tick:
            while self.events and time.time() - t0 >= self.events[0].at:
                with sh.cond:
                    self._carry_out(self.events.pop(0), wait=False)
            if sh.paused_at is not None:
                with sh.cond:
                    sh.cond.wait(timeout=0.2)
                continue
            t0 = self.t0 + sh.paused_for
            due_tick = int((time.time() - t0) / T) - REALTIME_LAG
            with sh.cond:
                if sh.stop:
                    return
                while self.next_tick <= min(due_tick, self.last_tick):
                    n = self.next_tick
                    self._record(n)
                    if self.next_tick == n:  # nobody has reported yet
                        break
                    # drop rows older than what was recorded
                    for old in [k for k in sh.rows if k < self.next_tick]:
                        sh.rows.pop(old)
                sh.cond.wait(timeout=T)
            now = time.monotonic()
            if now - last_status > STATUS_PERIOD:
                last_status = now
                self._publish_status()
                self.pub_clock.put(encode_control("start", t0=t0))  # again, for late joiners
        # give the final tick's telemetry a moment, then record what is left with the newest states
        end = time.monotonic() + 2.0
        with sh.cond:
            live = [self.index[v] for v in sh.alive]
            while (any(sh.acked.get(j, -1) < self.last_tick for j in live) and time.monotonic() < end
                   and not sh.stop):
                sh.cond.wait(timeout=0.1)
            while self.next_tick <= self.last_tick:
                n = self.next_tick
                self._record(n)
                if self.next_tick == n:
                    break

    def _carry_out(self, ev: Any, wait: bool) -> None:
        """Ask the launcher to kill/pause/resume/restart a vehicle (caller holds the lock).

        In lockstep the fleet waits for the launcher's acknowledgement, so the fault lands
        at its tick; in realtime it lands as soon as the launcher acts.
        """
        op = {"pause": "pause_vehicle", "resume": "resume_vehicle"}.get(ev.action, ev.action)
        self._event(f"scheduled {ev.action} of {ev.vehicle} (at {ev.at:g} s)")
        self.sh.fault_done.discard(ev.vehicle)
        self.sh.came_back.discard(ev.vehicle)
        self.pub_launcher.put(encode_control(op, vehicle=ev.vehicle))
        if not wait:
            return
        deadline = time.monotonic() + 10.0
        while ev.vehicle not in self.sh.fault_done and not self.sh.stop:
            if time.monotonic() > deadline:
                self._event(f"no launcher carried out the {ev.action} of {ev.vehicle} within 10 s; going on")
                return
            self.sh.cond.wait(timeout=0.2)
        if ev.action == "restart":  # hold the fleet until the new process is up, so it rejoins on time
            deadline = time.monotonic() + 30.0
            while ev.vehicle not in self.sh.came_back and not self.sh.stop and time.monotonic() < deadline:
                self.sh.cond.wait(timeout=0.2)

    def _publish_status(self) -> None:
        sh = self.sh
        n = len(self.recorder)
        status = {
            "v": 1, "t": (self.next_tick - 1) * self.period, "duration": self.duration, "clock": self.clock,
            "alive": sorted(sh.alive), "vehicles": len(self.ids), "ids": self.ids,
            "events": sh.events[-10:],
            "path_error_max": float(self.recorder.view("path_error")[-1].max()) if n else None,
            "coord_error_max": (float(self.recorder.edge_error()[-1].max())
                                if n and self.recorder.edges else None),
        }
        try:
            self.pub_status.put(json.dumps(status).encode())
        except Exception:
            pass

    def stop(self) -> None:
        with self.sh.cond:
            self.sh.stop = True
            self.sh.cond.notify_all()

    def link_block(self) -> dict:
        total = LinkCounters()
        missed = 0
        rejected = self.sh.rejected
        for st in self.sh.stats.values():
            total.sent += int(st.get("sent_to_me", 0))
            total.delivered += int(st.get("delivered", 0))
            total.dropped += int(st.get("dropped", 0))
            total.duplicated += int(st.get("duplicated", 0))
            rejected += int(st.get("rejected", 0))
            missed += int(st.get("missed_deadlines", 0))
            total.latencies.extend(x / 1000.0 for x in st.get("latencies_ms", []))
        total.rejected = rejected
        out = link_summary(total)
        out["missed_deadlines"] = missed
        faults = [st["faults"] for st in self.sh.stats.values() if isinstance(st.get("faults"), dict)]
        if faults:
            try:
                merged = merge_link_summaries(faults)
                # every change seen during the run, not just each agent's newest
                merged["state_changes"] = [{"t": t, "link": link, "state": state}
                                           for t, link, state in sorted(self._link_changes_seen)]
                out["faults"] = merged
            except (KeyError, TypeError):
                pass
        return out

    def finish(self) -> dict:
        """Tell the agents to stop, write the metrics (and trace). Safe to call after a stop."""
        with self.sh.cond:
            self.finished = True
        try:
            if self.session is not None:
                self.pub_clock.put(encode_control("stop"))
        except Exception:
            pass
        time.sleep(0.2)  # let the agents' last counters arrive
        sc = self.scenario
        wall = time.perf_counter() - self._t_start
        if len(self.recorder):
            metrics = self.recorder.summary(scenario=sc.name, mode=self.clock, seed=sc.seed, path_tol=sc.path_tol,
                                            coord_tol=sc.coord_tol, link=self.link_block(), wall_s=wall)
        else:
            metrics = {"scenario": sc.name, "mode": self.clock, "seed": sc.seed, "duration_s": 0.0,
                       "path_tol": sc.path_tol, "coord_tol": sc.coord_tol, "path_settle_s": None,
                       "coord_settle_s": None, "final_path_error_max": None, "final_coord_error_max": None,
                       "omega_rate_final": {}, "link": self.link_block(), "wall_s": wall, "realtime_factor": None}
        metrics["events"] = list(self.sh.events)
        metrics["completed"] = self.next_tick > self.last_tick
        if self.metrics_out:
            write_json(self.metrics_out, metrics)
            self.log(f"metrics written to {self.metrics_out}")
        if self.trace_out and len(self.recorder):
            self.recorder.save_trace(self.trace_out)
        self.sink.update(self.recorder)
        self.sink.close()
        return metrics


def run_world(world: World) -> int:
    """Open, run, write; SIGINT/SIGTERM stop the run and still write the metrics."""
    def _stop(signum, frame):
        world.stop()

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    try:
        world.open()
        m = world.run()
        world.log(f"done: path settle {m['path_settle_s']}, coordination settle {m['coord_settle_s']}")
        return 0
    except TimeoutError as e:
        world.log(f"error: {e}")
        world.finish()
        return 1
    finally:
        world.close()

"""The vehicle process: one vehicle's core (vehicle.Vehicle) wired to Zenoh.

It subscribes to its neighbours' ω keys only, publishes its own ω, its telemetry and
its counters, declares a liveliness token once it is ready, and follows the world's clock:

- lockstep: it steps tick n once the world has granted it and it holds every live
  neighbour's newest broadcast sent before tick n (so the run is deterministic and equal
  to the in-process one, whatever the OS scheduling);
- realtime: it steps on the wall clock from the world's start time t0, tick n at
  t0 + n T, using whatever has arrived; a tick finishing after the next one was due is a
  missed deadline.

Everything received is validated (cdus.wire.messages) on Zenoh's thread and counted
when rejected; only valid messages reach the main loop, through a lock-protected inbox.
The link model decides drops and delays at this receiver, per (src, dst, seq).
"""

from __future__ import annotations

import heapq
import math
import signal
import sys
import threading
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from typing import Any, Callable

import zenoh

from cdus.scenario.config import ConfigError
from cdus.scenario.link import validate_link
from cdus.wire import keys
from cdus.wire.transport import Transport, open_session
from cdus.core.link import DropBursts, IdealLink, LinkCounters, LinkModel, burst_text
from cdus.wire.messages import (
    CLOCK_OPS, COMMAND_OPS, OmegaMsg, StateMsg, decode_control, decode_omega, decode_states, encode_omega, encode_states,
)
from cdus.core.neighbours import NeighbourTable, consensus_target
from cdus.sim.build import build_vehicle, links_of
from cdus.core.schedule import broadcast_every, delivery_tick, last_broadcast_seq, send_tick, total_ticks
from cdus.core.vehicle import Vehicle

CLOCKS = ("realtime", "lockstep")
STATE_BATCH = {"lockstep": 10, "realtime": 5}  # telemetry rows per message
STATS_PERIOD = 1.0
STALL_TICKS = 10  # realtime: this many periods late means the process was frozen, not just slow  # s of wall time between counter reports
END_WAIT = 10.0  # s to wait for the world's stop after the last tick


@dataclass
class Inbox:
    """What Zenoh's threads hand to the main loop, under one condition variable."""

    cond: threading.Condition = field(default_factory=threading.Condition)
    omega: list[tuple[float, OmegaMsg]] = field(default_factory=list)  # (receive wall time, message)
    seen_seq: dict[int, int] = field(default_factory=dict)  # newest seq physically received per sender
    granted: int = -1
    front: int = -1  # the world's front tick at the first grant we saw (> 0: we join late)
    need_seq: int = -1  # lockstep: the broadcast the main loop is waiting for (-1: not waiting)
    t0: float | None = None
    stop: bool = False
    paused: bool = False
    commands: list[Any] = field(default_factory=list)
    gone: set[int] = field(default_factory=set)  # neighbours whose liveliness token is gone
    back: set[int] = field(default_factory=set)  # neighbours whose token (re)appeared
    rejected: Counter = field(default_factory=Counter)


class Agent:
    def __init__(self, scenario: Any, vid: str, fleet: str, transport: Transport, clock: str = "realtime",
                 policy: str = "hold", timeout: float = 1.5, link: LinkModel | None = None,
                 duration: float | None = None, log: Callable[[str], None] | None = None):
        if clock not in CLOCKS:
            raise ValueError(f"clock must be one of {CLOCKS}, got {clock!r}")
        self.scenario = scenario
        self.spec = scenario.vehicle(vid)
        self.id = vid
        self.index = self.spec.index
        self.fleet = keys.check_fleet(fleet)
        self.transport = transport
        self.clock = clock
        self.ids = [v.id for v in scenario.vehicles]
        self.vehicle = build_vehicle(self.spec, scenario.rates, scenario.seed)
        self.table = NeighbourTable(links_of(scenario, vid), policy, timeout)
        self.neighbours = sorted({ln.k for ln in self.table.links})
        self.link = link or IdealLink()
        self.link_table: dict = scenario.link_table
        self.period = 1.0 / scenario.rates.control
        self.every = broadcast_every(scenario.rates)
        self.last_tick = total_ticks(scenario.duration if duration is None else duration, self.period)
        self.inbox = Inbox()
        self.counters = LinkCounters()
        self.missed_deadlines = 0
        self.ticks_done = 0
        self.joined_at = 0
        self._due: dict[int, list[tuple[OmegaMsg, float]]] = defaultdict(list)  # lockstep: (msg, delay) by tick
        self._pending: list[tuple[float, int, int, OmegaMsg]] = []  # realtime: (usable sim time, order, -, msg)
        self._order = 0
        self.bursts = DropBursts()  # runs of drops on our incoming links, for the event log
        self._bursts_sent = 0
        self._early: list[tuple[float, OmegaMsg]] = []  # lockstep: arrived before we reached their tick
        # Telemetry goes to the world in batches (rows per message): fewer messages, less
        # CPU on a loaded machine; the world records a tick once every row for it is in.
        self.state_batch = STATE_BATCH[clock]
        self._states: list[StateMsg] = []
        self._logged_rejects: set[tuple[str, str]] = set()
        self.log = log or (lambda s: print(f"[{vid}] {s}", flush=True))
        self.session = None

    # ------------------------------------------------------------------ zenoh wiring
    def open(self) -> None:
        s = self.session = open_session(self.transport)
        f = self.fleet
        self._subs = []
        for k in self.neighbours:
            # the sender is known from the subscription: no key parsing on the receive path
            self._subs.append(s.declare_subscriber(keys.omega(f, self.ids[k]),
                                                   lambda sample, k=k: self._on_omega(sample, k)))
        self._subs.append(s.declare_subscriber(keys.clock(f), self._on_clock))
        self._subs.append(s.declare_subscriber(keys.cmd(f, self.id), self._on_command))
        self._subs.append(s.declare_subscriber(keys.cmd(f, keys.ALL), self._on_command))
        self._subs.append(s.liveliness().declare_subscriber(keys.any_alive(f), self._on_liveliness, history=True))
        # Block rather than drop under congestion: losses are the link emulator's job, and a
        # lockstep neighbour waits for every broadcast. (``express`` measured no latency gain
        # and a tenfold throughput loss into Python callbacks.)
        block = zenoh.CongestionControl.BLOCK
        self.pub_omega = s.declare_publisher(keys.omega(f, self.id), congestion_control=block)
        self.pub_state = s.declare_publisher(keys.state(f, self.id), congestion_control=block)
        self.pub_stats = s.declare_publisher(keys.stats(f, self.id))
        # Ready: every subscriber is in place. The token tells the world and the launcher.
        self.token = s.liveliness().declare_token(keys.alive(f, self.id))
        self.log(f"ready: {self.spec.kind} on a {dict(self.spec.path)['family']} path, "
                 f"neighbours {[self.ids[k] for k in self.neighbours]}, clock {self.clock}")

    def close(self) -> None:
        if self.session is None:
            return
        try:
            self.publish_stats()
            self.token.undeclare()
            self.session.close()
        except Exception as e:  # closing must never hide the run's own outcome
            self.log(f"while closing the session: {e}")
        self.session = None

    def _reject(self, sender: str, reason: str) -> None:
        self.inbox.rejected[reason] += 1
        if (sender, reason) not in self._logged_rejects:  # log once per sender and reason
            self._logged_rejects.add((sender, reason))
            self.log(f"rejected a message from {sender!r}: {reason} (counted; logged once)")

    def _on_omega(self, sample: Any, sender: int) -> None:
        msg = decode_omega(sample.payload.to_bytes(), expected_sender=sender, n_vehicles=len(self.ids))
        if isinstance(msg, str):
            return self._reject(self.ids[sender], msg)
        now = time.time()
        ib = self.inbox
        with ib.cond:
            if msg.seq <= ib.seen_seq.get(sender, -1):
                ib.rejected["stale"] += 1
                return
            ib.seen_seq[sender] = msg.seq
            ib.omega.append((now, msg))
            # wake the main loop only when it waits for this message (lockstep); a realtime
            # loop wakes at its tick anyway
            if ib.need_seq >= 0 and msg.seq >= ib.need_seq:
                ib.cond.notify_all()

    def _on_clock(self, sample: Any) -> None:
        c = decode_control(sample.payload.to_bytes(), CLOCK_OPS)
        if isinstance(c, str):
            return self._reject("clock", c)
        ib = self.inbox
        with ib.cond:
            if c.op == "grant":
                ib.granted = max(ib.granted, c.fields["until"])
                if ib.front < 0:
                    ib.front = c.fields["front"]
            elif c.op == "start":
                ib.t0 = c.fields["t0"]
            elif c.op == "stop":
                ib.stop = True
            ib.cond.notify_all()

    def _on_command(self, sample: Any) -> None:
        c = decode_control(sample.payload.to_bytes(), COMMAND_OPS)
        if isinstance(c, str):
            return self._reject("command", c)
        ib = self.inbox
        with ib.cond:
            if c.op == "stop":
                ib.stop = True
            elif c.op == "pause":
                ib.paused = True
            elif c.op == "resume":
                ib.paused = False
            else:
                ib.commands.append(c)
            ib.cond.notify_all()

    def _on_liveliness(self, sample: Any) -> None:
        vid = keys.vehicle_of(str(sample.key_expr))
        if vid not in self.ids:
            return
        k = self.ids.index(vid)
        if k not in self.neighbours:
            return
        gone = str(sample.kind).endswith("DELETE")
        ib = self.inbox
        with ib.cond:
            if gone:
                ib.gone.add(k)
                ib.back.discard(k)
            else:
                ib.back.add(k)
            ib.cond.notify_all()

    # ------------------------------------------------------------------ the loop
    def run(self) -> int:
        """Step to the last tick (or a stop). Returns the number of ticks stepped."""
        if self.clock == "lockstep":
            self._run_lockstep()
        else:
            self._run_realtime()
        self._await_stop()
        return self.ticks_done

    def _take_inbox(self) -> tuple[list[tuple[float, OmegaMsg]], list[Any]]:
        """Swap out what arrived (caller holds the lock)."""
        ib = self.inbox
        msgs, ib.omega = ib.omega, []
        cmds, ib.commands = ib.commands, []
        for k in ib.gone:
            self.table.mark_absent(k)
            self.log(f"neighbour {self.ids[k]} is gone: left out of the consensus sum")
        ib.gone.clear()
        ib.back.clear()
        return msgs, cmds

    def _apply_commands(self, cmds: list[Any]) -> None:
        for c in cmds:
            if c.op == "link":
                self._update_link(c.fields["link"], c.fields["at"])
            elif c.op == "set_gains":
                self._set_gains(c.fields["gains"])

    def _update_link(self, table: dict, at: float) -> None:
        """Merge ``table`` over the current [link] table; it applies to messages sent from ``at`` on."""
        merged = {**self.link_table, **table}
        try:
            spec = validate_link(merged, self.ids, "link command")
            at = max(at, self.link.epochs[-1][0]) if getattr(self.link, "epochs", None) else at
            self.link.update(spec, at)
        except (ConfigError, ValueError) as e:
            self.inbox.rejected["bad_link_command"] += 1
            self.log(f"link command rejected: {e}")
            return
        self.link_table = merged
        self.log(f"link faults changed from t = {at:.2f} s: {table}")

    def _set_gains(self, gains: dict) -> None:
        v = self.vehicle
        k, c = gains.get("k", v.k), gains.get("c", v.c)
        if isinstance(k, (int, float)) and not isinstance(k, bool):
            k = (float(k),) * v.dim
        ok = (isinstance(k, (list, tuple)) and len(k) == v.dim and all(
              isinstance(x, (int, float)) and not isinstance(x, bool) and x > 0 for x in k)
              and isinstance(c, (int, float)) and not isinstance(c, bool) and c > 0)
        if not ok:
            self.inbox.rejected["bad_gains_command"] += 1
            self.log(f"set_gains rejected: k must be > 0 (one value or {v.dim}), c > 0; got {gains}")
            return
        v.k, v.c = tuple(float(x) for x in k), float(c)
        self.log(f"gains now k = {v.k}, c = {v.c}")

    def _rejoin(self, tick: int) -> None:
        """Join a run already under way at ``tick``: where the world last saw this vehicle,
        with ω near what its neighbours' consensus asks (not laps away)."""
        last: dict[int, StateMsg] = {}
        for j in [self.index, *self.neighbours]:
            try:
                for reply in self.session.get(keys.world_last(self.fleet, self.ids[j]), timeout=2.0):
                    if reply.ok is not None:
                        rows = decode_states(reply.ok.payload.to_bytes(), len(self.ids))
                        if not isinstance(rows, str) and rows[0].sender == j:
                            last[j] = rows[-1]
            except Exception as e:
                self.log(f"could not ask the world for {self.ids[j]}'s last state: {e}")
        target = consensus_target(self.table.links, {k: m.omega for k, m in last.items() if k != self.index})
        mine = last.get(self.index)
        hint = target if target is not None else (mine.omega if mine else None)
        if mine is not None:
            self.vehicle.rejoin(tick, mine.q, mine.heading, hint)
            where = f"its last known state q = {tuple(round(x, 2) for x in mine.q)}"
        else:
            self.vehicle.rejoin(tick, None, None, hint)
            where = "the configured start (no last state known)"
        self.log(f"rejoining at tick {tick} (t = {tick * self.period:.2f} s) from {where}, "
                 f"ω = {self.vehicle.omega:.3f}" + (" (near its neighbours' consensus)" if target is not None else ""))
        self.joined_at = tick

    def _run_lockstep(self) -> None:
        ib = self.inbox
        T = self.period
        with ib.cond:
            while ib.granted < 0 and not ib.stop:
                ib.cond.wait(timeout=1.0)
            front = ib.front
        first = 0
        if front > 0:  # the run is under way: a restarted process
            first = front
            self._rejoin(first)
        for n in range(first, self.last_tick + 1):
            # after a rejoin, messages sent before it were never heard: do not wait for them
            need = last_broadcast_seq(n - 1, self.every) if n > first or first == 0 else -1
            waited_since = time.monotonic()
            with ib.cond:
                while not ib.stop:
                    missing = [k for k in self.neighbours
                               if k not in ib.gone and k not in self.table.absent and ib.seen_seq.get(k, -1) < need]
                    if ib.granted >= n and not ib.paused and not missing:
                        break
                    ib.need_seq = need
                    ib.cond.wait(timeout=1.0)
                    if time.monotonic() - waited_since > 5.0:
                        waited_since = time.monotonic()
                        why = "the world's grant" if ib.granted < n else (
                            "resume" if ib.paused else f"ω from {[self.ids[k] for k in missing]}")
                        self.log(f"tick {n}: still waiting for {why}")
                ib.need_seq = -1
                if ib.stop:
                    return
                msgs, cmds = self._take_inbox()
            self._apply_commands(cmds)
            early = []
            for item in self._early + msgs:
                m = send_tick(item[1].t_send, T)
                if m >= n:  # from a neighbour already past us: decide it when it can matter
                    early.append(item)
                else:
                    self._route(item[1], m)
            self._early = early
            for msg, d in self._due.pop(n, ()):
                if self.table.offer(msg, n * T):
                    self.counters.delivered += 1
                    self.counters.record_latency(d)  # the emulated delay, in simulated time
                else:
                    self.counters.rejected += 1
            self._step(n)

    def _run_realtime(self) -> None:
        ib = self.inbox
        T = self.period
        with ib.cond:
            while ib.t0 is None and not ib.stop:
                ib.cond.wait(timeout=1.0)
            t0 = ib.t0
        if t0 is None:
            return
        n = max(0, math.ceil((time.time() - t0) / T))
        if n > 0:  # the run is under way: a restarted process
            self._rejoin(n)
        while n <= self.last_tick:
            target = t0 + n * T
            with ib.cond:
                while not ib.stop:
                    if ib.paused:
                        pause_start = time.time()
                        while ib.paused and not ib.stop:
                            ib.cond.wait(timeout=0.5)
                        t0 += time.time() - pause_start  # the fleet's clock stood still
                        target = t0 + n * T
                        continue
                    delay = target - time.time()
                    if delay <= 0:
                        break
                    ib.cond.wait(timeout=delay)
                if ib.stop:
                    return
                msgs, cmds = self._take_inbox()
            self._apply_commands(cmds)
            late = time.time() - target
            if late > STALL_TICKS * T:  # frozen (SIGSTOP) or starved: skip to now, where we were
                n = math.ceil((time.time() - t0) / T)
                v = self.vehicle
                v.rejoin(n, v.q, v.heading, v.omega)
                self.log(f"stalled for {late:.2f} s: resuming at tick {n} from where the vehicle was")
                if n > self.last_tick:
                    break
            now_sim = time.time() - t0
            for recv, msg in msgs:
                self.counters.record_latency(max(0.0, (recv - t0) - msg.t_send))
                self._route_realtime(msg, recv - t0)
            pend = self._pending
            while pend and pend[0][0] <= now_sim:
                _, _, _, msg = heapq.heappop(pend)
                if self.table.offer(msg, now_sim):
                    self.counters.delivered += 1
                else:
                    self.counters.rejected += 1
            self._step(n)
            if time.time() > t0 + (n + 1) * T:
                self.missed_deadlines += 1
            n += 1

    def _route(self, msg: OmegaMsg, m: int) -> None:
        """Lockstep: the link decides, in simulated time, when ``msg`` becomes usable."""
        delays = self.link.decide(msg.sender, self.index, msg.seq, msg.t_send)
        self._count_decision(delays, msg)
        for d in delays:
            self._due[delivery_tick(m, d, self.period)].append((msg, d))

    def _route_realtime(self, msg: OmegaMsg, arrival: float) -> None:
        delays = self.link.decide(msg.sender, self.index, msg.seq, msg.t_send)
        self._count_decision(delays, msg)
        for d in delays:
            self._order += 1
            heapq.heappush(self._pending, (arrival + d, self._order, 0, msg))

    def _count_decision(self, delays: tuple[float, ...], msg: OmegaMsg) -> None:
        self.bursts.feed(msg.sender, self.index, not delays, msg.t_send)
        self.counters.sent += 1  # messages addressed to us (counted at the receiver)
        if not delays:
            self.counters.dropped += 1
        self.counters.duplicated += max(0, len(delays) - 1)

    def _step(self, n: int) -> None:
        v = self.vehicle
        v.control(self.table.consensus((n - 1) * self.period))
        tel = v.telemetry()
        self._states.append(StateMsg(self.index, n, tel.t, tuple(tel.q), tel.heading, tel.speed,
                                     tel.omega, tel.omega_rate, tel.path_error))
        if len(self._states) >= self.state_batch or n >= self.last_tick:
            self.flush_states()
        if n % self.every == 0:
            self.pub_omega.put(encode_omega(OmegaMsg(self.index, n // self.every, v.t, v.omega, v.omega_rate)))
        v.advance()
        self.ticks_done = n + 1
        now = time.monotonic()
        if now - getattr(self, "_last_stats", 0.0) > STATS_PERIOD:
            self._last_stats = now
            self.publish_stats()

    def flush_states(self) -> None:
        if self._states and self.session is not None:
            self.pub_state.put(encode_states(self._states))
        self._states = []

    def stats(self) -> dict:
        c = self.counters
        return {
            "v": 1, "id": self.id, "tick": self.ticks_done, "sent_to_me": c.sent, "delivered": c.delivered,
            "dropped": c.dropped, "duplicated": c.duplicated, "rejected": c.rejected + sum(self.inbox.rejected.values()),
            "rejected_by_reason": dict(self.inbox.rejected), "missed_deadlines": self.missed_deadlines,
            "joined_at": self.joined_at,
            "latencies_ms": self._new_latencies_ms(),
            "faults": self._faults_summary(),
            "bursts": self._new_bursts(),
        }

    def _new_bursts(self) -> list[str]:
        new = self.bursts.done[self._bursts_sent:]
        self._bursts_sent = len(self.bursts.done)
        return [burst_text(b, self.ids) for b in new[-20:]]

    def _new_latencies_ms(self, most: int = 100) -> list[float]:
        """Latency samples taken since the last report (at most ``most``, evenly thinned)."""
        lat = self.counters.latencies
        start = min(getattr(self, "_lat_sent", 0), len(lat))  # the sample list may have been thinned
        new = lat[start:]
        self._lat_sent = len(lat)
        step = max(1, len(new) // most)
        return [x * 1000.0 for x in new[::step][:most]]

    def _faults_summary(self) -> dict | None:
        summary = getattr(self.link, "counters_summary", None)
        if summary is None:
            return None
        out = summary()
        out["state_changes"] = out["state_changes"][-50:]  # the newest; the world keeps the history
        return out

    def publish_stats(self) -> None:
        import msgpack

        if self.session is not None:
            self.pub_stats.put(msgpack.packb(self.stats(), use_bin_type=True))

    def _await_stop(self) -> None:
        """After the last tick, wait for the world's stop so it has received everything."""
        self.flush_states()
        self.publish_stats()
        ib = self.inbox
        deadline = time.monotonic() + END_WAIT
        with ib.cond:
            while not ib.stop and time.monotonic() < deadline:
                ib.cond.wait(timeout=0.5)


def run_agent(agent: Agent) -> int:
    """Open, run, close; SIGTERM and SIGINT end the run cleanly."""
    def _stop(signum, frame):
        with agent.inbox.cond:
            agent.inbox.stop = True
            agent.inbox.cond.notify_all()

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    try:
        agent.open()
        ticks = agent.run()
        agent.log(f"done after {ticks} ticks; missed deadlines {agent.missed_deadlines}; "
                  f"rejected {dict(agent.inbox.rejected) or 0}")
        return 0
    finally:
        agent.close()
        sys.stdout.flush()

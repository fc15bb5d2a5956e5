"""Who may step which tick, who is live, and when is a tick complete? The world's lockstep decisions.

Pure bookkeeping, driven by the world process (world_sim.world) and tested without one.
Inputs: telemetry reports (``on_report``), liveliness (``on_alive``), the launcher's
acknowledgements (``on_fault_done``) and operator commands (``pause``, ``resume``,
``vehicle_fault``). :meth:`Lockstep.poll` returns the actions to carry out, in order:

- :class:`Roster`: a liveness change, to every vehicle. Each change is sent before the
  tick it takes effect at is granted, so every agent applies it on that very tick.
  Scheduled faults give the changes of :func:`cdus.core.events.plan_roster` (the
  in-process fleet's, hence lockstep == in-process); a crash or a ground station's fault
  gives changes decided here.
- :class:`Fault`: ask the launcher to kill, pause (SIGSTOP), resume or restart a
  process. Grants stop at the tick before the fault until it is done, so it lands on
  its tick.
- :class:`Join`: tell a (re)started process the tick it joins at (0 at the start).
- :class:`CatchUp`: send a (re)started or resumed process the run-time commands (link
  faults, gains) it missed, after the roster changes it missed.
- :class:`Sense`: sample the proximity sensor at tick ``tick`` (every vehicle live at it
  has reported it) and send every vehicle its contacts (cdus.sim.sensing). Only with the
  safety filter on (``sense_every``).
- :class:`RadioSample`: with ``[radio]``, sample the radio geometry at ``tick`` once every
  vehicle live at it has reported it, and send it to every vehicle (cdus.sim.radio).
- :class:`Grant`: vehicles may step up to ``until``, a horizon: the run's last tick, the
  tick before the next vehicle fault, with ``[radio]`` s + lag for the next radio sample s
  not sent (:meth:`Lockstep.radio_limit`), and, with the sensor, s + latency - 1 for the next
  sample tick s whose contacts have not been sent (a vehicle uses the contacts of s from
  s + latency on, so it must have them by then); and at most ``window`` ticks ahead of the
  slowest vehicle that is due to report (the world's memory of unrecorded rows). A grant
  below the horizon is sent only once it moves by ``grant_step`` or more. Roster changes up
  to the new grant are sent before it.
- a :class:`FleetEvent` for the record.

A tick is complete (:meth:`recordable`) once every vehicle live at it has reported it.

A liveliness loss nobody asked for is not decided at once: the world calls
:meth:`decide_drops` once the losses of the moment are in (``pending``). Some vehicles
gone and others still there: they crashed, and are gone from the first tick they did not
report (``lost`` until a new process joins). Every vehicle gone at once: the router or the
network went, not the vehicles, whose processes keep their state: an ``outage``, with no
roster change, until they are back (the run goes on as if nothing happened) or the world
gives up (:meth:`end_outage`: they are lost).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

from cdus.commands.vehicle import BY_EVENT as FAULT_BY_EVENT
from cdus.core.events import LEASE_S, Event, RosterChange, event_tick, plan_roster
from cdus.sim.reports import commanded_fault, scheduled_fault, vehicle_back, vehicle_lost
from cdus.wire.schemas import FleetEvent

GRANT_WINDOW = 100  # ticks the fastest vehicle may run ahead of the slowest, at the least
#: ... and at the most: the world widens its window with the fleet's speed (a horizon of about
#: world_sim.world.HORIZON_S of wall time, so an operator's command, which applies past every
#: grant, still lands soon); a vehicle's ω seq check allows twice this (vehicle_agent.agent)
MAX_GRANT_WINDOW = 2000
#: a vehicle fault's scenario action -> the launcher's op for it (cdus.commands.vehicle's names)
FAULT_OPS = {event: fault.NAMES.op for event, fault in FAULT_BY_EVENT.items()}


def horizon_window(ticks_per_s: float, horizon_s: float) -> int:
    """The grant window for a fleet recording ``ticks_per_s``: about ``horizon_s`` of its wall
    time, within [GRANT_WINDOW, MAX_GRANT_WINDOW]."""
    if not ticks_per_s > 0:
        return GRANT_WINDOW
    return max(GRANT_WINDOW, min(MAX_GRANT_WINDOW, int(ticks_per_s * horizon_s)))


@dataclass(frozen=True)
class Grant:
    until: int


@dataclass(frozen=True)
class Sense:
    tick: int


@dataclass(frozen=True)
class RadioSample:
    """Sample the radio geometry at tick ``tick`` (every vehicle live at it has reported it) and
    send it to every vehicle (cdus.sim.radio). Only with ``[radio]`` (``radio_every``)."""

    tick: int


@dataclass(frozen=True)
class Join:
    vehicle: int
    tick: int


@dataclass(frozen=True)
class Roster:
    change: RosterChange
    to: int | None = None  # one vehicle (a joiner catching up), None: every vehicle


@dataclass(frozen=True)
class CatchUp:
    """A (re)joining or resumed process: send it the run-time commands it missed (link
    faults, gains), after the roster changes."""

    vehicle: int


@dataclass(frozen=True)
class Fault:
    op: str  # kill | pause_vehicle | resume_vehicle | restart (cdus.wire.messages.LAUNCHER_OPS)
    vehicle: int


@dataclass(frozen=True)
class Decided:
    """A ground station's vehicle fault that asked for an answer (``ref``) is decided: carried out
    from ``tick`` (``reason`` None) or not (``reason`` says why: nothing to do)."""

    ref: object
    tick: int
    reason: str | None = None


Action = Grant | Join | Roster | CatchUp | Fault | Sense | RadioSample | FleetEvent | Decided


@dataclass
class _Pending:
    """A vehicle fault being carried out at ``tick``."""

    tick: int
    action: str  # kill | pause | resume | restart
    vehicle: int
    stage: str = "due"  # due -> asked (the launcher) -> waiting_token (restart, resume) -> done
    by: str | None = None  # who commanded it (a ground station); None: the scenario's schedule
    ref: object = None  # the answer it waits for (Decided), None: nobody asked


@dataclass
class Lockstep:
    ids: Sequence[str]
    period: float
    last_tick: int
    events: Sequence[Event] = ()
    window: int = GRANT_WINDOW
    lease: float = LEASE_S
    granted: int = -1
    paused: bool = False
    started: bool = False
    acked: dict[int, int] = field(default_factory=dict)  # newest tick reported, per vehicle
    alive: set[int] = field(default_factory=set)
    sense_every: int | None = None  # ticks between proximity samples; None: no sensor
    sense_latency: int = 1  # ticks from a sample to its first use (>= 1)
    sensed: int = -1  # the newest sample tick whose contacts were sent
    #: the least move of a grant worth a message (fewer ctl messages with a wide window); a grant
    #: up to a limit (a fault, a sensor sample, the last tick) goes at once
    grant_step: int = 1
    radio_every: int | None = None  # ticks between radio geometry samples; None: no [radio]
    radio_lag: int = 1  # ticks from a radio sample to the first send tick it is in force at (>= 1)
    radioed: int = -1  # the newest radio sample tick sent

    def __post_init__(self) -> None:
        self._plan = list(plan_roster(self.events, self.ids, self.period, self.lease))
        self._decided: list[RosterChange] = []  # changes decided here (crashes, a ground station's faults)
        self._changes_by: dict[int, list[RosterChange]] | None = None  # cache of _by_vehicle
        self.changes: list[RosterChange] = []  # every change sent so far, in order
        self._queue: list[_Pending] = sorted((_Pending(event_tick(e.at, self.period), e.action, self.ids.index(e.vehicle))
                                              for e in self.events), key=lambda p: (p.tick, p.vehicle))
        self._current: _Pending | None = None
        self._expect: dict[int, set[str]] = {}  # liveliness changes a fault in progress explains
        self._paused_by_hand: dict[int, int] = {}  # vehicle -> tick a ground station paused it at
        self._lapsed_by_hand: dict[int, int] = {}  # vehicle -> tick of a ground station's pause that lapsed to gone
        self._killed: set[int] = set()  # killed and not restarted since (a resume cannot bring them back)
        self._out: list[Action] = []
        self.pending: set[int] = set()  # liveliness lost, not decided yet (decide_drops)
        self.outage: set[int] = set()  # lost all at once with the rest of the fleet: waited for
        self.lost: set[int] = set()  # lost with nobody asking (a crash, an outage given up) and not back
        self._fault_tick: dict[int, int] = {}  # vehicle -> the tick of its newest fault carried out
        # the tick of the roster change the last on_alive's news belongs to (None: not one we made):
        # events about it carry that tick, as the in-process fleet stamps them, not the tick recorded
        self.news_tick: int | None = None
        self._lease_ticks = max(1, math.ceil(self.lease / self.period - 1e-9))
        if self.sense_every is not None and (self.sense_every < 1 or self.sense_latency < 1):
            raise ValueError(f"sense_every and sense_latency must be >= 1 tick, got {self.sense_every}, "
                             f"{self.sense_latency}")

    # ------------------------------------------------------------------ who is live
    def state_at(self, j: int, n: int) -> str:
        """Vehicle j's state at tick n, from the changes sent so far and the plan."""
        state = "live"
        for ch in self._by_vehicle().get(j, ()):
            if ch.tick > n:
                break
            state = ch.state
        return state

    def _by_vehicle(self) -> dict[int, list[RosterChange]]:
        """The plan's and the decided changes per vehicle, by tick (stable: same tick, given
        order); rebuilt only when a change is decided (state_at is on the world's per-tick path)."""
        if self._changes_by is None:
            by: dict[int, list[RosterChange]] = {}
            for ch in sorted([*self._plan, *self._decided], key=lambda c: c.tick):
                by.setdefault(ch.vehicle, []).append(ch)
            self._changes_by = by
        return self._changes_by

    def _due(self, j: int) -> bool:
        """Is vehicle j due to report its next tick?"""
        n = self.acked.get(j, -1) + 1
        return n <= self.last_tick and self.state_at(j, n) == "live"

    def recordable(self, n: int) -> bool:
        """Has every vehicle live at tick n reported it?"""
        return all(self.acked.get(j, -1) >= n for j in range(len(self.ids)) if self.state_at(j, n) == "live")

    # ------------------------------------------------------------------ inputs
    def start(self) -> None:
        self.started = True
        for j in range(len(self.ids)):
            self._out.append(Join(j, 0))

    def on_report(self, j: int, tick: int) -> None:
        if tick > self.acked.get(j, -1):
            self.acked[j] = tick
        if j in self._expect and self._current is None and tick >= self._last_change_tick(j):
            del self._expect[j]  # it is back and stepping: liveliness news is news again

    def on_alive(self, j: int, up: bool) -> None:
        """A liveliness token appeared (``up``) or went away."""
        self.news_tick = None
        was = j in self.alive
        if up == was:
            return
        (self.alive.add if up else self.alive.discard)(j)
        if not self.started:
            return
        t = self._frontier() * self.period
        vid = self.ids[j]
        kind = "up" if up else "down"
        if kind in self._expect.get(j, ()):
            self._expect[j].discard(kind)
            self.news_tick = self._change_tick(j, up)
            if up:
                self._out.append(vehicle_back(self.news_tick * self.period, vid))
            return
        if up and (j in self.pending or j in self.outage):  # back before anything was decided: same process
            self.pending.discard(j)
            if j in self.outage:
                self.outage.discard(j)
                if not self.outage:
                    self._out.append(FleetEvent.of(t, "fleet", "every vehicle is back; the run goes on"))
                    self._out.append(Grant(self.granted))  # said again: one sent meanwhile may be lost
            return
        if up:  # an unscheduled (re)start: it joins at the first tick nobody has been granted
            self.lost.discard(j)
            b = self.granted + 1
            self._send(RosterChange(b, j, "gone"))
            self._send(RosterChange(b, j, "live", fresh=True))
            self._catch_up(j)
            self._out.append(Join(j, b))
            self.acked[j] = b - 1
            self.news_tick = b
            self._out.append(vehicle_back(t, vid, joins_at=b))
        else:  # a crash, a kill nobody scheduled, or an outage: decide_drops tells them apart
            self.pending.add(j)

    def decide_drops(self) -> str | None:
        """Decide the pending liveliness losses: ``"outage"`` if they leave no vehicle of the fleet
        that is live and alive (the router or network went: wait for them), ``"lost"`` if others
        remain (crashes: gone from the first tick each did not report), None if nothing pending."""
        if not self.pending or not self.started:
            return None
        n = self._frontier()
        remaining = [j for j in self.alive if self.state_at(j, n) == "live"]
        if not remaining and len(self.pending) > 1:
            self.outage |= self.pending
            self.pending = set()
            names = ", ".join(self.ids[j] for j in sorted(self.outage))
            self._out.append(FleetEvent.of(n * self.period, "fleet", f"every vehicle dropped at once ({names}): "
                                           "waiting for them (router or network)", severity="warn"))
            return "outage"
        for j in sorted(self.pending):
            self._lose(j)
        self.pending = set()
        return "lost"

    def end_outage(self) -> None:
        """The fleet did not come back in time: each vehicle still away is lost."""
        for j in sorted(self.outage):
            self._lose(j)
        self.outage = set()

    def _lose(self, j: int) -> None:
        """Gone from the first tick it did not report."""
        g = self.acked.get(j, -1) + 1
        if self.state_at(j, g) != "gone":
            self._send(RosterChange(g, j, "gone"))
        self.lost.add(j)
        self._out.append(vehicle_lost(self._frontier() * self.period, self.ids[j]))

    def on_fault_done(self, j: int) -> None:
        p = self._current
        if p is None or p.vehicle != j or p.stage != "asked":
            return
        if p.action == "restart" or (p.action == "resume" and j not in self.alive):
            p.stage = "waiting_token"
        else:
            p.stage = "done"

    def pause(self) -> None:
        self.paused = True

    def resume(self) -> None:
        self.paused = False

    def vehicle_fault(self, action: str, j: int, by: str = "a ground station", ref: object = None) -> int:
        """A ground station's kill | pause | resume | restart: at the first tick not yet granted
        (returned). With ``ref``, a Decided action says when it is carried out or found moot."""
        tick = self.granted + 1
        self._queue.append(_Pending(tick, action, j, by=by, ref=ref))
        self._queue.sort(key=lambda p: (p.tick, p.vehicle))
        return tick

    def undecided(self) -> list[tuple[object, int]]:
        """(ref, tick) of the ground stations' faults still queued (at the end: never carried out)."""
        return [(p.ref, p.tick) for p in self._queue if p.ref is not None]

    def give_up(self, j: int) -> None:
        """The launcher never acknowledged the fault in progress (or the new process never came):
        go on without it."""
        p = self._current
        if p is not None and p.vehicle == j:
            self._out.append(FleetEvent.of(p.tick * self.period, "fault_missed",
                                           f"the {p.action} of {self.ids[j]} was not carried out; going on",
                                           vehicle=self.ids[j]))
            p.stage = "done"

    # ------------------------------------------------------------------ decisions
    def poll(self) -> list[Action]:
        """The actions to carry out now, in order."""
        if self.started:
            self._faults()
            self._sense()
            self._radio()
            self._grant()
        out, self._out = self._out, []
        return out

    def _faults(self) -> None:
        p = self._current
        if p is not None:
            if p.stage == "waiting_token" and p.vehicle in self.alive:
                p.stage = "done"
                if p.action == "restart":
                    self._catch_up(p.vehicle)
                    self._out.append(Join(p.vehicle, p.tick))
                    self.acked[p.vehicle] = p.tick - 1
                else:  # resumed after its session lapsed: what was sent meanwhile never reached it
                    self._catch_up(p.vehicle)
                    self._out.append(Grant(self.granted))
            if p.stage != "done":
                return
            self._current = None
        while self._queue and self._current is None:
            p = self._queue[0]
            if self.granted < p.tick - 1 or not self.recordable(p.tick - 1):
                return  # not there yet: everyone steps up to the tick before, then it happens
            self._queue.pop(0)
            self._carry_out(p)

    def _carry_out(self, p: _Pending) -> None:
        j, vid = p.vehicle, self.ids[p.vehicle]
        scheduled = any(c.vehicle == j and c.tick == p.tick for c in self._plan)
        if not scheduled and p.by is not None:  # a ground station's: is there anything to do?
            now = self.state_at(j, p.tick)
            killed = j in self._killed
            moot = {"pause": now != "live", "resume": now == "live" or killed, "kill": killed}.get(p.action, False)
            if moot:
                # "usv2 is killed at tick 13199" read as when it was killed (it had been at 9500):
                # the tick is where this fault would have landed, so say that
                lapsed = self._lapsed_by_hand.get(j) if now == "gone" and not killed else None
                was = "" if lapsed is None else f" (paused at tick {lapsed}; gone once its liveliness lease lapsed)"
                why = (f"{vid} is {'killed' if killed else now} at tick {p.tick}{was}, where this {p.action} would "
                       f"land (nothing done)")
                self._out.append(FleetEvent.of(p.tick * self.period, "rejected",
                                               f"{p.action} of {vid} by {p.by}: it is "
                                               f"{'killed' if killed else now} (nothing done)", vehicle=vid))
                if p.ref is not None:
                    self._out.append(Decided(p.ref, p.tick, why))
                return
        self._fault_tick[j] = p.tick
        if p.action == "kill":
            self._killed.add(j)
        elif p.action == "restart":
            self._killed.discard(j)
        self._lapsed_by_hand.pop(j, None)  # a fault carried out: what the vehicle is now is that fault's doing
        if not scheduled:  # a ground station's: decide its roster changes here
            if p.action == "pause" and self.state_at(j, p.tick) == "live":
                self._send(RosterChange(p.tick, j, "paused"))
                self._paused_by_hand[j] = p.tick
            elif p.action == "resume" and self.state_at(j, p.tick) != "live":
                self._send(RosterChange(p.tick, j, "live"))
                self._paused_by_hand.pop(j, None)
            elif p.action == "kill" and self.state_at(j, p.tick) != "gone":
                self._send(RosterChange(p.tick, j, "gone"))
            elif p.action == "restart":
                self._send(RosterChange(p.tick, j, "gone"))
                self._send(RosterChange(p.tick, j, "live", fresh=True))
        # the liveliness news this fault explains: a frozen process's token lapses with the lease
        # (maybe only after the resume), a restarted one goes and comes back
        self._expect[j] = {"kill": {"down"}, "pause": {"down", "up"}, "resume": {"down", "up"},
                           "restart": {"down", "up"}}[p.action]
        self._out.append(Fault(FAULT_OPS[p.action], j))
        self._out.append(scheduled_fault(p.tick, self.period, p.action, vid) if p.by is None
                         else commanded_fault(p.tick, self.period, p.action, vid, p.by))
        if p.ref is not None:
            self._out.append(Decided(p.ref, p.tick))
        p.stage = "asked"
        self._current = p

    def next_sample(self) -> int | None:
        """The next sample tick whose contacts have not been sent (None: no sensor, or past the end)."""
        if self.sense_every is None:
            return None
        s = 0 if self.sensed < 0 else self.sensed + self.sense_every
        return s if s <= self.last_tick else None

    def _sense(self) -> None:
        while (s := self.next_sample()) is not None and s <= self.granted and self.recordable(s):
            self.sensed = s
            self._out.append(Sense(s))

    def next_radio(self) -> int | None:
        """The next radio sample tick not sent yet (None: no [radio], or past the end)."""
        if self.radio_every is None:
            return None
        s = 0 if self.radioed < 0 else self.radioed + self.radio_every
        return s if s <= self.last_tick else None

    def _radio(self) -> None:
        while (s := self.next_radio()) is not None and s <= self.granted and self.recordable(s):
            self.radioed = s
            self._out.append(RadioSample(s))

    def radio_limit(self) -> int | None:
        """The newest tick that may be granted before the next radio sample is sent: a tick n
        decides the messages sent before it with the sample in force at n - 1, and sample s is
        in force from s + lag (sample 0 from the start), so not past s + lag (0 for s = 0)."""
        s = self.next_radio()
        if s is None:
            return None
        return s + self.radio_lag if s > 0 else 0

    def _grant(self) -> None:
        if self.paused:
            return
        due = [self.acked.get(j, -1) for j in range(len(self.ids)) if self._due(j)]
        limit = self.last_tick  # the horizon: the end, the next sample the vehicles wait for, a fault
        s = self.next_sample()
        if s is not None:
            limit = min(limit, s + self.sense_latency - 1)
        r = self.radio_limit()
        if r is not None:
            limit = min(limit, r)
        if self._current is not None:
            limit = min(limit, self._current.tick - 1)
        if self._queue:
            limit = min(limit, self._queue[0].tick - 1)
        want = min(limit, min(due) + self.window) if due else limit
        if want < limit and want - self.granted < self.grant_step:
            return  # a small move: not worth a message yet (the vehicles are far from the grant)
        for j, since in list(self._paused_by_hand.items()):  # a ground station's pause lapses with the lease
            if want >= since + self._lease_ticks and self.state_at(j, since + self._lease_ticks) == "paused":
                self._send(RosterChange(since + self._lease_ticks, j, "gone"))
                del self._paused_by_hand[j]
                self._lapsed_by_hand[j] = since
        if want > self.granted:
            for ch in self._plan:  # the scheduled changes up to the new grant, before it
                if self.granted < ch.tick <= want:
                    self._send(ch, planned=True)
            self.granted = want
            self._out.append(Grant(want))

    # ------------------------------------------------------------------ helpers
    def _send(self, change: RosterChange, planned: bool = False) -> None:
        if not planned:
            self._decided.append(change)
            self._changes_by = None
        self.changes.append(change)
        self._out.append(Roster(change))

    def _catch_up(self, j: int) -> None:
        """A joining process hears every change so far (its neighbours' liveness)."""
        for ch in self.changes:
            self._out.append(Roster(ch, to=j))
        self._out.append(CatchUp(j))

    def _change_tick(self, j: int, up: bool) -> int:
        """The tick of the change a fault's liveliness news belongs to: the first one at or after
        the fault's tick that makes vehicle j live (``up``) or gone (a pause's: when the lease
        runs out, if planned); else the fault's own tick."""
        since = self._fault_tick.get(j, 0)
        want = "live" if up else "gone"
        ticks = [c.tick for c in [*self._plan, *self._decided] if c.vehicle == j and c.tick >= since
                 and c.state == want]
        return min(ticks, default=since)

    def _frontier(self) -> int:
        return max(0, min(self.granted, self.last_tick))

    def _last_change_tick(self, j: int) -> int:
        ticks = [c.tick for c in [*self._plan, *self._decided] if c.vehicle == j and c.tick <= self.granted + 1]
        return max(ticks, default=0)

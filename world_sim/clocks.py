"""Whose clock does the world keep: the grants (lockstep) or the wall clock (realtime)?

The world's clock is one of two strategy objects, picked once where the world is built
(:func:`pick_clock`); nothing else in world_sim asks which clock runs. Each answers the
same questions its own way:

- ``run()``: the run loop (lockstep: grant, record what is complete, watch outages and
  catch-ups; realtime: publish a start time, record a little behind the wall clock, carry
  out the scheduled faults as their time comes);
- ``tick_limit()``: the newest tick a vehicle can have stepped (a newer row is forged);
- ``effect_tick()``, ``effect_time(asked)``: the first tick a run-time change applies from,
  and the time a change named in time (link, radio) applies from, the same on every vehicle
  (docs/ground_station.md, "When a command takes effect"): cdus.commands.effect's one rule
  over the clock's ``known_and_lead()`` (lockstep: the grant, lead 1; realtime: the wall
  clock's tick, EFFECT_LEAD_S of ticks);
- ``sim_now()``, ``first_step(vid)``, ``live_at(n)``, ``roster_states(tick)``, ``lost()``:
  where the fleet is and who steps;
- ``on_alive(name, j, up)``: liveliness news (lockstep: Lockstep decides the roster;
  realtime: a roster change at once);
- ``paused()``, ``pause(pause)``: the fleet's pause;
- ``vehicle_fault(...)``, ``fault_done(vid)``: a vehicle fault a command asks for.
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from cdus.commands.effect import LEAD_S, effect_tick, effect_time, lead_ticks
from cdus.commands.vehicle import BY_EVENT as FAULT_BY_EVENT, BY_OP as FAULT_BY_OP
from cdus.core.events import RosterChange
from cdus.sim.lockstep import CatchUp, Decided, Fault, Grant, Join, RadioSample, Roster, Sense, horizon_window
from cdus.sim.reports import vehicle_back, vehicle_lost
from cdus.wire import keys
from cdus.wire.messages import encode_control
from cdus.wire.schemas import FleetEvent
from world_sim.verdict import LATER, Verdict

if TYPE_CHECKING:  # the world holds its clock, the clock its world
    from world_sim.world import World

REALTIME_LAG = 8  # ticks the world waits before recording a realtime tick (> the telemetry batch)
STATUS_PERIOD = 1.0  # s
FAULT_TIMEOUT = 10.0  # s the launcher may take to carry out a fault
JOIN_TIMEOUT = 30.0  # s a restarted process may take to come up
GRANT_RESEND = 0.5  # s: grants and start times are said again for processes that missed them
#: lockstep: a resumed or restarted process that has reported no tick this long (s) after its
#: catch-up gets the catch-up again (a resumed process whose session lapsed reconnects: the world
#: sees its token back before the router has its subscriptions again, and what it sent then was
#: lost; the process then waited for its roster for ever, and its neighbours for its ω)
CATCHUP_RESEND = 1.0
CATCHUP_RESEND_MAX = 8.0
#: realtime: a ground station's vehicle fault is answered when the launcher says it carried it
#: out; none within this (s): not carried out (a --remote vehicle, a launcher gone)
RT_FAULT_CONFIRM = 5.0
#: realtime: a run-time change applies this far (s) ahead of the wall clock's tick, so every
#: vehicle hears it before it steps that tick (cdus.commands.effect says why)
EFFECT_LEAD_S = LEAD_S
#: realtime: telemetry may be this far (s) ahead of the world's own clock (clock skew between
#: hosts, a batch sent at once); beyond it, a row is from a tick nobody can have stepped yet
REALTIME_SLACK = 1.0
#: s a lockstep world waits for a fleet that dropped all at once (the router or the network went,
#: not the vehicles: their processes keep their state) before it declares them lost. A router
#: frozen or restarted comes back in seconds, and the agents' sessions reconnect every <= 0.5 s
#: (cdus.wire.transport), so 30 s covers that with room; a fleet gone longer is not coming back.
OUTAGE_GRACE = 30.0
#: lockstep: the grant window is about this much wall time at the fleet's speed (measured every
#: HORIZON_EVERY s), so the vehicles rarely meet a grant, and a command that applies past every
#: grant (an operator's kill, link or gains) lands this soon
HORIZON_S = 0.25
HORIZON_EVERY = 0.25
DROP_WINDOW = 0.3  # s: liveliness losses this close together count as one (a lapsed router drops them all)


def pick_clock(clock: str, world: "World") -> "LockstepClock | RealtimeClock":
    """The one place the clock's name is compared: its strategy object for ``world``."""
    if clock == "lockstep":
        return LockstepClock(world)
    if clock == "realtime":
        return RealtimeClock(world)
    raise ValueError(f"clock: {clock!r} is no clock; choose lockstep or realtime")


class _EffectRule:
    """When a run-time change applies (cdus.commands.effect's one rule), from what a clock knows:
    its ``known_and_lead()`` and the world's period."""

    w: "World"

    def known_and_lead(self) -> tuple[int, int]:
        raise NotImplementedError

    def effect_tick(self) -> int:
        """The first tick a run-time change applies from on every vehicle alike."""
        return effect_tick(*self.known_and_lead())

    def effect_time(self, asked: float | None) -> tuple[float, str]:
        """The simulated time a change asked for ``asked`` (None: as soon as possible) applies
        from, never before the effect tick's start, and the note when ``asked`` had passed."""
        return effect_time(asked, *self.known_and_lead(), self.w.period)


@dataclass
class _CatchingUp:
    """A process caught up (lockstep), until it reports a tick past ``acked``."""

    acked: int  # the newest tick it had reported when caught up
    at: float  # monotonic s: say the catch-up again then
    join: int | None = None  # the join tick of a restart
    told: bool = False  # the log says it once
    every: float = CATCHUP_RESEND / 2  # s between resends, doubled each time (CATCHUP_RESEND_MAX at most)


class LockstepClock(_EffectRule):
    """The fleet steps what the world grants: cdus.sim.lockstep.Lockstep decides (grants, the
    roster, faults on their ticks, joins), this clock carries its decisions out."""

    name = "lockstep"
    wake_every = 0.25  # s between the ticker's wakes
    radio_from_rows = True  # radio samples from the telemetry of exactly their tick

    def __init__(self, world: "World"):
        self.w = world
        self.ls = world.lockstep
        self.catching: dict[int, _CatchingUp] = {}  # caught-up processes not heard from since
        self.fault_since: float | None = None
        self.drops_since: float | None = None  # monotonic time of the first undecided liveliness loss
        self.outage_since: float | None = None  # the whole fleet dropped at once: waiting for it
        self.last_grant = 0.0

    def __str__(self) -> str:
        return self.name

    # ------------------------------------------------------------------ where the fleet is
    def tick_limit(self) -> int:
        """The newest tick a vehicle can have stepped: the grant."""
        return self.ls.granted

    def known_and_lead(self) -> tuple[int, int]:
        """The effect rule's inputs: the highest tick granted (-1 before the first grant), and a
        lead of 1: a change applies from a tick nobody was granted."""
        return self.ls.granted, 1

    def sim_now(self) -> float:
        """The fleet's present in simulated seconds: the newest tick recorded."""
        return max(0, self.w.next_tick - 1) * self.w.period

    def first_step(self, vid: str) -> int:
        """A tick no later than the first one ``vid``'s process (restarted, resumed) can step now:
        after the newest it reported or joins past."""
        return self.ls.acked.get(self.w.index[vid], -1) + 1

    def live_at(self, n: int) -> list[bool]:
        """Which vehicles step tick n: the roster's word."""
        return [self.ls.state_at(j, n) == "live" for j in range(len(self.w.ids))]

    def starts_unseen(self, j: int, n: int, latest: Any) -> bool:
        """Vehicle j never reported and does not step tick n (paused or killed from tick 0)."""
        return self.ls.state_at(j, n) != "live"

    def roster_states(self, tick: int) -> list[str]:
        """Each vehicle's roster state at ``tick`` (a vehicle a fault paused is gone from the
        roster once its lease lapses: still paused to an operator)."""
        faulted = self.w._faulted
        return ["paused" if st == "gone" and faulted.get(vid) == "paused" else st
                for vid, st in zip(self.w.ids, (self.ls.state_at(j, tick) for j in range(len(self.w.ids))))]

    def news_tick(self) -> int | None:
        """The tick of the roster change the newest liveliness news belongs to."""
        return self.ls.news_tick

    def lost(self) -> bool:
        return bool(self.ls.lost | self.ls.outage)

    # ------------------------------------------------------------------ news and commands
    def on_alive(self, name: str, j: int, up: bool) -> None:
        self.ls.on_alive(j, up)
        if self.ls.pending and self.drops_since is None:
            self.drops_since = time.monotonic()
        self.act(self.ls.poll())

    def paused(self) -> bool:
        return self.ls.paused

    def pause(self, pause: bool) -> int:
        """Pause (or resume) the fleet from the first tick nobody was granted; that tick."""
        tick = self.effect_tick()
        (self.ls.pause if pause else self.ls.resume)()
        return tick

    def vehicle_fault(self, vid: str, action: str, op: str, by: str, ref: Any):
        """Lockstep decides the fault's tick; a Decided action answers whoever waits."""
        tick = self.ls.vehicle_fault(action, self.w.index[vid], by=by, ref=ref)
        return LATER if ref is not None else Verdict(True, "", tick)

    def fault_done(self, vid: str) -> None:
        """The launcher carried out a fault on ``vid``: Lockstep goes on with it."""
        self.ls.on_fault_done(self.w.index[vid])

    def forget_faults(self) -> None:
        """At the end: the faults waiting are Lockstep's (answered by the world from its list)."""

    # ------------------------------------------------------------------ the run
    def run(self) -> None:
        w, ls = self.w, self.ls
        for j, vid in enumerate(w.ids):
            ls.on_alive(j, vid in w.st.alive)
        ls.start()
        self.last_grant = 0.0
        last_status = 0.0
        mark = (time.monotonic(), w.next_tick)
        while w.next_tick <= w.last_tick and not w.stop_requested:
            self.act(ls.poll())
            self.record_complete()
            now = time.monotonic()
            if now - mark[0] >= HORIZON_EVERY:
                mark = self.widen_horizon(now, mark)
            if self.supervise_outage(now):
                break
            if self.catching:
                self.catch_up_again(now)
            if now - self.last_grant > GRANT_RESEND and ls.granted >= 0:  # for anyone who missed it
                self.last_grant = now
                w.pub_ctl.put(encode_control("grant", until=ls.granted))
            if self.fault_since is not None and ls._current is not None and ls._current.stage != "done":
                limit = JOIN_TIMEOUT if ls._current.stage == "waiting_token" else FAULT_TIMEOUT
                if now - self.fault_since > limit:
                    ls.give_up(ls._current.vehicle)
                    self.fault_since = None
            if now - last_status > STATUS_PERIOD:
                last_status = now
                w._publish_status()
            if w.next_tick <= w.last_tick:
                w._drain(block=True)

    def act(self, actions: list) -> None:
        """Carry out Lockstep's decisions, in order."""
        w = self.w
        for a in actions:
            if isinstance(a, Roster):
                w._send_roster(a.change, a.to)
            elif isinstance(a, Grant):
                self.last_grant = time.monotonic()
                w.pub_ctl.put(encode_control("grant", until=a.until))
            elif isinstance(a, Join):
                w._put(keys.ctl(w.fleet, [w.ids[a.vehicle]]), encode_control("join", tick=a.tick))
                if a.vehicle in self.catching:
                    self.catching[a.vehicle].join = a.tick
            elif isinstance(a, CatchUp):
                w._replay_commands(w.ids[a.vehicle])
                w._replay_geometry(w.ids[a.vehicle])
                self.catching[a.vehicle] = _CatchingUp(self.ls.acked.get(a.vehicle, -1),
                                                       time.monotonic() + CATCHUP_RESEND)
            elif isinstance(a, Sense):
                w._send_contacts(a.tick, w._sample_rows.pop(a.tick, {}))
            elif isinstance(a, RadioSample):
                w._send_geometry(a.tick, w._radio_rows.pop(a.tick, {}))
            elif isinstance(a, Fault):
                self.fault_since = time.monotonic()
                w._note_fault(w.ids[a.vehicle], FAULT_BY_OP[a.op].NAMES.event)
                w.pub_launcher.put(encode_control(a.op, vehicle=w.ids[a.vehicle]))
            elif isinstance(a, FleetEvent):
                w._note(a)
            elif isinstance(a, Decided):
                w._decided(a)

    def record_complete(self) -> None:
        w = self.w
        while w.next_tick <= w.last_tick and self.ls.recordable(w.next_tick):
            if not w._record(w.next_tick):
                return

    def catch_up_again(self, now: float) -> None:
        """A process caught up (CatchUp) that has reported no tick since hears it all
        again, in the first one's order (its roster, the commands and radio samples, the join tick
        of a restart, the grant): each is told once to a process that had it (roster changes are
        kept once, commands by their seq). After CATCHUP_RESEND s, then twice as long each time up
        to 8 s, while its liveliness token is up, until it reports. Not while it is down: a
        restart's fault_done can come before the old process's token goes, so the first catch-up
        went to a process not yet started (seen in the suite: the new uav2 waited for its join for
        ever); when the new one's token comes, it hears it."""
        w, ls = self.w, self.ls
        for j, c in list(self.catching.items()):
            vid = w.ids[j]
            if ls.acked.get(j, -1) > c.acked:
                del self.catching[j]
                continue
            if now < c.at or vid not in w.st.alive:
                continue
            if not c.told:
                c.told = True
                w.log(f"{vid} has reported nothing since its catch-up: saying it again")
            c.every = min(2 * c.every, CATCHUP_RESEND_MAX)
            c.at = now + c.every
            for ch in ls.changes:
                w._send_roster(ch, j)
            w._replay_commands(vid)
            w._replay_geometry(vid)
            if c.join is not None:  # last, as the first time: it starts stepping when it hears it
                w._put(keys.ctl(w.fleet, [vid]), encode_control("join", tick=c.join))
            w.pub_ctl.put(encode_control("grant", until=ls.granted))

    def widen_horizon(self, now: float, mark: tuple[float, int]) -> tuple[float, int]:
        """Size the grant window to the fleet's speed since ``mark`` (wall s, next tick to record
        then); a grant moves by a quarter window at a time. Returns the new mark."""
        ls, w = self.ls, self.w
        ls.window = horizon_window((w.next_tick - mark[1]) / (now - mark[0]), HORIZON_S)
        ls.grant_step = max(1, ls.window // 4)
        return now, w.next_tick

    def supervise_outage(self, now: float) -> bool:
        """Decide liveliness losses once those of the moment are in (DROP_WINDOW); wait for a fleet
        that dropped all at once up to ``outage_grace``. True: the run cannot go on."""
        ls, w = self.ls, self.w
        if not ls.pending:
            self.drops_since = None
        elif self.drops_since is not None and now - self.drops_since > DROP_WINDOW:
            self.drops_since = None
            if ls.decide_drops() == "outage":
                self.outage_since = now
                w.log(f"every vehicle dropped at once: waiting up to {w.outage_grace:g} s for them")
            self.act(ls.poll())
        if not ls.outage:
            self.outage_since = None
        elif self.outage_since is not None and now - self.outage_since > w.outage_grace:
            w.completion = "router_lost" if w._router_lost() else "vehicles_lost"
            ls.end_outage()
            self.act(ls.poll())
            w.log(f"the fleet did not come back within {w.outage_grace:g} s: the run ends ({w.completion})")
            return True
        return False


class RealtimeClock(_EffectRule):
    """The fleet steps with the wall clock from a start time t0 the world publishes once every
    vehicle is up; the world records tick n a little after it is due (REALTIME_LAG), and turns
    liveliness changes into roster changes at once."""

    name = "realtime"
    radio_from_rows = False  # radio samples from the newest telemetry as the clock passes their tick

    def __init__(self, world: "World"):
        self.w = world
        self.wake_every = min(0.25, world.period * 5)
        self.t0: float | None = None
        self.paused_at: float | None = None  # wall time of a fleet pause
        self.next_radio = 0  # the next radio sample tick
        self.next_sample = 0  # the next proximity sample tick
        self.faults_due = list(world.scenario.events)  # carried out when their time comes
        self.expect: dict[str, set[str]] = {}  # liveliness changes a fault we asked for explains
        self.lost_now: set[str] = set()  # lost with nobody asking, not back
        #: vid -> (query ref, action, monotonic deadline) of the faults the launcher has not
        #: yet said it carried out, oldest first (ref None: the scenario's, nobody waits: the
        #: launcher says `fault_done` for each fault in the order asked, theirs too)
        self.asked: dict[str, deque[tuple[object | None, str, float]]] = {}

    def __str__(self) -> str:
        return self.name

    # ------------------------------------------------------------------ where the fleet is
    def tick_now(self) -> int:
        """The wall clock's tick (0 before the start; it stands still while the fleet is paused)."""
        if self.t0 is None:
            return 0
        now = self.paused_at if self.paused_at is not None else time.time()
        return max(0, int((now - self.t0) / self.w.period))

    def tick_limit(self) -> int:
        """The newest tick a vehicle can have stepped: the wall clock's tick plus REALTIME_SLACK
        (before the start, the first ticks)."""
        return self.tick_now() + math.ceil(REALTIME_SLACK / self.w.period)

    def known_and_lead(self) -> tuple[int, int]:
        """The effect rule's inputs: the wall clock's tick, and EFFECT_LEAD_S of ticks (at least
        1) for the change to reach every vehicle before it steps the tick it names."""
        return self.tick_now(), lead_ticks(self.w.period, EFFECT_LEAD_S)

    def sim_now(self) -> float:
        """The fleet's present in simulated seconds: the wall clock's tick."""
        return self.tick_now() * self.w.period

    def first_step(self, vid: str) -> int:
        """A tick no later than the first one a (restarted, resumed) process can step now: the wall
        clock's less the slack."""
        return self.tick_now() - math.ceil(REALTIME_SLACK / self.w.period)

    def live_at(self, n: int) -> list[bool]:
        """Whose liveliness token is up (a frozen process's lapses with the lease)."""
        return [vid in self.w.st.alive for vid in self.w.ids]

    def starts_unseen(self, j: int, n: int, latest: Any) -> bool:
        """Vehicle j never reported: a fault holds it, its rows are newer than n (they come in
        order), or it is a robot holding for its odometry (it steps no tick until its first: the
        world recorded nothing and its run never ended, a 6 s run still going at 60 s)."""
        return self.w.ids[j] in self.w._faulted or latest is not None or self.w.scenario.vehicles[j].robot is not None

    def roster_states(self, tick: int) -> list[str]:
        faulted, alive = self.w._faulted, self.w.st.alive
        return ["paused" if faulted.get(vid) == "paused" else "live" if vid in alive else "gone"
                for vid in self.w.ids]

    def news_tick(self) -> int | None:
        return None

    def lost(self) -> bool:
        return bool(self.lost_now)

    # ------------------------------------------------------------------ news and commands
    def on_alive(self, name: str, j: int, up: bool) -> None:
        w = self.w
        if not w.started:
            return
        n = self.tick_now()
        if up:
            self.lost_now.discard(name)
            if w._faulted.get(name) == "paused":  # a stopped process declares nothing: this one runs
                del w._faulted[name]
            w._send_roster(RosterChange(n, j, "live", fresh=True))
            w.pub_ctl.put(encode_control("start", t0=self.t0))
            w._replay_commands(name)
            w._note(vehicle_back(n * w.period, name))
        else:
            w._send_roster(RosterChange(n, j, "gone"))
            expected = self.expect.get(name, set())
            if "down" in expected:  # the fault we asked for, already reported as such
                expected.discard("down")
            else:
                self.lost_now.add(name)
                w._note(vehicle_lost(n * w.period, name))

    def paused(self) -> bool:
        return self.paused_at is not None

    def pause(self, pause: bool) -> int:
        """Pause (or resume) the fleet now; the present tick."""
        w, tick = self.w, self.tick_now()
        if pause and self.paused_at is None:
            self.paused_at = time.time()
            w.pub_ctl.put(encode_control("pause"))
        elif not pause and self.paused_at is not None and self.t0 is not None:
            self.t0 += time.time() - self.paused_at  # the fleet's clock stood still
            self.paused_at = None
            w.pub_ctl.put(encode_control("resume", t0=self.t0))
        return tick

    def moot(self, vid: str, action: str) -> str | None:
        """Why a ground station's fault would do nothing (as Lockstep finds it on its tick: a pause
        of a vehicle not live, a resume of a live or killed one, a kill of a killed one), else None."""
        now = self.w._faulted.get(vid) or ("live" if vid in self.w.st.alive else "gone")
        moot = {"pause": now != "live", "resume": now in ("live", "killed"), "kill": now == "killed"}.get(action)
        return f"{vid} is {now} (nothing done)" if moot else None

    def vehicle_fault(self, vid: str, action: str, op: str, by: str, ref: Any):
        """Asked of the launcher now; answered when it says it carried it out (fault_done)."""
        w = self.w
        moot = self.moot(vid, action)
        if moot:
            w._note(FleetEvent.of(self.sim_now(), "rejected", f"{action} of {vid} by {by}: {moot}", vehicle=vid))
            return moot
        w.pub_launcher.put(encode_control(op, vehicle=vid))
        self.expect_news(vid, action)
        w._note(FleetEvent.of(self.sim_now(), "fault", f"{action} of {vid} by {by}", vehicle=vid))
        # every fault asked holds its place (the launcher says fault_done for each, in order): one
        # put or past MAX_WAITING, nobody waiting (ref None), too, or its word answers a later query
        self.asked.setdefault(vid, deque()).append((ref, action, time.monotonic() + RT_FAULT_CONFIRM))
        if ref is not None:  # answered when the launcher says it is done (fault_done)
            return LATER
        return Verdict(True, "realtime: the launcher carries it out now", self.tick_now())

    def expect_news(self, vid: str, action: str) -> None:
        """The liveliness changes a kill | pause | resume | restart we asked the launcher for will
        cause (a paused process's token lapses with the lease)."""
        self.expect[vid] = {"kill": {"down"}, "pause": {"down"}, "resume": set(),
                            "restart": {"down"}}.get(action, set())
        self.w._note_fault(vid, action)

    def fault_done(self, vid: str) -> None:
        """The launcher carried out a fault on ``vid``: the oldest ground station's fault on it
        waiting is answered, applied from the present tick."""
        waiting = self.asked.get(vid)
        if waiting:
            ref, _, _ = waiting.popleft()
            if ref is not None:  # else a scheduled fault's: not a ground station's answer
                self.w._decided(Decided(ref, self.tick_now()))

    def forget_faults(self) -> None:
        """At the end: no fault asked of the launcher is waited for any more."""
        self.asked.clear()

    def faults_unconfirmed(self, now: float) -> None:
        """The ground stations' faults the launcher has not confirmed in RT_FAULT_CONFIRM s are
        answered: not carried out."""
        w = self.w
        for vid, waiting in self.asked.items():
            while waiting and waiting[0][2] <= now:
                ref, action, _ = waiting.popleft()
                if ref is None:  # a scheduled fault's (the launcher's log says why it was not done)
                    continue
                why = (f"the launcher did not say it carried out the {action} of {vid} within "
                       f"{RT_FAULT_CONFIRM:g} s: not done here (a vehicle started with --remote on another "
                       "host is faulted there; see the launcher's log)")
                w._note(FleetEvent.of(self.sim_now(), "fault_missed", f"the {action} of {vid} was not "
                                      "confirmed by the launcher", vehicle=vid))
                w._decided(Decided(ref, self.tick_now(), why))

    # ------------------------------------------------------------------ the run
    def run(self) -> None:
        w = self.w
        st, T = w.st, w.period
        self.t0 = time.time() + 0.5
        w.pub_ctl.put(encode_control("start", t0=self.t0))
        last_status = last_start = time.monotonic()
        while w.next_tick <= w.last_tick and not w.stop_requested:
            w._drain(block=True)
            if self.asked:
                self.faults_unconfirmed(time.monotonic())
            self.sense()
            self.radio()
            now = time.monotonic()
            if now - last_start > STATUS_PERIOD:  # again, for late joiners
                last_start = now
                w.pub_ctl.put(encode_control("start", t0=self.t0))
            if now - last_status > STATUS_PERIOD:
                last_status = now
                w._publish_status()
            if self.paused_at is not None:
                continue
            self.scheduled_faults(self.tick_now() * T)
            due = min(self.tick_now() - REALTIME_LAG, w.last_tick)
            while w.next_tick <= due and w._record(w.next_tick):
                pass
            for old in [k for k in st.rows if k < w.next_tick]:
                st.rows.pop(old)
        if w.stop_requested and w._stop_tick is None:  # a signal: no tick was said
            return
        # a stop ends the run after the tick it said (the wall clock's, REALTIME_LAG ahead of the
        # newest recorded: a stop said "t = 17.36 s" and the metrics ended at 17.2 s)
        last = w.last_tick if w._stop_tick is None else min(w._stop_tick, w.last_tick)
        # give the final tick's telemetry a moment, then record what is left with the newest states
        end = time.monotonic() + 2.0
        live = [w.index[v] for v in st.alive]
        while (any(st.acked.get(j, -1) < last for j in live) and time.monotonic() < end
               and (not w.stop_requested or w._stop_tick is not None)):
            w._drain(block=True)
        while w.next_tick <= last and w._record(w.next_tick):
            pass

    def scheduled_faults(self, now: float) -> None:
        """Ask the launcher for the scheduled vehicle faults whose time has come (the world does
        not wait for them; their liveliness news makes the roster changes)."""
        w = self.w
        while self.faults_due and self.faults_due[0].at <= now:
            ev = self.faults_due.pop(0)
            op = FAULT_BY_EVENT[ev.action].NAMES.op
            w.pub_launcher.put(encode_control(op, vehicle=ev.vehicle))
            # its fault_done must not answer a ground station's fault asked after it
            self.asked.setdefault(ev.vehicle, deque()).append((None, ev.action, time.monotonic() + RT_FAULT_CONFIRM))
            self.expect_news(ev.vehicle, ev.action)
            w._note(FleetEvent.of(now, "fault", f"scheduled {ev.action} of {ev.vehicle} (t = {ev.at:g} s)",
                                  vehicle=ev.vehicle))

    def radio(self) -> None:
        """Once the clock has passed a radio sample tick, sample the newest telemetry of the
        vehicles alive under that tick (once each of them has sent some; never past the run)."""
        w = self.w
        if w.radio is None or self.t0 is None or self.paused_at is not None:
            return
        n = self.tick_now()
        if n < self.next_radio or n > w.last_tick:
            return
        every = w.radio[0]
        # a vehicle a fault paused or killed is not live in the sample (as in lockstep), and one
        # paused from the start, which reports nothing, holds no sample back
        alive = {w.index[v] for v in w.st.alive if v not in w._faulted}
        with w._lock:
            positions = {j: m.q for j, m in w.st.latest.items() if j in alive}
        if not w.st.latest or len(positions) < len(alive):
            return  # a live vehicle not heard from yet (the start): it would look out of range
        self.next_radio = (n // every + 1) * every
        w._send_geometry(n // every * every, positions)

    def sense(self) -> None:
        """Once the clock has passed a sample tick, sample the newest telemetry of the vehicles
        alive and publish their contacts under the present tick."""
        w = self.w
        if w.sensing is None or self.t0 is None or self.paused_at is not None:
            return
        n = self.tick_now()
        if n < self.next_sample:
            return
        every = w.sensing[0]
        self.next_sample = (n // every + 1) * every
        alive = {w.index[v] for v in w.st.alive}
        with w._lock:
            positions = {j: m.q for j, m in w.st.latest.items() if j in alive}
        w._send_contacts(n, positions)

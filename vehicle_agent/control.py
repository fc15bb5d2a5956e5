"""What does a control message from the world do to this agent, and did it apply?

The world's clock (grant, join, start, pause, resume, stop), its roster and the run-time
commands it relays (link, gains, formation, path, radio) arrive on the ``ctl`` key. Each is
decoded (cdus.wire.messages.decode_control), range-checked (:func:`ctl_problem`) and applied;
:meth:`Control.take` returns the :class:`Outcome`, applied or refused with its reason, and the
intake counts a refusal from that value. A numbered command (``seq``) applies once however often
it is heard, and only a command applied uses its number.

This module is the agent's one door for control messages. A run-time command is parsed into its
typed command and applied by it (cdus.commands: the gains rule, the path and phase checks, the
link merge are the world's and a ground station's own); its outcome is returned, not counted.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from cdus.commands.changes import Formation, Path
from cdus.commands.gains import Gains
from cdus.commands.link import Link
from cdus.commands.radio import Radio
from cdus.core.events import RosterChange
from cdus.scenario.config import nesting_problem
from cdus.wire.messages import CTL_OPS, MAX_LINK_AT, decode_control
from cdus.wire.rejected import Rejected
from cdus.wire.text import printable

if TYPE_CHECKING:
    from vehicle_agent.agent import Agent

T0_PAST = 86400.0  # s: a realtime t0 (start, resume) older than the run's duration plus this is not ours
T0_AHEAD = 60.0  # s: ... nor one further in the future than this
MAX_COMMAND_NESTING = 2  # a link or gains table nests its containers at most this deep (delay = {...})


@dataclass(frozen=True)
class Outcome:
    """What became of one control message: applied, heard again (a numbered command applied
    before: nothing to do), or refused for ``reason`` (a reject reason, counted by the intake;
    ``detail``, if any, is the log line saying what was wrong, logged each time: a bad command is
    the world's or an operator's, rare and worth a line; else the reject is logged once per reason)."""

    reason: str | None = None
    detail: str | None = None
    again: bool = False

    @property
    def applied(self) -> bool:
        return self.reason is None and not self.again


APPLIED = Outcome()
HEARD_AGAIN = Outcome(again=True)


def refused(reason: str, detail: str | None = None) -> Outcome:
    return Outcome(reason, detail)


def ctl_problem(op: str, f: dict, *, last_tick: int, period: float, ids: list[str], me: str) -> str | None:
    """What is out of range in a control message from the world (None: nothing): ticks within
    the run, a grant not past its last tick, a realtime t0 near now, a known roster vehicle."""
    last = last_tick
    if op == "grant" and not 0 <= f["until"] <= last:
        return "grant_range"
    if op == "join" and not 0 <= f["tick"] <= last:
        return "join_range"
    if op == "gains" and not 0 <= f["tick"] < 2**31:  # past the run's end it never applies: harmless
        return "gains_range"
    if op == "roster" and (f["vehicle"] not in ids or f["state"] not in ("live", "paused", "gone")
                           or not 0 <= f["tick"] <= last + 1):
        return "bad_roster"
    if op in ("start", "resume"):
        now = time.time()
        if not now - T0_PAST - last * period <= f["t0"] <= now + T0_AHEAD:
            return "t0_range"
    # a radio command's own reason: radio_range is the geometry's (a coordinate or a tick out of range)
    name = "radio_command" if op == "radio" else op
    if op in ("link", "radio") and not 0.0 <= f["at"] <= MAX_LINK_AT:
        return f"{name}_range"
    if op in ("link", "gains", "radio") and nesting_problem(f[op], MAX_COMMAND_NESTING):
        return f"{name}_range"
    if op in ("formation", "path"):
        return _change_problem(op, f, me)
    return None


def _change_problem(op: str, f: dict, me: str) -> str | None:
    """A formation or path change's tick and shape (its contents: :meth:`Control._formation`,
    :meth:`Control._path`)."""
    if not 0 <= f["tick"] < 2**31:  # past the run's end it never applies: harmless
        return f"{op}_range"
    if nesting_problem(f[op if op == "path" else "phases"], MAX_COMMAND_NESTING):
        return f"{op}_range"
    if op == "path" and f["vehicle"] != me:
        return "path_vehicle"  # the world sends a path to its vehicle only
    return None


class Control:
    """The world's control messages applied to one agent: its clock (``agent.clock``, through the
    clock strategy for a resume), its node, its link table."""

    def __init__(self, agent: Agent):
        self.agent = agent
        self.link_table: dict = agent.scenario.link_table
        self.seen: set[int] = set()  # the world's run-time commands applied, by their seq
        self.heard_again = 0  # replays of those (a catch-up said again): not applied twice
        self._apply: dict[str, Callable[[dict], Outcome]] = {
            "grant": self._grant, "join": self._join, "start": self._start, "roster": self._roster,
            "pause": self._pause, "resume": self._resume, "link": self._link, "gains": self._gains,
            "formation": self._formation, "path": self._path, "radio": self._radio, "stop": self._stop,
        }

    def take(self, payload: bytes) -> Outcome:
        """Decode, check and apply one control message; its outcome."""
        a = self.agent
        c = decode_control(payload, CTL_OPS)
        if isinstance(c, Rejected):
            return refused(c.reason)
        op, f = c.op, c.fields
        problem = ctl_problem(op, f, last_tick=a.last_tick, period=a.period, ids=a.ids, me=a.id)
        if problem is not None:
            return refused(problem)
        seq = f.get("seq")
        if seq is not None and seq in self.seen:  # a numbered run-time command: once, however often heard
            self.heard_again += 1
            return HEARD_AGAIN
        outcome = self._apply[op](f)
        # only a command applied uses its number: a refused one (counted) would else lock the
        # world's own command with that number out (an open fleet: anyone may publish first)
        if seq is not None and outcome.applied:
            self.seen.add(seq)
        return outcome

    # ------------------------------------------------------------------ the clock
    def _grant(self, f: dict) -> Outcome:
        clock = self.agent.clock
        clock.granted = max(clock.granted, f["until"])
        return APPLIED

    def _join(self, f: dict) -> Outcome:
        clock = self.agent.clock
        clock.begun, clock.join = True, f["tick"]
        return APPLIED

    def _start(self, f: dict) -> Outcome:
        self.agent.clock.t0 = f["t0"]
        return APPLIED

    def _pause(self, f: dict) -> Outcome:
        self.agent.clock.paused = True
        return APPLIED

    def _resume(self, f: dict) -> Outcome:
        self.agent.loop.resume(self.agent.clock, f["t0"])
        return APPLIED

    def _stop(self, f: dict) -> Outcome:
        self.agent.clock.stop = True
        return APPLIED

    def _roster(self, f: dict) -> Outcome:
        a = self.agent
        j = a.ids.index(f["vehicle"])
        news = a.node.on_roster(RosterChange(f["tick"], j, f["state"], f["fresh"]))
        if news and j in a.node.neighbours:  # a catch-up said again is not logged again
            a.log(f"neighbour {f['vehicle']} {f['state']} from tick {f['tick']}")
        return APPLIED

    # ------------------------------------------------------------------ run-time commands
    # Each is parsed into its typed command (cdus.commands: the same parse and rules as the world's
    # and a ground station's) and applied to the node by the command; its outcome is the value.
    def _link(self, f: dict) -> Outcome:
        """Merge the table over the current [link] table (sub-tables key by key: ``delay.jitter``
        keeps ``delay.base``); it applies to messages sent from ``at`` on. A ``policy`` or
        ``timeout`` in it changes the stale-neighbour policy from the first tick at or after ``at``."""
        a = self.agent
        cmd, done = self._carry_out(Link, {"link": f["link"], "at": f["at"]}, f["at"], (self.link_table, a.ids))
        if isinstance(done, Rejected):
            return refused("bad_link_command", f"link command rejected: {_why(done, 'link')}")
        self.link_table = cmd.merged(self.link_table, a.ids)
        a.log(f"link faults changed from t = {done.at:.2f} s: {f['link']}")
        return APPLIED

    def _carry_out(self, cls: type, fields: dict, when: float, context: object = None) -> tuple:
        """``fields`` parsed into the command ``cls`` and applied to the node from ``when`` (a
        tick, or a time for link and radio): (the command, its Applied or Rejected)."""
        cmd = cls.parse(fields)
        return cmd, cmd if isinstance(cmd, Rejected) else cmd.apply(self.agent.node, when, context)

    def _gains(self, f: dict) -> Outcome:
        """New gains for this vehicle from their tick (the gains rule: cdus.commands.gains)."""
        a, tick = self.agent, f["tick"]
        context = a.scenario.gain_context(a.id)
        cmd, done = self._carry_out(Gains, {"gains": f["gains"], "vehicle": a.id}, tick, context)
        if isinstance(done, Rejected):
            return refused("bad_gains_command", f"gains command rejected: {done}")
        v = a.node.vehicle
        k, c = cmd.for_vehicle(v.dim, tuple(v.k), v.c)
        a.log(f"gains k = {k}, c = {c} from tick {tick}{self._too_late(tick)}")
        return APPLIED

    def _formation(self, f: dict) -> Outcome:
        """New phases from their tick (checked as the world and the config check them)."""
        a, tick = self.agent, f["tick"]
        cmd, done = self._carry_out(Formation, {"phases": f["phases"]}, tick, a.ids)
        if isinstance(done, Rejected):
            return refused("bad_formation_command", f"formation command rejected: {done}")
        a.log(f"formation phases {printable(dict(cmd.phases), 200)} from tick {tick}")
        return APPLIED

    def _too_late(self, tick: int) -> str:
        """What a change from ``tick`` heard after stepping it says in the log: the node applies
        it from the next tick stepped (docs/ground_station.md, the effect tick)."""
        done = self.agent.ticks_done
        return "" if tick >= done else f" (heard too late: from tick {done})"

    def _path(self, f: dict) -> Outcome:
        """A new path for this vehicle from its tick (checked as the config's paths are)."""
        a, tick = self.agent, f["tick"]
        cmd, done = self._carry_out(Path, {"vehicle": f["vehicle"], "path": f["path"]}, tick, a.ids)
        if isinstance(done, Rejected):
            return refused("bad_path_command", f"path command rejected: {done}")
        a.log(f"path {printable(f['path'], 200)} from tick {tick}")
        return APPLIED

    def _radio(self, f: dict) -> Outcome:
        """A run-time radio change (tx_power, station) for messages sent from ``at`` on."""
        a, at = self.agent, f["at"]
        cmd, done = self._carry_out(Radio, {"radio": f["radio"], "at": at}, at)
        if isinstance(done, Rejected):
            return refused("bad_radio_command", f"radio command rejected: {done}")
        a.log(f"radio changed from t = {at:.2f} s: {printable(f['radio'], 200)}")
        return APPLIED


def _why(r: Rejected, prefix: str) -> str:
    """A refusal with its field named inside the command's table (``link.delay.base``)."""
    return str(r.under(prefix)) if r.field and not r.field.startswith(prefix) else str(r)

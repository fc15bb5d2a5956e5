"""What does a control message from the world do to this agent, and did it apply?

The world's clock (grant, join, start, pause, resume, stop), its roster and the run-time
commands it relays (link, gains, formation, path, radio) arrive on the ``ctl`` key. Each is
decoded (cdus.wire.messages.decode_control), range-checked (:func:`ctl_problem`) and applied;
:meth:`Control.take` returns the :class:`Outcome`, applied or refused with its reason, and the
intake counts a refusal from that value. A numbered command (``seq``) applies once however often
it is heard, and only a command applied uses its number.

This module is the agent's one door for control messages: wiring it to typed commands
(cdus.commands) is a change here alone.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from cdus.core.events import RosterChange, event_tick
from cdus.core.node import gains_problem
from cdus.scenario.config import ConfigError, nesting_problem
from cdus.scenario.events import check_path, check_phases
from cdus.scenario.link import merge_link_tables, validate_link
from cdus.sim.radio import apply_radio_change, radio_change_problem
from cdus.wire.messages import CTL_OPS, MAX_LINK_AT, decode_control
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
        if isinstance(c, str):
            return refused(c)
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
    def _link(self, f: dict) -> Outcome:
        """Merge the table over the current [link] table (sub-tables key by key: ``delay.jitter``
        keeps ``delay.base``); it applies to messages sent from ``at`` on. A ``policy`` or
        ``timeout`` in it changes the stale-neighbour policy from the first tick at or after ``at``."""
        a, table = self.agent, f["link"]
        merged = merge_link_tables(self.link_table, table)
        try:
            spec = validate_link(merged, a.ids, "link command")
        except (ConfigError, ValueError) as e:
            return refused("bad_link_command", f"link command rejected: {e}")
        done = a.node.set_link(spec, f["at"])
        if not done:
            return refused("bad_link_command", f"link command rejected: {done.reason}")
        at = done.at
        if "policy" in table or "timeout" in table:
            policy = a.node.set_policy(spec.policy, spec.timeout, event_tick(at, a.period))
            if not policy:
                return refused("bad_link_command", f"link command rejected: {policy.reason}")
        self.link_table = merged
        a.log(f"link faults changed from t = {at:.2f} s: {table}")
        return APPLIED

    def _gains(self, f: dict) -> Outcome:
        a, gains, tick = self.agent, f["gains"], f["tick"]
        v = a.node.vehicle
        problem = gains_problem(gains, v.dim, **a.scenario.gain_context(a.id))  # as the world checked
        if problem is not None:
            return refused("bad_gains_command", f"gains command rejected: {problem}")
        k = gains.get("k", v.k)
        k = tuple(float(x) for x in k) if isinstance(k, (list, tuple)) else (float(k),) * v.dim
        c = float(gains.get("c", v.c))
        done = a.node.set_gains(k, c, tick)
        if not done:
            return refused("bad_gains_command", f"gains command rejected: {done.reason}")
        a.log(f"gains k = {tuple(k)}, c = {c} from tick {tick}{self._too_late(tick)}")
        return APPLIED

    def _formation(self, f: dict) -> Outcome:
        """New phases from their tick (checked as the world and the config check them)."""
        a, tick = self.agent, f["tick"]
        checked = check_phases(f["phases"], a.ids)
        if isinstance(checked, tuple):
            return refused("bad_formation_command", f"formation command rejected: {' '.join(checked)}")
        done = a.node.set_formation({a.ids.index(vid): theta for vid, theta in checked.items()}, tick)
        if not done:
            return refused("bad_formation_command", f"formation command rejected: {done.reason}")
        a.log(f"formation phases {printable(checked, 200)} from tick {tick}")
        return APPLIED

    def _too_late(self, tick: int) -> str:
        """What a change from ``tick`` heard after stepping it says in the log: the node applies
        it from the next tick stepped (docs/ground_station.md, the effect tick)."""
        done = self.agent.ticks_done
        return "" if tick >= done else f" (heard too late: from tick {done})"

    def _path(self, f: dict) -> Outcome:
        """A new path for this vehicle from its tick (checked as the config's paths are)."""
        a, table, tick = self.agent, f["path"], f["tick"]
        path = check_path(table, a.node.vehicle.dim)
        if isinstance(path, tuple):
            return refused("bad_path_command", f"path command rejected: {' '.join(path)}")
        done = a.node.set_path(path, tick)
        if not done:
            return refused("bad_path_command", f"path command rejected: {done.reason}")
        a.log(f"path {printable(table, 200)} from tick {tick}")
        return APPLIED

    def _radio(self, f: dict) -> Outcome:
        """A run-time radio change (tx_power, station) for messages sent from ``at`` on."""
        a, change, at = self.agent, f["radio"], f["at"]
        radio = a.node.radio
        problem = "this scenario has no [radio] table" if radio is None else radio_change_problem(change)
        if problem is None:
            try:
                apply_radio_change(radio.channel, change, at)
            except ValueError as e:
                problem = str(e)
        if problem is not None:
            return refused("bad_radio_command", f"radio command rejected: {problem}")
        a.log(f"radio changed from t = {at:.2f} s: {printable(change, 200)}")
        return APPLIED

"""What does each run-time command do to the run?

A command's op and fields are parsed once into a typed command (cdus.commands.parse.parse_wire:
the same parse as a ground station's and a scenario event's), a refusal counted and answered
(:meth:`CommandHandlers.carry_out`); then one handler per command type
(:meth:`CommandHandlers.handlers`) checks it against this fleet as the agents would, computes
the tick it applies from with the clock's one rule (``effect_tick``, cdus.commands.effect),
relays it to the vehicles (numbered, kept for (re)joiners and world/settings) and returns its
verdict (world_sim.verdict): Verdict, a reason string (rejected), or LATER (decided when its
tick comes)."""

from __future__ import annotations

import math
from typing import Any, Callable, NamedTuple

from cdus.commands.changes import Formation, Path
from cdus.commands.effect import tick_of
from cdus.commands.fleet import Pause, Resume, Stop
from cdus.commands.gains import Gains
from cdus.commands.link import Link
from cdus.commands.parse import BY_OP, parse_wire
from cdus.commands.radio import Radio
from cdus.commands.vehicle import VEHICLE_FAULTS, Kill, PauseVehicle, Restart, ResumeVehicle
from cdus.sim.radio import apply_radio_change
from cdus.sim.reports import formation_changed, path_changed
from cdus.wire import keys
from cdus.wire.messages import MAX_LINK_AT, encode_control
from cdus.wire.schemas import FleetEvent, MAX_REASON
from cdus.wire.rejected import Rejected
from cdus.wire.text import printable
from world_sim.verdict import Verdict


class _Change(NamedTuple):
    """A run-time change the world sent to the vehicles (its ctl payload, numbered), kept for
    (re)joiners and world/settings."""

    kept_for: str | None  # one vehicle; None: every vehicle
    payload: bytes
    op: str
    tick: int | None  # a gains change's tick (None for the others, which are all replayed)


class CommandHandlers:
    """The World's command handlers, one per op, and the run-time changes they relayed (a mixin
    of World)."""

    def handlers(self) -> dict[type, Callable[[Any, str, int | None], Any]]:
        """command type -> handler(command, by, ref) -> Verdict | reason str | None | LATER
        (world_sim.verdict; ``ref``: the asking query's, None if nobody waits): the one table
        the world dispatches commands by (other parts may add theirs)."""
        return {
            Stop: self._cmd_stop, Pause: self._cmd_pause, Resume: self._cmd_resume, Gains: self._cmd_gains,
            Link: self._cmd_link, Formation: self._relay_formation, Path: self._relay_path, Radio: self._cmd_radio,
            **{fault: self._cmd_vehicle_fault for fault in VEHICLE_FAULTS},
        }

    def carry_out(self, op: str, fields: dict, by: str, ref: int | None = None) -> Any:
        """A decoded command map's ``op`` and ``fields`` from ``by``, carried out: parsed into its
        type (a refusal counted under the command's op, or ``unknown_op``, and answered), then
        handed to its handler. ``fault_done`` is the launcher's word, not a command."""
        if op == "fault_done":
            return self._cmd_fault_done(fields, by)
        command = parse_wire(op, fields)
        if isinstance(command, Rejected):
            kind = BY_OP.get(op)
            return self._refuse(by, kind.NAMES.op if kind is not None else "unknown_op", f"{op} command",
                                str(command))
        handler = self.command_handlers.get(type(command))
        if handler is None:
            self._reject(by, "unknown_op")
            return f"this world does not carry out {op!r}"
        return handler(command, by, ref)

    def _effect_tick(self) -> int:
        """The first tick a run-time change applies from, on every vehicle alike: the clock's one
        rule (world_sim.clocks, ``effect_tick``), used by every handler."""
        return self.clock.effect_tick()

    def _cmd_stop(self, c: Stop, by: str, ref: int | None = None) -> Verdict | str:
        if self.stop_requested:
            return "the run is stopping"
        # the launcher asks only when it was interrupted (Ctrl-C, SIGTERM); anyone else's stop is an operator's
        interrupted = by == keys.LAUNCHER
        self._note(FleetEvent.of(self._sim_now(), "fleet", "fleet stopped: the launcher was interrupted"
                                 if interrupted else f"fleet stopped by {by}"))
        self.completion = self.completion or ("interrupted" if interrupted else "stopped")
        self.stop_requested = True
        # the tick of the event (and of the run's last record): the answer said the next one, a tick later
        tick = round(self._sim_now() / self.period)
        self._stop_tick = tick
        return Verdict(True, "the run ends after this tick: its metrics are written", tick)

    def _cmd_fault_done(self, f: dict, by: str) -> Verdict | str:
        if by != keys.LAUNCHER:
            self._reject(by, "sender")
            return "only the launcher reports a fault carried out"
        if f["vehicle"] in self.index:
            self.clock.fault_done(f["vehicle"])
        return Verdict(True, "", max(0, self.lockstep.granted))

    def _cmd_pause(self, c: Pause, by: str, ref: int | None = None) -> Verdict | str | None:
        return self._fleet_pause(True, by)

    def _cmd_resume(self, c: Resume, by: str, ref: int | None = None) -> Verdict | str | None:
        return self._fleet_pause(False, by)

    def _cmd_gains(self, c: Gains, by: str, ref: int | None = None) -> Verdict | str:
        return self._relay_gains(c, by)

    def _cmd_link(self, c: Link, by: str, ref: int | None = None) -> Verdict | str:
        asked = c.at
        if asked is not None and asked >= self.duration:  # it would be answered "applied" and never apply
            return self._refuse(by, "link", "link command",
                                f"--at {asked:g} s is not before the end of the run ({self.duration:g} s): "
                                "it would change nothing; give a time within the run")
        if asked is not None and asked > MAX_LINK_AT:
            return self._refuse(by, "link", "link command",
                                f"link command: at = {asked:.6g} s is beyond the latest time a link change "
                                f"may name ({MAX_LINK_AT:g} s of simulated time)")
        # the agents' own check, made before relaying: a change they would refuse is no change
        merged = c.merged(self._link_table, self.ids)
        if isinstance(merged, Rejected):
            return self._refuse(by, "link", "link command", str(merged))
        # Never before the effect tick (what a vehicle may already have sent), so every receiver
        # applies it from the same message on; a past --at means "now" (the clock's one rule).
        at, late_note = self.clock.effect_time(asked)
        late = self._never_applies(tick_of(at, self.period))
        if late:
            return self._refuse(by, "link", "link command", late)
        self._link_table = merged
        change = c.link_table()
        self._send_command(None, None, c.NAMES.op, link=change, at=float(at))
        self.st.link_commanded = True
        self._note(FleetEvent.of(self._sim_now(), "link_changed",
                                 f"link faults changed from t = {at:.2f} s by {by}: {printable(change, 200)}"),
                   by_command=True)
        return Verdict(True, late_note, tick_of(at, self.period), float(at))

    def _cmd_vehicle_fault(self, c: Kill | PauseVehicle | ResumeVehicle | Restart, by: str,
                           ref: int | None = None) -> Verdict | str:
        """kill | pause_vehicle | resume_vehicle | restart: the clock's to carry out, under the
        command's names (its wire op for the launcher, its event word for the roster and news)."""
        vid = c.vehicle
        if vid not in self.index:
            self._reject(by, "unknown_vehicle")
            return f"no vehicle {printable(vid, 64)!r} in this fleet (its vehicles: {', '.join(self.ids)})"
        return self.clock.vehicle_fault(vid, c.NAMES.event, c.NAMES.op, by, ref)

    def _relay_radio(self, c: Radio, sender: str) -> Verdict | str | None:
        """A ground station's radio change ``{"radio": {tx_power, station}, "at": s}``: checked,
        then relayed to every vehicle with the send time it applies from, never before what a
        vehicle may already have sent (lockstep: past the grant; a past ``at`` means as soon as
        possible), like a link command. The verdict (applied from that time), else why it was not."""
        change = c.change()
        if self.radio is None:
            return "this scenario has no [radio] table"
        problem = c.topology_problem(self.radio_watch.channel.spec.topology)
        if problem is not None:
            return str(problem)
        at, late = self.clock.effect_time(c.at)
        end = self.last_tick * self.period
        if at > end:  # it would never apply, and epochs go in time order: it would refuse every later change
            return (f"--at {at:g} s is past the run's end (t = {end:g} s): it would never apply; give --at "
                    f"from now to {end:g} s, or no --at (as soon as possible)")
        later = self.radio_watch.channel.epochs[-1][0] if self.radio_watch is not None else -math.inf
        if at < later:  # changes apply in time order (epochs): a scheduled or earlier command's comes later
            return (f"a radio change from t = {later:g} s is already in force later (scheduled or commanded); "
                    f"give --at {later:g} or later")
        self._send_command(None, None, c.NAMES.op, radio=change, at=float(at))
        if self.radio_watch is not None:
            apply_radio_change(self.radio_watch.channel, change, float(at))
        self._note(FleetEvent.of(self._sim_now(), "radio_changed",
                                 f"radio changed from t = {at:.2f} s by {printable(sender, 64)}: "
                                 f"{printable(change, 200)}"), by_command=True)
        return Verdict(True, late, tick_of(at, self.period), float(at))

    def _cmd_radio(self, c: Radio, by: str, ref: int | None = None) -> Verdict | str:
        """The ``radio`` command: relayed (:meth:`_relay_radio`) or refused, counted and reported."""
        out = self._relay_radio(c, by)
        if isinstance(out, str):
            self._reject(by, "radio")
            self._note(FleetEvent.of(self._sim_now(), "rejected",
                                     f"radio command from {printable(by, 64)}: {printable(out, 200)}"))
        return out

    def _relay_gains(self, c: Gains, sender: str) -> Verdict | str:
        """A gains change for one vehicle or all, checked for each (the gains rule,
        cdus.commands.gains.Gains.for_vehicle, as each agent checks it), relayed with its tick."""
        vehicle, gains = c.vehicle or "", c.fields()["gains"]
        targets = self.ids if vehicle == "" else [vehicle] if vehicle in self.index else []
        problems = set()
        for v in targets:
            spec = self.scenario.vehicle(v)
            kc = c.for_vehicle(spec.dim, tuple(spec.k), spec.c, **self.scenario.gain_context(v))
            if isinstance(kc, Rejected):
                problems.add(str(kc))
        if not targets or problems:  # all or nothing: no fleet with gains half changed
            self._reject(sender, "gains")
            why = f"no vehicle {printable(vehicle, 64)!r}" if not targets else printable("; ".join(sorted(problems)))
            self._note(FleetEvent.of(self._sim_now(), "rejected",
                                     f"gains {printable(gains, 120)} from {sender}: {why}"))
            return why
        tick = self._effect_tick()
        late = self._never_applies(tick)
        if late:
            return self._refuse(sender, "gains", f"gains {printable(gains, 120)}", late)
        self._send_command(targets, vehicle or None, c.NAMES.op, gains=gains, tick=tick)
        self._note(FleetEvent.of(tick * self.period, "gains_changed",
                                 f"gains {gains} for {vehicle or 'every vehicle'} from tick {tick} by {sender}"),
                   by_command=True)
        return Verdict(True, "", tick)

    def _never_applies(self, tick: int) -> str | None:
        """Why a change from ``tick`` would never apply (past the run's last tick: near the end the
        grant has reached it, or the wall clock nearly has), else None. It was answered "applied
        from tick N+1" and `cdus gs` exited 0."""
        if tick <= self.last_tick:
            return None
        return (f"the run's last tick is {self.last_tick} (t = {self.last_tick * self.period:.2f} s) and the first "
                f"this change could apply from is {tick}: it would never apply (the run is ending)")

    def _refuse(self, sender: str, reason: str, what: str, why: str) -> str:
        """Count and report a refused command; returns the reason (for an acknowledgement)."""
        self._reject(sender, reason)
        self._note(FleetEvent.of(self._sim_now(), "rejected",
                                 f"{what} from {printable(sender, 64)}: {printable(why, 200)}"))
        return printable(why, MAX_REASON)  # the ground station's reply keeps all a reply may hold

    def _relay_formation(self, c: Formation, sender: str, ref: int | None = None) -> Verdict | str:
        """A ground station's formation change: phases ``{id: θ}`` or offsets ``[{i, k, delta}]``
        (exactly one), checked as the config's are (offsets with the Δs in force on the other
        edges must close around every cycle) and turned into phases, relayed to every vehicle
        with the tick they apply from (:meth:`_effect_tick`), and measured against from that
        tick. Returns the verdict (applied from that tick), else the reason it was refused."""
        tick = self._effect_tick()
        late = self._never_applies(tick)
        if late:
            return self._refuse(sender, "formation", "formation", late)
        sc = self.scenario
        resolved = c.resolve(self.ids, self.recorder.formation.phases_at(tick), sc.edges, sc.directed)
        if isinstance(resolved, Rejected):  # offsets that do not close: the reason names the cycle and the fix
            why = resolved.reason if resolved.field == "offsets" else str(resolved)
            return self._refuse(sender, "formation", "formation", why)
        ordered = list(resolved.phases)
        self.recorder.formation.add(tick, {self.index[vid]: theta for vid, theta in ordered})
        for lo in range(0, len(ordered), 32):  # a control map holds at most 64 entries (decode_control)
            self._send_command(None, None, c.NAMES.op, phases=dict(ordered[lo:lo + 32]), tick=tick)
        self._note(formation_changed(tick, self.period, ordered, sender), by_command=True)
        return Verdict(True, "" if ordered else "no phase changed: the offsets given were in force", tick)

    def _relay_path(self, c: Path, sender: str, ref: int | None = None) -> Verdict | str:
        """A ground station's new path for one vehicle, checked as the config's paths are, relayed
        to that vehicle with the tick it applies from. Returns the verdict, else the reason."""
        vid, table = c.vehicle, c.path_table()
        if vid not in self.index:
            return self._refuse(sender, "unknown_vehicle", "path", f"no vehicle {printable(vid, 64)!r}")
        path = c.checked_for(self.scenario.vehicle(vid).dim)
        if isinstance(path, Rejected):
            return self._refuse(sender, "path", f"path of {vid}", str(path))
        tick = self._effect_tick()
        late = self._never_applies(tick)
        if late:
            return self._refuse(sender, "path", f"path of {vid}", late)
        self._send_command([vid], vid, c.NAMES.op, vehicle=vid, path=table, tick=tick)
        self._note(path_changed(tick, self.period, vid, sorted(table.items()), sender), by_command=True)
        return Verdict(True, "", tick)

    def _fleet_pause(self, pause: bool, by: str = "") -> Verdict | str:
        if pause == self.clock.paused():
            return "the fleet is already paused" if pause else "the fleet is not paused"  # not news
        tick = self.clock.pause(pause)
        self._note(FleetEvent.of(self._sim_now(), "fleet", ("fleet paused" if pause else "fleet resumed")
                                 + (f" by {by}" if by else "")))
        self._publish_status()  # at once: a ground station attaching is answered the newest status
        return Verdict(True, "", tick)

    def _send_command(self, to: list[str] | None, kept_for: str | None, op: str, **fields: Any) -> None:
        """A run-time command to the vehicles ``to`` (None: the ctl publisher, every vehicle), kept
        for (re)joiners (``kept_for`` one vehicle, None all) and numbered (``seq``: a process that
        hears it again applies it once). A gains change for the same vehicles on the same tick as
        the change kept last replaces it there (a vehicle applies both at that tick, the later
        last: the earlier one never shows): a flood of them in one grant is one entry."""
        seq = self._seq
        self._seq += 1
        payload = encode_control(op, **fields, seq=seq)
        if to is None:
            self.pub_ctl.put(payload)
        else:
            self._put(keys.ctl(self.fleet, to), payload)
        change = _Change(kept_for, payload, op, fields["tick"] if op == "gains" else None)
        last = self._commands[-1] if self._commands else None
        if change.tick is not None and last is not None and (last.op, last.kept_for, last.tick) == (
                op, kept_for, change.tick):
            self._commands[-1] = change
        else:
            self._commands.append(change)
        self._settings_changed(op)

    def _replay_commands(self, vid: str) -> None:
        """A (re)started or resumed process missed the ground stations' run-time commands (a new
        one starts from the scenario file): send it each again, in order. Each applies from the
        time or tick it did (link changes at once if that is past), so it ends where the rest of
        the fleet is. Of the gains changes that apply before the first tick it can step, only the
        last is sent (it applies them all at that tick, the last last): a restart after a flood
        of gains changes is sent the one in force and those still to come, not the history."""
        first = self.clock.first_step(vid)
        mine = [c for c in self._commands if c.kept_for is None or c.kept_for == vid]
        in_force = max((i for i, c in enumerate(mine) if c.tick is not None and c.tick <= first), default=None)
        for i, c in enumerate(mine):
            if c.tick is None or c.tick > first or i == in_force:
                self._put(keys.ctl(self.fleet, [vid]), c.payload)

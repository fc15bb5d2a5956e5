"""How does the launcher carry out a vehicle fault the world asks for? Typed, checked, then a signal.

The world asks on the launcher's key (``to/+launcher+/cmd``) for a kill, pause, resume or restart
of one vehicle (cdus.commands.vehicle). Only the scenario's own vehicles started here are
faulted: anything else (``kill world``, an unknown id, a vehicle started on another host, a
malformed message) is counted by reason, logged once per reason (escaped) and dropped. The
supervise loop carries the faults out (:meth:`FaultDispatch._carry_out`, on the main thread:
children are only started there) and tells the world each is done (``fault_done``).
"""

from __future__ import annotations

import signal
from typing import Any

import zenoh

from cdus.commands.parse import parse_wire
from cdus.commands.vehicle import Kill, PauseVehicle, Restart, ResumeVehicle, VehicleFault
from cdus.wire import keys
from cdus.wire.messages import LAUNCHER_OPS, decode_control, encode_control
from cdus.wire.rejected import Rejected
from cdus.wire.text import printable


class FaultDispatch:
    """The launcher's fault requests (mixed into cdus.app.launcher.Launcher, whose ``scenario``,
    ``children``, ``cond``, ``requests``, ``rejected``, ``env``, ``session``, ``fleet`` and
    ``log`` it uses)."""

    def _on_fault_request(self, sample: Any) -> None:
        """The world asks for a vehicle fault; the supervise loop carries it out. Only faults on
        the scenario's vehicles started here: never the world, an unknown or a remote id."""
        c = decode_control(sample.payload.to_bytes(), LAUNCHER_OPS)
        fault = c if isinstance(c, Rejected) else parse_wire(c.op, c.fields)
        if isinstance(fault, Rejected) and fault.field == "vehicle":
            self._reject("command not_a_vehicle", f"{c.op} {printable(c.fields['vehicle'], 64)}: not a vehicle id")
            return
        if isinstance(fault, Rejected):  # the decoder's reason, or a command that is not one ('type')
            self._reject(f"command {fault.reason if fault is c else 'type'}",
                         f"a malformed command on {printable(str(sample.key_expr))}")
            return
        vid, op = fault.vehicle, fault.NAMES.op
        if vid not in self.scenario.ids:
            self._reject("command not_a_vehicle", f"{op} {printable(vid, 64)}: not a vehicle of the scenario")
            return
        if vid not in self.children:
            self._reject("command remote", f"{op} {printable(vid, 64)}: started on another host, not here")
            return
        with self.cond:
            self.requests.append(fault)
            self.cond.notify_all()

    def _reject(self, reason: str, what: str) -> None:
        """Count a dropped message by reason; log the first of each reason (escaped text only)."""
        with self.cond:
            n = self.rejected[reason] = self.rejected.get(reason, 0) + 1
        if n == 1:
            self.log(f"  rejected: {what} ({reason}; further ones are only counted)")

    def _carry_out(self, fault: VehicleFault) -> None:
        """A vehicle fault (cdus.commands.vehicle) on a process started here: a signal, or a new process."""
        vid = fault.vehicle
        c = self.children[vid]
        if isinstance(fault, (Kill, Restart)):
            c.restart_at = None  # the fault decides, not a pending restart by the policy
        if isinstance(fault, Kill):
            c.intended_exit = True
            c.signal_group(signal.SIGKILL)
        elif isinstance(fault, PauseVehicle):
            c.signal_group(signal.SIGSTOP)
        elif isinstance(fault, ResumeVehicle):
            c.signal_group(signal.SIGCONT)
        elif isinstance(fault, Restart):
            if c.running():
                c.intended_exit = True
                c.signal_group(signal.SIGKILL)
                c.proc.wait()
            c.poll()
            c.restarts += 1
            c.start(self.env)
        op = fault.NAMES.op
        self.log(f"  fault: {fault.NAMES.event} {vid}")
        try:
            self.session.put(keys.world_cmd(self.fleet, keys.LAUNCHER), encode_control("fault_done", vehicle=vid))
        except zenoh.ZError as e:
            self.log(f"  could not tell the world the {op} of {vid} is done: {e}")

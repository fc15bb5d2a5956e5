"""What does the agent take from what arrives, and what does it refuse?

Every sample addressed to the vehicle comes here by its key (:meth:`Intake.take`): a
neighbour's ω (its exact key is known, no parsing), the world's control messages
(vehicle_agent.control), its proximity contacts and its radio geometry. Everything is
validated where it enters (cdus.wire.messages, then cdus.core.node for ω) and a reject is
counted by reason (stale duplicates too) and logged once per sender and reason. ω is accepted
only within the clock's horizon of what its sender can have sent, and, in realtime, only at the
rate a sender can send (``rate``, checked before decoding: vehicle_agent.realtime).
"""

from __future__ import annotations

from collections import Counter
from typing import TYPE_CHECKING, Any

from cdus.core.radiolink import as_point
from cdus.sim.build import listeners_of
from cdus.sim.sensing import contacts_of
from cdus.wire import keys
from cdus.wire.rejected import Rejected
from cdus.wire.messages import decode_contacts, decode_geometry, decode_omega
from cdus.wire.text import printable
from vehicle_agent.control import Outcome

if TYPE_CHECKING:
    from vehicle_agent.agent import Agent

_KINDS = ("omega", "state", "stats", "ctl", "contacts", "cmd", "wake", "last")  # named in a reject reason
MAX_LOGGED = 256  # (sender, reason) pairs logged; past that, rejects are only counted


def _bytes(payload: Any) -> bytes:
    """A payload as the public door gives it (bytes) or as Zenoh delivers it (ZBytes)."""
    return payload if isinstance(payload, bytes) else payload.to_bytes()


class Intake:
    """One agent's receive path and its reject counters (``rejected``, by reason)."""

    def __init__(self, agent: Agent):
        self.agent = agent
        self.rejected: Counter = Counter()  # by reason, every reject (the node's ω ones too, but "gone")
        self._logged: set[tuple[str, str]] = set()
        sc, f, ids = agent.scenario, agent.fleet, agent.ids
        # the exact key each neighbour's ω arrives on (its listener set is known): no parsing
        self.omega_from: dict[str, int] = {keys.omega(f, ids[k], listeners_of(sc, ids[k])): k
                                           for k in agent.node.neighbours}
        self._dims = [v.dim for v in sc.vehicles]  # the world sends a boat 2 coordinates, a drone 3
        self._leaves = {"ctl": self.ctl, "contacts": self.contacts, "radio": self.geometry}

    def reject(self, sender: str, reason: str) -> None:
        self.rejected[reason] += 1
        if (sender, reason) not in self._logged and len(self._logged) < MAX_LOGGED:  # once per sender, reason
            self._logged.add((sender, reason))
            self.agent.log(f"rejected a message from {printable(sender, 64)!r}: {reason} (counted; logged once)")

    def take(self, key: str, payload: Any, now: float | None) -> None:
        """One sample addressed to this vehicle. ``now``: simulated arrival time (realtime) or None."""
        k = self.omega_from.get(key)
        if k is not None:
            return self.omega(k, payload, now)
        kind = keys.leaf_kind(key)
        take = self._leaves.get(kind)
        if take is not None:
            take(_bytes(payload))
            return None
        if kind == "wake":
            return None
        kind, src = keys.leaf(key)
        self.reject(src or key, "unexpected_" + (kind if kind in _KINDS else "key"))

    def omega(self, k: int, payload: Any, now: float | None) -> None:
        """An ω on neighbour ``k``'s key (the inbox's, or its realtime ring's)."""
        a = self.agent
        if a.loop.over_rate(k):  # before decoding: a flood costs a lookup and a subtraction
            return self.reject(a.ids[k], "rate")
        msg = decode_omega(_bytes(payload), expected_sender=k, n_vehicles=len(a.ids))
        if isinstance(msg, Rejected):
            return self.reject(a.ids[k], msg.reason)
        a.node.horizon = a.loop.horizon(a.clock, a.period, a.rejoin)
        reason = a.node.on_message(msg, now)
        if reason is not None:
            self.reject(a.ids[k], reason)
        else:
            a.loop.refund(k)

    def ctl(self, payload: bytes) -> Outcome:
        """A control message from the world (vehicle_agent.control): a refusal counted by its reason."""
        outcome = self.agent.control.take(payload)
        if outcome.reason is not None:
            if outcome.detail is None:
                self.reject(keys.WORLD, outcome.reason)
            else:
                self.rejected[outcome.reason] += 1
                self.agent.log(printable(outcome.detail, 240))
        return outcome

    def contacts(self, payload: bytes) -> None:
        """The world's proximity sensor: this vehicle's contacts of a sample tick (counted and
        dropped if malformed)."""
        a = self.agent
        msg = decode_contacts(payload, len(a.ids), a.index, a.node.vehicle.dim)
        if isinstance(msg, Rejected):
            return self.reject(keys.WORLD, f"contacts_{msg.reason}")
        if msg.tick > a.last_tick:  # no sample is taken past the run's end: kept, it would never be freed
            return self.reject(keys.WORLD, "contacts_range")
        a.node.on_contacts(msg.tick, contacts_of(msg, a.ids))

    def geometry(self, payload: bytes) -> None:
        """The world's radio geometry sample (cdus.sim.radio): counted and dropped if malformed, out
        of the run, not on the sample schedule, without [radio], or a second one for its tick
        (the first stands: ``radio_stale`` if it is the same, ``radio_conflict`` if not)."""
        a = self.agent
        radio = a.node.radio
        if radio is None:
            return self.reject(keys.WORLD, "radio_unexpected")
        msg = decode_geometry(payload, len(a.ids), self._dims)
        if isinstance(msg, Rejected):
            return self.reject(keys.WORLD, f"radio_{msg.reason}")
        if msg.tick > a.last_tick:
            return self.reject(keys.WORLD, "radio_range")
        if msg.tick % radio.every:
            return self.reject(keys.WORLD, "radio_tick")
        if not a.node.on_geometry(msg.tick, msg.positions):
            # the world says a sample again only to a (re)joining process, with the same bytes: a
            # second, different sample for a tick is someone else's (an open fleet): the first stands
            held = radio.held(msg.tick)
            same = held is not None and held.positions == tuple(None if q is None else as_point(q)
                                                                for q in msg.positions)
            self.reject(keys.WORLD, "radio_stale" if same else "radio_conflict")

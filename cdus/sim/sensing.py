"""When does the proximity sensor sample, and when does a vehicle use it? One schedule for both
runners (docs/safety.md).

The world (or the in-process fleet) samples every vehicle's position at the sensor ticks
s (s % every == 0; cdus.sim.build.sensor_schedule), once every vehicle live at s has
stepped it, and hands each vehicle its contacts (cdus.core.proximity.sense) as a
:class:`cdus.wire.messages.ContactsMsg`; the vehicle uses them from tick s + latency.
Both runners put the message through the wire codec once, so they are bit-identical.
"""

from __future__ import annotations

from typing import Mapping, Sequence

from cdus.core.paths import Vec
from cdus.core.proximity import Body, sense
from cdus.core.safety import Contact
from cdus.scenario.model import Scenario
from cdus.wire.messages import ContactsMsg


def sense_tick(scenario: Scenario, tick: int, positions: Mapping[int, Vec],
               gone: Mapping[int, Vec] | None = None) -> dict[int, ContactsMsg]:
    """Every sampled vehicle's contacts at ``tick`` from ``positions`` (vehicle index -> q of
    the vehicles that stepped ``tick``), keyed by vehicle index; an empty message for a vehicle that sees nobody (a deterministic runner waits for it). ``gone``:
    the vehicles that are not live, where they were last seen: obstacles the others see
    (share 1), sent nothing."""
    vehicles = scenario.vehicles
    index = {v.id: v.index for v in vehicles}
    bodies = [Body(vehicles[j].id, vehicles[j].kind, tuple(q)) for j, q in sorted(positions.items())]
    bodies += [Body(vehicles[j].id, vehicles[j].kind, tuple(q), live=False)
               for j, q in sorted((gone or {}).items()) if j not in positions]
    seen = sense(bodies, scenario.safety.range, scenario.safety.cross_domain)
    return {index[vid]: ContactsMsg(tick, tuple((index[c.id], c.share, tuple(c.q)) for c in cs))
            for vid, cs in seen.items()}


def contacts_of(msg: ContactsMsg, ids: Sequence[str]) -> tuple[Contact, ...]:
    """The core's contacts from a (decoded, checked) wire message."""
    return tuple(Contact(q, ids[k], share) for k, share, q in msg.contacts)

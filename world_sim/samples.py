"""What does the world sample for the vehicles: proximity contacts and radio geometry?

With the safety filter on, each vehicle its contacts at the sensor ticks (cdus.sim.sensing);
with [radio], every vehicle's position at the radio ticks (cdus.sim.radio), watched for the
events and views. Which ticks, and from which telemetry, is the clock's (world_sim.clocks)."""

from __future__ import annotations

from cdus.sim.radio import geometry_sample
from cdus.sim.sensing import sense_tick
from cdus.wire import keys
from cdus.wire.messages import decode_geometry, encode_contacts, encode_geometry
from cdus.wire.rejected import Rejected


class Samples:
    """The proximity contacts and radio geometry the World sends the vehicles (a mixin of
    World)."""

    def _send_contacts(self, tick: int, positions: dict[int, tuple]) -> None:
        """The proximity sensor at ``tick``: each sampled vehicle its contacts (cdus.sim.sensing);
        a vehicle not sampled (killed, paused) stays an obstacle where it was last seen."""
        for old in [k for k in self._sample_rows if k < tick]:
            del self._sample_rows[old]
        with self._lock:
            gone = {j: m.q for j, m in self.st.latest.items() if j not in positions}
        for j, msg in sense_tick(self.scenario, tick, positions, gone).items():
            self._put(keys.contacts(self.fleet, self.ids[j]), encode_contacts(msg))

    def _send_geometry(self, tick: int, positions: dict[int, tuple]) -> None:
        """The radio geometry at ``tick`` (cdus.sim.radio), as the in-process fleet samples it: the
        positions of the vehicles that stepped it, to every vehicle, then watched (events, views)."""
        for old in [k for k in self._radio_rows if k < tick]:
            del self._radio_rows[old]
        payload = encode_geometry(geometry_sample(tick, positions, len(self.ids), self._dims))
        self.pub_radio.put(payload)
        self._radio_sent.append((tick, payload))
        msg = decode_geometry(payload, len(self.ids))  # what the vehicles read: the same numbers
        if isinstance(msg, Rejected) or self.radio_watch is None:
            return
        for ev in self.radio_watch.observe(msg):
            self._note(ev)
        self.sink.radio(tick * self.period, self.radio_watch)

    def _replay_geometry(self, vid: str) -> None:
        """A (re)joining process needs the radio samples in force from its join on: the newest ones."""
        for _, payload in self._radio_sent:
            self._put(keys.radio(self.fleet, [vid]), payload)

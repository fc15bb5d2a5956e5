"""Who publishes the fleet to ROS 2? A process of its own, reading what the world reads.

The bridge (``python -m cdus.ros2``, started by ``cdus launch --ros2``) is one ROS 2 node in
rmw_zenoh's format (:mod:`cdus.ros2.rmw`): a liveliness token for the node and one per
publisher, so ``ros2 node list`` and ``ros2 topic list`` show them. It subscribes to the
vehicles' telemetry (``to/*/state/*``) and the fleet's events on the fleet's own Zenoh and
republishes them as the topics of :mod:`cdus.ros2.fleet`: per vehicle its pose, odometry, ω and
ω̇ and a /tf transform every ``1/rate`` simulated seconds, /clock at every control tick (once
two live vehicles have reported it, one when one is live: /clock never goes back, and no one
vehicle can push it ahead and freeze it), each event as it
comes, and the paths once, at the start, kept for late subscribers (transient local).

It cannot slow the fleet: a sample is put in a bounded queue in Zenoh's callback and taken
from there by the bridge's own thread, so a slow bridge drops its oldest telemetry (counted)
and never holds up the router's link to it. A hostile or malformed sample is counted by reason
and dropped. It stops when the world's liveliness token goes (the run is over) or on SIGTERM.
"""

from __future__ import annotations

import collections
import json
import signal
import threading
import time
from typing import Any, Callable


from cdus.ros2 import fleet as rf
from cdus.ros2.publisher import Publisher
from cdus.ros2.rmw import Node
from cdus.scenario.model import Scenario
from cdus.core.schedule import total_ticks
from cdus.sim.polyline import path_polyline
from cdus.wire import keys
from cdus.wire.access import ROS2_ROLE
from cdus.wire.rejected import Rejected
from cdus.wire.messages import decode_states
from cdus.wire.schemas import decode_event

MAX_T = 2.0**31 - 1  # s: builtin_interfaces/Time's seconds are an int32
GONE = object()  # in the queue: (GONE, name) when a liveliness token goes
QUEUE = 4096  # samples waiting for the bridge's thread; past this the oldest are dropped (counted)


class Republisher:
    """What the bridge makes of one sample of the fleet: telemetry rows into the vehicles' topics
    and /clock, an event into the events topic. ``publish((vehicle or None, field), value)`` sends
    a message; a malformed or forged sample is counted in ``rejected`` by reason and dropped."""

    def __init__(self, scenario: Scenario, fleet: str, publish: Callable[[tuple[str | None, str], dict], None],
                 duration: float | None = None):
        self.fleet, self.publish, self.spec, self.ids = keys.check_fleet(fleet), publish, scenario.ros2, scenario.ids
        self.every = rf.every(scenario.ros2, scenario.rates.control)
        self.period = 1.0 / scenario.rates.control
        self.last = total_ticks(duration or scenario.duration, self.period)  # the run's last tick
        self.rejected: dict[str, int] = {}
        self.last_tick = -1
        self.before: dict[str, tuple[float, float]] = {}  # per vehicle, (t, heading) of its previous row
        #: per vehicle, the newest tick it reported; /clock is the second newest of them while two
        #: or more vehicles are live (the newest with one): no one vehicle moves the fleet's clock.
        #: Before, the first row of a tick published it: one forged row at the run's last tick (from
        #: a vehicle's own credentials) froze /clock for the rest of the run.
        self.newest: dict[str, int] = {}
        self.gone_ids: set[str] = set()  # vehicles whose liveliness token went, until they report again

    def gone(self, vid: str) -> None:
        """A vehicle's liveliness token went (killed, ended): its ticks no longer hold /clock back."""
        if vid in self.ids:
            self.newest.pop(vid, None)
            self.gone_ids.add(vid)
            self._clock()

    def _clock(self) -> None:
        need = 2 if len(self.ids) - len(self.gone_ids) >= 2 else 1
        ticks = sorted(self.newest.values())
        if len(ticks) < need:
            return
        tick = ticks[-need]
        if tick > self.last_tick:
            self.last_tick = tick
            self.publish((None, "clock"), rf.clock(tick * self.period))

    def _reject(self, reason: str) -> None:
        self.rejected[reason] = self.rejected.get(reason, 0) + 1

    def handle(self, key: str, payload: bytes) -> None:
        """One sample from the fleet: telemetry rows or an event."""
        if key == keys.world_events(self.fleet):
            e = decode_event(payload, self.ids)
            if isinstance(e, Rejected):
                self._reject(f"event {e.reason}")
                return
            self.publish((None, "events"), {"data": json.dumps(e.as_dict(), ensure_ascii=False)})
            return
        kind, src = keys.leaf(key)
        if kind != "state" or src not in self.ids:
            self._reject("state unknown_sender")
            return
        rows = decode_states(payload, len(self.ids))
        if isinstance(rows, Rejected):
            self._reject(f"state {rows.reason}")
            return
        for row in rows:
            vid = self.ids[row.sender]
            if vid != src:  # a vehicle speaks only for itself
                self._reject("state wrong_sender")
                continue
            if not (row.tick <= self.last and 0.0 <= row.t < MAX_T and abs(row.t - row.tick * self.period) <= self.period / 2):
                self._reject("state tick_time")  # t_n = n T, n within the run: a forged tick would stop /clock
                continue
            self.publish_row(vid, row)

    def publish_row(self, vid: str, row: Any) -> None:
        frame = self.spec.world_frame
        if row.tick > self.newest.get(vid, -1):
            self.newest[vid] = row.tick
            self.gone_ids.discard(vid)  # restarted
            self._clock()
        rate = rf.yaw_rate(row.heading, row.t, self.before.get(vid))
        self.before[vid] = (row.t, row.heading)
        if row.tick % self.every:
            return
        for which, value in rf.vehicle_messages(vid, row.t, row.q, row.heading, row.speed, row.omega, row.omega_rate,
                                                frame, rate):
            self.publish(which, value)


class Bridge:
    def __init__(self, scenario: Scenario, fleet: str, session: Any, log: Callable[[str], None] = print,
                 duration: float | None = None):
        self.scenario, self.fleet, self.session, self.log = scenario, keys.check_fleet(fleet), session, log
        spec = self.spec = scenario.ros2
        self.ids = scenario.ids
        self.node = Node(spec.domain_id, str(session.info.zid()), rf.node_name(fleet), spec.namespace)
        self.dropped = 0
        self.queue: collections.deque = collections.deque()
        self.cond = threading.Condition()
        self.world_seen = False
        self.world_tokens: set[str] = set()  # the world's sessions whose tokens are up (_on_world)
        self.stop = False
        self.node_token = session.liveliness().declare_token(self.node.token())
        self.pubs: dict[tuple[str | None, str], Publisher] = {}
        for entity_id, topic in enumerate(rf.topics(spec, self.ids), start=1):
            self.pubs[(topic.vehicle, topic.field)] = Publisher(session, self.node, entity_id, topic,
                                                                rf.key(spec, topic), spec.distro)
        for v in scenario.vehicles:  # once: the advanced publisher keeps it for late subscribers
            self.pubs[(v.id, "path")].publish(rf.path(path_polyline(v, scenario.duration), spec.world_frame))
        self.republisher = Republisher(scenario, fleet, lambda which, value: self.pubs[which].publish(value), duration)
        f = self.fleet
        self.subs = [session.declare_subscriber(keys.any_state(f), self._enqueue),
                     session.declare_subscriber(keys.world_events(f), self._enqueue),
                     session.liveliness().declare_subscriber(keys.alive_of(f, keys.WORLD), self._on_world,
                                                             history=True),
                     session.liveliness().declare_subscriber(keys.any_alive(f), self._on_alive)]
        # ready: the launcher waits for it
        self.alive = session.liveliness().declare_token(keys.alive(f, ROS2_ROLE, str(session.zid())))

    # ------------------------------------------------------------------ Zenoh's threads: never block
    def _enqueue(self, sample: Any) -> None:
        with self.cond:
            if len(self.queue) >= QUEUE:
                self.queue.popleft()
                self.dropped += 1
            self.queue.append((str(sample.key_expr), sample.payload.to_bytes()))
            self.cond.notify()

    def _on_alive(self, sample: Any) -> None:
        if str(sample.kind).endswith("DELETE"):  # handled in order with the telemetry, on the bridge's thread
            with self.cond:
                self.queue.append((GONE, keys.alive_name(str(sample.key_expr)) or ""))
                self.cond.notify()

    def _on_world(self, sample: Any) -> None:
        """The world's tokens, exactly as keys.alive makes them (a wildcard or bare key is
        nobody's: ignored): the world is gone once every token it was seen with is."""
        token = keys.alive_token(str(sample.key_expr))
        if token is None or token[0] != keys.WORLD:
            return
        with self.cond:
            if str(sample.kind).endswith("DELETE"):
                self.world_tokens.discard(token[1])
                self.stop = self.stop or (self.world_seen and not self.world_tokens)
            else:
                self.world_tokens.add(token[1])
                self.world_seen = True
            self.cond.notify()

    def request_stop(self) -> None:
        with self.cond:
            self.stop = True
            self.cond.notify()

    # ------------------------------------------------------------------ the bridge's thread
    def run(self) -> int:
        """Republish until the world is gone or a stop is asked for. Returns 0."""
        while True:
            with self.cond:
                while not self.queue and not self.stop:
                    self.cond.wait(timeout=1.0)
                if self.stop and not self.queue:
                    break
                batch, self.queue = self.queue, collections.deque()
            for key, payload in batch:
                if key is GONE:
                    self.republisher.gone(payload)
                else:
                    self.republisher.handle(key, payload)
        return 0

    def summary(self) -> str:
        sent = sum(p.sent for p in self.pubs.values())
        rej = ", ".join(f"{n} {r}" for r, n in sorted(self.republisher.rejected.items())) or "none"
        return (f"ros2 bridge: {sent} messages published on {len(self.pubs)} topics (domain {self.spec.domain_id}, "
                f"{self.spec.distro}); {self.dropped} telemetry samples dropped by a full queue; rejected: {rej}; "
                f"CPU {time.process_time():.2f} s")

    def close(self) -> None:
        for s in self.subs:
            s.undeclare()
        self.alive.undeclare()
        for p in self.pubs.values():
            p.close()
        self.node_token.undeclare()


def run_bridge(scenario: Scenario, fleet: str, session: Any, duration: float | None = None) -> int:
    bridge = Bridge(scenario, fleet, session, duration=duration)
    signal.signal(signal.SIGTERM, lambda *_: bridge.request_stop())
    signal.signal(signal.SIGINT, lambda *_: bridge.request_stop())
    bridge.log(f"ros2 bridge up: node {bridge.node.namespace.rstrip('/')}/{bridge.node.name}, "
               f"{len(bridge.pubs)} publishers in domain {scenario.ros2.domain_id}")
    try:
        return bridge.run()
    finally:
        bridge.log(bridge.summary())
        bridge.close()

"""How does cdus publish one ROS 2 topic? A Zenoh publisher at rmw_zenoh's key, its graph token, its
GID and sequence number in every publication's attachment (cdus.ros2.rmw). The bridge publishes
the fleet's topics with it, a robot's agent (vehicle_agent.robot) its Twist; apart from Zenoh it
loads only the CDR encoder, so a vehicle process stays light (tests/vehicle_agent/test_footprint.py).
"""

from __future__ import annotations

import time
from typing import Any

import zenoh
import zenoh.ext

from cdus.ros2 import cdr, fleet as rf
from cdus.ros2.rmw import Node, attachment, gid


class Publisher:
    """One ROS 2 publisher: its Zenoh publisher, its graph token, its GID and sequence number."""

    def __init__(self, session: Any, node: Node, entity_id: int, topic: rf.Topic, key: str, distro: str):
        self.topic = topic
        if topic.qos.transient_local:  # what rmw_zenoh does: an advanced publisher with a cache
            self.pub = zenoh.ext.declare_advanced_publisher(
                session, key, cache=zenoh.ext.CacheConfig(max_samples=topic.qos.depth), publisher_detection=True)
        else:
            self.pub = session.declare_publisher(key)
        self.token = session.liveliness().declare_token(
            node.publisher_token(entity_id, topic.name, topic.type_name, topic.qos, distro))
        self.gid = gid(node.zid, entity_id)
        self.seq = 0
        self.sent = 0

    def publish(self, value: dict) -> None:
        self.seq += 1
        self.pub.put(cdr.encode(self.topic.type_name, value), attachment=attachment(self.seq, time.time_ns(), self.gid))
        self.sent += 1

    def close(self) -> None:
        self.token.undeclare()
        self.pub.undeclare()

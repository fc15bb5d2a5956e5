"""Is a ``[ros2]`` table valid? The fleet's ROS 2 face, validated into a :class:`Ros2Spec`.

``[ros2]`` (docs/ros2.md) says whether ``cdus launch`` publishes the fleet as ROS 2 topics in
rmw_zenoh's format, and how: the ROS domain, the namespace of the fleet's topics, the ROS 2
distribution whose keys to use, the world frame and the rate of the per-vehicle topics. It is
off unless ``enabled = true`` (or ``cdus launch --ros2``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from cdus.scenario.checks import Problems

ROS2_KEYS = ("enabled", "domain_id", "namespace", "distro", "world_frame", "rate")
DISTROS = ("jazzy", "humble")  # jazzy: Jazzy and later (RIHS01 type hashes); humble: TypeHashNotSupported
MAX_DOMAIN_ID = 232  # ROS 2's largest domain id (DDS ports; rmw_zenoh takes the same range)
MAX_RATE = 1000.0
_TOKEN = r"[A-Za-z][A-Za-z0-9_]*"
NAMESPACE_RE = re.compile(rf"^/$|^(/{_TOKEN})+$")
FRAME_RE = re.compile(rf"^{_TOKEN}(/{_TOKEN})*$")


@dataclass(frozen=True)
class Ros2Spec:
    """The validated ``[ros2]`` table (docs/ros2.md)."""

    enabled: bool = False
    domain_id: int = 0
    namespace: str = "/cdus"  # the fleet's topics: <namespace>/<vehicle>/pose, ...; /tf and /clock are global
    distro: str = "jazzy"
    world_frame: str = "world"
    rate: float = 10.0  # Hz of simulated time: per-vehicle topics and /tf; /clock goes every control tick


def ros_name(vid: str) -> str:
    """A vehicle id as a ROS name token: ``-`` becomes ``_``, a leading digit gets ``v``
    (``usv-1`` -> ``usv_1``, ``1a`` -> ``v1a``)."""
    token = vid.replace("-", "_")
    return "v" + token if token[:1].isdigit() else token


def ros2_section(p: Problems, table: Mapping[str, Any], ids: Sequence[str] | None) -> Ros2Spec:
    """``[ros2]``: every key checked; the defaults of :class:`Ros2Spec` for those absent."""
    p.unknown_keys(table, ROS2_KEYS, "ros2")
    d = Ros2Spec()
    enabled = p.boolean(table.get("enabled", d.enabled), "ros2.enabled",
                        true=" (cdus launch publishes the fleet as ROS 2 topics)", false=" (the default)")
    domain = p.integer(table.get("domain_id", d.domain_id), "ros2.domain_id", ge=0,
                       note=" (ROS_DOMAIN_ID of the ROS 2 machines that should see the fleet)")
    if domain is not None and domain > MAX_DOMAIN_ID:
        p.add("ros2.domain_id", f"must be at most {MAX_DOMAIN_ID} (ROS 2's domain ids are 0-{MAX_DOMAIN_ID}), "
                                f"got {domain}")
        domain = None
    namespace = p.string(table.get("namespace", d.namespace), "ros2.namespace")
    if namespace is not None and not NAMESPACE_RE.match(namespace):
        p.add("ros2.namespace", f"must be a ROS 2 namespace such as \"/cdus\" or \"/lake/fleet1\" (a leading /, "
                                f"names of letters, digits and _ starting with a letter), got {namespace!r}")
        namespace = None
    distro = p.choice(table.get("distro", d.distro), "ros2.distro", DISTROS, "ROS 2 distribution",
                      extra=" (jazzy for Jazzy and later)")
    frame = p.string(table.get("world_frame", d.world_frame), "ros2.world_frame")
    if frame is not None and not FRAME_RE.match(frame):
        p.add("ros2.world_frame", f"must be a frame id such as \"world\" or \"map\" (letters, digits and _), "
                                  f"got {frame!r}")
        frame = None
    rate = d.rate
    if "rate" in table:
        rate = p.number(table["rate"], "ros2.rate", gt=0, le=MAX_RATE,
                        unit=" Hz of simulated time (poses, odometry, ω and /tf; /clock every control tick)") or d.rate
    if enabled and ids is not None:
        seen: dict[str, str] = {}
        for vid in ids:
            other = seen.setdefault(ros_name(vid), vid)
            if other != vid:
                p.add("ros2", f"vehicles {other!r} and {vid!r} would share the ROS 2 name {ros_name(vid)!r} "
                              f"(a - becomes _): rename one to publish the fleet as ROS 2 topics")
    return Ros2Spec(bool(enabled), d.domain_id if domain is None else domain, namespace or d.namespace,
                    distro or d.distro, frame or d.world_frame, rate)

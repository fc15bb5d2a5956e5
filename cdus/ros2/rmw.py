"""Where does a ROS 2 publication go on Zenoh? rmw_zenoh's key expressions, liveliness tokens,
QoS strings and attachments (ros2/rmw_zenoh, docs/design.md).

- A topic's data: ``<domain>/<fully qualified name, no leading slash>/<DDS type>/<type hash>``,
  e.g. ``0/chatter/std_msgs::msg::dds_::String_/RIHS01_df66...``. On Humble the hash is
  ``TypeHashNotSupported``.
- A node's liveliness token: ``@ros2_lv/<domain>/<session id>/<node id>/<node id>/NN/<enclave>/
  <namespace>/<node name>``; a publisher's: ``@ros2_lv/<domain>/<session id>/<node id>/<entity id>/
  MP/<enclave>/<namespace>/<node name>/<topic>/<DDS type>/<type hash>/<qos>``, names mangled
  (every ``/`` a ``%``; the root namespace and an empty enclave ``%``).
- QoS: ``<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:<lifespan s>,<ns>:
  <liveliness>,<s>,<ns>``, a field equal to rmw_zenoh's default left empty (reliable,
  volatile, keep last, infinite durations, automatic liveliness); the depth always written.
- Every publication's attachment, as Zenoh's own serializer writes it: the sequence number
  (int64), the source timestamp (int64, ns since the epoch), and the 16-byte GID as a
  length-prefixed byte string (LEB128 length 16, then the bytes).
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass

from cdus.ros2.types import HUMBLE_HASH, dds_name, type_hash
from cdus.scenario.ros2 import DISTROS

ADMIN_SPACE = "@ros2_lv"
GID_SIZE = 16
RELIABLE, BEST_EFFORT = 1, 2  # rmw_qos_reliability_policy_e
TRANSIENT_LOCAL, VOLATILE = 1, 2  # rmw_qos_durability_policy_e
KEEP_LAST = 1


def mangle(name: str) -> str:
    """``/cdus/usv1/pose`` -> ``%cdus%usv1%pose``; the root or an empty name -> ``%``."""
    return name.replace("/", "%") if name not in ("", "/") else "%"


def hash_for(type_name: str, distro: str) -> str:
    """The type hash a ``distro`` publisher puts in its keys."""
    if distro not in DISTROS:
        raise ValueError(f"ROS 2 distribution {distro!r}: choose one of {', '.join(DISTROS)}")
    return HUMBLE_HASH if distro == "humble" else type_hash(type_name)


def topic_key(domain: int, topic: str, type_name: str, distro: str = "jazzy") -> str:
    """The data key of ``topic`` (fully qualified, ``/ns/name``)."""
    return f"{domain}/{topic.strip('/')}/{dds_name(type_name)}/{hash_for(type_name, distro)}"


@dataclass(frozen=True)
class Qos:
    """What rmw_zenoh's liveliness tokens say of a publisher's QoS (the fields cdus sets)."""

    depth: int = 10
    transient_local: bool = False
    reliable: bool = True

    def encode(self) -> str:
        reliability = "" if self.reliable else str(BEST_EFFORT)
        durability = str(TRANSIENT_LOCAL) if self.transient_local else ""
        return f"{reliability}:{durability}:,{self.depth}:,:,:,,"


@dataclass(frozen=True)
class Node:
    """A ROS 2 node as the graph sees it: one Zenoh session (``zid``), its id within it."""

    domain: int
    zid: str
    name: str
    namespace: str = "/"
    node_id: int = 0
    enclave: str = ""

    def token(self) -> str:
        return (f"{ADMIN_SPACE}/{self.domain}/{self.zid}/{self.node_id}/{self.node_id}/NN/"
                f"{mangle(self.enclave)}/{mangle(self.namespace)}/{self.name}")

    def publisher_token(self, entity_id: int, topic: str, type_name: str, qos: Qos, distro: str = "jazzy") -> str:
        return (f"{ADMIN_SPACE}/{self.domain}/{self.zid}/{self.node_id}/{entity_id}/MP/"
                f"{mangle(self.enclave)}/{mangle(self.namespace)}/{self.name}/{mangle(topic)}/"
                f"{dds_name(type_name)}/{hash_for(type_name, distro)}/{qos.encode()}")


def gid(zid: str, entity_id: int) -> bytes:
    """A publisher's 16-byte GID: unique per session and entity (rmw_zenoh hashes the same)."""
    return hashlib.sha256(f"{zid}/{entity_id}".encode()).digest()[:GID_SIZE]


def attachment(seq: int, timestamp_ns: int, source_gid: bytes) -> bytes:
    """The attachment of one publication (see the module's docstring)."""
    if len(source_gid) != GID_SIZE:
        raise ValueError(f"a GID is {GID_SIZE} bytes, got {len(source_gid)}")
    return struct.pack("<qqB", seq, timestamp_ns, GID_SIZE) + source_gid


def decode_attachment(data: bytes) -> tuple[int, int, bytes] | str:
    """(sequence number, source timestamp, GID), or why ``data`` is not an attachment."""
    if len(data) != 17 + GID_SIZE:
        return "size"
    seq, ts, n = struct.unpack_from("<qqB", data)
    if n != GID_SIZE:
        return "gid_size"
    return seq, ts, bytes(data[17:])

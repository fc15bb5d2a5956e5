"""What is a ROS 2 message type? The few the fleet publishes, their type hashes and definitions.

Each type is its fields as the ROS 2 interface definitions (common_interfaces,
rcl_interfaces, geometry2) declare them, once, in :data:`TYPES`; everything else is derived
from that table: the RIHS01 type hash (REP-2011: SHA-256 over a canonical JSON of the type
description and every type it references, :func:`type_hash`), the DDS type name rmw_zenoh
puts in its key expressions (:func:`dds_name`), and the ``.msg`` text with its dependencies
that MCAP's ``ros2msg`` schema encoding carries (:func:`definition`). The CDR encoder
(:mod:`cdus.ros2.cdr`) walks the same table.

A field type is a primitive (``float64``, ``int32``, ``uint32``, ``string``), a message type
(``geometry_msgs/msg/Pose``), or either followed by ``[N]`` (a fixed array) or ``[]`` (an
unbounded sequence).
"""

from __future__ import annotations

import hashlib
import json
import re

#: the fields of every message type the fleet uses (their default values play no part in the hash)
TYPES: dict[str, tuple[tuple[str, str], ...]] = {
    "builtin_interfaces/msg/Time": (("sec", "int32"), ("nanosec", "uint32")),
    "std_msgs/msg/Header": (("stamp", "builtin_interfaces/msg/Time"), ("frame_id", "string")),
    "std_msgs/msg/String": (("data", "string"),),
    "std_msgs/msg/Float64": (("data", "float64"),),
    "geometry_msgs/msg/Point": (("x", "float64"), ("y", "float64"), ("z", "float64")),
    "geometry_msgs/msg/Vector3": (("x", "float64"), ("y", "float64"), ("z", "float64")),
    "geometry_msgs/msg/Quaternion": (("x", "float64"), ("y", "float64"), ("z", "float64"), ("w", "float64")),
    "geometry_msgs/msg/Pose": (("position", "geometry_msgs/msg/Point"),
                               ("orientation", "geometry_msgs/msg/Quaternion")),
    "geometry_msgs/msg/PoseStamped": (("header", "std_msgs/msg/Header"), ("pose", "geometry_msgs/msg/Pose")),
    "geometry_msgs/msg/PoseWithCovariance": (("pose", "geometry_msgs/msg/Pose"), ("covariance", "float64[36]")),
    "geometry_msgs/msg/Twist": (("linear", "geometry_msgs/msg/Vector3"), ("angular", "geometry_msgs/msg/Vector3")),
    "geometry_msgs/msg/TwistWithCovariance": (("twist", "geometry_msgs/msg/Twist"), ("covariance", "float64[36]")),
    "geometry_msgs/msg/Transform": (("translation", "geometry_msgs/msg/Vector3"),
                                    ("rotation", "geometry_msgs/msg/Quaternion")),
    "geometry_msgs/msg/TransformStamped": (("header", "std_msgs/msg/Header"), ("child_frame_id", "string"),
                                           ("transform", "geometry_msgs/msg/Transform")),
    "nav_msgs/msg/Odometry": (("header", "std_msgs/msg/Header"), ("child_frame_id", "string"),
                              ("pose", "geometry_msgs/msg/PoseWithCovariance"),
                              ("twist", "geometry_msgs/msg/TwistWithCovariance")),
    "nav_msgs/msg/Path": (("header", "std_msgs/msg/Header"), ("poses", "geometry_msgs/msg/PoseStamped[]")),
    "tf2_msgs/msg/TFMessage": (("transforms", "geometry_msgs/msg/TransformStamped[]"),),
    "rosgraph_msgs/msg/Clock": (("clock", "builtin_interfaces/msg/Time"),),
}

#: type_description_interfaces/msg/FieldType: the id of each primitive (1: a nested message)
FIELD_TYPE_IDS = {"int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8,
                  "uint64": 9, "float32": 10, "float64": 11, "char": 13, "bool": 15, "byte": 16, "string": 17}
NESTED = 1
ARRAY_OFFSET, UNBOUNDED_SEQUENCE_OFFSET = 48, 144  # FieldType: a fixed array, an unbounded sequence of the type
HUMBLE_HASH = "TypeHashNotSupported"  # what rmw_zenoh on Humble (no type descriptions yet) puts in its keys

_FIELD_RE = re.compile(r"^(?P<base>[A-Za-z0-9_/]+)(?:\[(?P<size>\d*)\])?$")


def parse_field(ftype: str) -> tuple[str, int | None]:
    """(element type, array length) of a field type: None for a single value, 0 for an
    unbounded sequence ``T[]``, N for a fixed array ``T[N]``."""
    m = _FIELD_RE.match(ftype)
    if m is None:
        raise ValueError(f"field type {ftype!r}: not a ROS 2 field type")
    size = m.group("size")
    return m.group("base"), None if size is None else (int(size) if size else 0)


def is_message(base: str) -> bool:
    return "/" in base


def _field_description(name: str, ftype: str) -> dict:
    base, size = parse_field(ftype)
    tid = NESTED if is_message(base) else FIELD_TYPE_IDS[base]
    if size is not None:
        tid += UNBOUNDED_SEQUENCE_OFFSET if size == 0 else ARRAY_OFFSET
    return {"name": name, "type": {"type_id": tid, "capacity": size or 0, "string_capacity": 0,
                                   "nested_type_name": base if is_message(base) else ""}}


def referenced(type_name: str) -> list[str]:
    """Every message type ``type_name`` refers to, directly or not, sorted by name."""
    seen: set[str] = set()
    todo = [type_name]
    while todo:
        for _, ftype in TYPES[todo.pop()]:
            base, _ = parse_field(ftype)
            if is_message(base) and base not in seen:
                seen.add(base)
                todo.append(base)
    return sorted(seen)


def type_hash(type_name: str) -> str:
    """The RIHS01 hash of ``type_name`` (REP-2011, as rosidl_generator_type_description computes
    it: the type description with its referenced types sorted by name, default values left out,
    as JSON with ``", "`` and ``": "`` separators)."""

    def description(name: str) -> dict:
        return {"type_name": name, "fields": [_field_description(n, t) for n, t in TYPES[name]]}

    data = {"type_description": description(type_name),
            "referenced_type_descriptions": [description(r) for r in referenced(type_name)]}
    text = json.dumps(data, ensure_ascii=True, allow_nan=False, separators=(", ", ": "), sort_keys=False)
    return "RIHS01_" + hashlib.sha256(text.encode()).hexdigest()


def dds_name(type_name: str) -> str:
    """The DDS type name rmw_zenoh keys carry: ``std_msgs/msg/String`` -> ``std_msgs::msg::dds_::String_``."""
    pkg, kind, name = type_name.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def _short(type_name: str) -> str:
    pkg, _, name = type_name.split("/")
    return f"{pkg}/{name}"


def _msg_text(type_name: str) -> str:
    lines = []
    for name, ftype in TYPES[type_name]:
        base, size = parse_field(ftype)
        shown = _short(base) if is_message(base) else base
        suffix = "" if size is None else f"[{size}]" if size else "[]"
        lines.append(f"{shown}{suffix} {name}")
    return "\n".join(lines)


def definition(type_name: str) -> str:
    """The ``.msg`` definition of ``type_name`` followed by each type it refers to, as rosbag2
    writes MCAP schemas (encoding ``ros2msg``)."""
    parts = [_msg_text(type_name)]
    for r in referenced(type_name):
        parts.append("=" * 80 + f"\nMSG: {_short(r)}\n" + _msg_text(r))
    return "\n".join(parts) + "\n"

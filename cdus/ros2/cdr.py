"""How does a ROS 2 message look on the wire? CDR, little-endian, as rmw_zenoh and rosbag2 carry it.

A serialized message is the 4-byte encapsulation header ``00 01 00 00`` (CDR, little
endian) and the fields in order, each primitive aligned to its own size counted from the
end of the header; a string is its uint32 length (with the terminating NUL), its UTF-8
bytes and the NUL; a sequence is its uint32 count and its elements; a fixed array only its
elements. The fields come from :data:`cdus.ros2.types.TYPES`, the one table of the types.

A message's value is a mapping of its field names to values (nested mappings for nested
messages, sequences for arrays); a field left out is zero, an empty string or an empty
sequence (Quaternion's ``w`` included: give it).

:func:`decode` reads the same bytes back (a robot's odometry, issue 29): it returns the
mapping, or :class:`cdus.wire.rejected.Rejected` with the reason (``header``, ``truncated``,
``string``, ``count``, ``trailing``), never raising, whatever the bytes.
"""

from __future__ import annotations

import struct
from typing import Any, Mapping

from cdus.ros2.types import TYPES, is_message, parse_field
from cdus.wire.rejected import Rejected

ENCAPSULATION = b"\x00\x01\x00\x00"  # CDR_LE
PRIMITIVES = {"int8": "b", "uint8": "B", "int16": "h", "uint16": "H", "int32": "i", "uint32": "I",
              "int64": "q", "uint64": "Q", "float32": "f", "float64": "d", "bool": "?", "byte": "B", "char": "B"}
_SIZES = {k: struct.calcsize(v) for k, v in PRIMITIVES.items()}


class _Writer:
    __slots__ = ("buf",)

    def __init__(self) -> None:
        self.buf = bytearray(ENCAPSULATION)

    def align(self, n: int) -> None:
        pad = (-(len(self.buf) - 4)) % n
        if pad:
            self.buf += b"\x00" * pad

    def primitive(self, kind: str, v: Any) -> None:
        size = _SIZES[kind]
        self.align(size)
        self.buf += struct.pack("<" + PRIMITIVES[kind], v)

    def primitives(self, kind: str, values: Any) -> None:
        values = list(values)
        if values:
            self.align(_SIZES[kind])
            self.buf += struct.pack(f"<{len(values)}{PRIMITIVES[kind]}", *values)

    def string(self, s: str) -> None:
        data = s.encode("utf-8")
        self.primitive("uint32", len(data) + 1)
        self.buf += data + b"\x00"


def _value(w: _Writer, base: str, v: Any) -> None:
    if is_message(base):
        _message(w, base, v)
    elif base == "string":
        w.string(v)
    else:
        w.primitive(base, v)


def _message(w: _Writer, type_name: str, value: Mapping[str, Any]) -> None:
    for name, ftype in TYPES[type_name]:
        base, size = parse_field(ftype)
        v = value.get(name)
        if size is None:
            _value(w, base, _default(base) if v is None else v)
            continue
        items = list(v) if v is not None else ([] if size == 0 else [_default(base)] * size)
        if size == 0:
            w.primitive("uint32", len(items))
        elif len(items) != size:
            raise ValueError(f"{type_name}.{name}: {len(items)} values for an array of {size}")
        if base in PRIMITIVES:
            w.primitives(base, items)
        else:
            for item in items:
                _value(w, base, item)


def _default(base: str) -> Any:
    if is_message(base):
        return {}
    return "" if base == "string" else 0


def encode(type_name: str, value: Mapping[str, Any]) -> bytes:
    """The CDR bytes of ``value``, a message of type ``type_name`` (e.g. ``std_msgs/msg/String``)."""
    if type_name not in TYPES:
        raise KeyError(f"{type_name}: not a type cdus publishes ({', '.join(sorted(TYPES))})")
    w = _Writer()
    _message(w, type_name, value)
    return bytes(w.buf)


MAX_SEQUENCE = 1 << 16  # elements: a count beyond this is refused before anything is allocated
DECODE_REASONS = ("header", "truncated", "string", "count", "trailing")


class _Malformed(Exception):
    def __init__(self, reason: str):
        self.reason = reason


class _Reader:
    __slots__ = ("buf", "pos")

    def __init__(self, buf: bytes):
        self.buf, self.pos = buf, 4

    def align(self, n: int) -> None:
        self.pos += (-(self.pos - 4)) % n

    def take(self, n: int) -> bytes:
        if self.pos + n > len(self.buf):
            raise _Malformed("truncated")
        out = self.buf[self.pos:self.pos + n]
        self.pos += n
        return out

    def primitive(self, kind: str) -> Any:
        size = _SIZES[kind]
        self.align(size)
        return struct.unpack("<" + PRIMITIVES[kind], self.take(size))[0]

    def primitives(self, kind: str, n: int) -> list:
        if n == 0:
            return []
        self.align(_SIZES[kind])
        return list(struct.unpack(f"<{n}{PRIMITIVES[kind]}", self.take(n * _SIZES[kind])))

    def string(self) -> str:
        n = self.primitive("uint32")
        if n == 0 or n > len(self.buf):
            raise _Malformed("string")
        data = self.take(n)
        if data[-1] != 0:
            raise _Malformed("string")
        try:
            return data[:-1].decode("utf-8")
        except UnicodeDecodeError:
            raise _Malformed("string") from None


def _read_value(r: _Reader, base: str) -> Any:
    if is_message(base):
        return _read_message(r, base)
    return r.string() if base == "string" else r.primitive(base)


def _read_message(r: _Reader, type_name: str) -> dict:
    out: dict = {}
    for name, ftype in TYPES[type_name]:
        base, size = parse_field(ftype)
        if size is None:
            out[name] = _read_value(r, base)
            continue
        n = size
        if size == 0:
            n = r.primitive("uint32")
            if n > MAX_SEQUENCE:
                raise _Malformed("count")
        if base in PRIMITIVES:
            out[name] = r.primitives(base, n)
        else:
            out[name] = [_read_value(r, base) for _ in range(n)]
    return out


def decode(type_name: str, data: bytes) -> dict | Rejected:
    """The message of type ``type_name`` in ``data`` (CDR little-endian with its header, as
    :func:`encode` writes it), or ``Rejected(reason)``: ``header`` (not CDR_LE), ``truncated``,
    ``string`` (no NUL, bad UTF-8 or a length past the end), ``count`` (a sequence longer than
    :data:`MAX_SEQUENCE`), ``trailing`` (more than alignment padding after the message)."""
    if type_name not in TYPES:
        raise KeyError(f"{type_name}: not a type cdus knows ({', '.join(sorted(TYPES))})")
    buf = bytes(data)
    if len(buf) < 4 or buf[:2] != ENCAPSULATION[:2]:
        return Rejected("header")
    r = _Reader(buf)
    try:
        value = _read_message(r, type_name)
    except _Malformed as e:
        return Rejected(e.reason)
    if len(buf) - r.pos > 7:  # a serializer may pad the end to 4 or 8 bytes; more is not this type
        return Rejected("trailing")
    return value

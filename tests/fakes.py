"""Stand-ins for the few Zenoh objects the process shells touch, for tests without a network."""

from __future__ import annotations

from dataclasses import dataclass


class Payload:
    def __init__(self, data: bytes):
        self.data = data

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class Sample:
    """What a subscription hands over: a key and a payload."""

    key_expr: str
    payload: Payload

"""What goes over the radio: the ω message, its wire format and its validation.

The one source of truth for the schema; every process imports it. Payload (msgpack):

    [version=1, sender index, seq, t_send (float64 s), ω (float64), ω̇ (float32)]

at most 31 bytes. ω is float64 on the wire and everywhere else: it is unbounded (it
decreases at 1/s forever) and a narrow type would ruin it (dgvf.md §4). The sender's
id travels in the key (``cdus/<fleet>/v/<id>/omega``); the index inside the payload
must agree with it. ``decode_omega`` never raises: it returns a message or the reason
for rejecting it, so a receiver can count and drop without a try/except in its loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import msgpack

OMEGA_VERSION = 1
MAX_OMEGA_PAYLOAD = 32
F32_MAX = 3.0e38  # ω̇ is clamped to the float32 range on the wire


@dataclass(frozen=True)
class OmegaMsg:
    sender: int  # index of the sender in the scenario's vehicle list
    seq: int  # per-sender sequence number, starts at 0, strictly increasing
    t_send: float  # sender's clock: simulated s (lockstep/in-process) or wall s (realtime)
    omega: float
    omega_rate: float  # mean ω̇ over the sender's last control period


def encode_omega(m: OmegaMsg) -> bytes:
    """The payload of ``m``: a 6-element msgpack array, ω̇ packed as float32 (a rate
    near -1 that is only used to extrapolate), everything else exact."""
    return b"".join((
        b"\x96",
        _pack(OMEGA_VERSION), _pack(m.sender), _pack(m.seq),
        _pack(float(m.t_send)), _pack(float(m.omega)),
        msgpack.packb(max(-F32_MAX, min(F32_MAX, float(m.omega_rate))), use_single_float=True),
    ))


_pack = msgpack.Packer(use_single_float=False, autoreset=True).pack


def decode_omega(payload: bytes, expected_sender: int | None = None, n_vehicles: int | None = None
                 ) -> OmegaMsg | str:
    """A valid message, or a short reason string (``"malformed"``, ``"version"``, ...)."""
    if len(payload) > MAX_OMEGA_PAYLOAD:
        return "oversized"
    try:
        obj = msgpack.unpackb(payload, raw=True, strict_map_key=True, max_array_len=8,
                              max_map_len=0, max_str_len=0, max_bin_len=0, max_ext_len=0)
    except Exception:
        return "malformed"
    if not isinstance(obj, list) or len(obj) != 6:
        return "malformed"
    v, sender, seq, t, w, wd = obj
    if type(v) is not int or v != OMEGA_VERSION:
        return "version"
    if type(sender) is not int or type(seq) is not int:
        return "type"
    if not all(type(x) is float for x in (t, w, wd)):
        return "type"
    if not (math.isfinite(t) and math.isfinite(w) and math.isfinite(wd)):
        return "non_finite"
    if seq < 0 or sender < 0 or (n_vehicles is not None and sender >= n_vehicles):
        return "unknown_sender"
    if expected_sender is not None and sender != expected_sender:
        return "unknown_sender"
    return OmegaMsg(sender, seq, t, w, wd)

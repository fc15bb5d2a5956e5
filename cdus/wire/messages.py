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
    wd = float(m.omega_rate)
    if math.isfinite(wd):  # a non-finite rate must stay so, for the receiver to reject it
        wd = max(-F32_MAX, min(F32_MAX, wd))
    return b"".join((
        b"\x96",
        _pack(OMEGA_VERSION), _pack(m.sender), _pack(m.seq),
        _pack(float(m.t_send)), _pack(float(m.omega)),
        msgpack.packb(wd, use_single_float=True),
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


# --------------------------------------------------------------------------- telemetry

STATE_VERSION = 1


@dataclass(frozen=True)
class StateMsg:
    """A vehicle's telemetry at control tick ``tick`` (after the controller's update).

    In lockstep it doubles as the acknowledgement of that tick.
    """

    sender: int
    tick: int
    t: float
    q: tuple[float, ...]
    heading: float
    speed: float
    omega: float
    omega_rate: float
    path_error: float


MAX_STATE_ROWS = 64


def encode_states(rows: list[StateMsg]) -> bytes:
    """A batch of one sender's telemetry rows: [version, sender, [[tick, t, q, ψ, |v|, ω, ω̇, |Φ|], ...]]."""
    return _pack([STATE_VERSION, rows[0].sender,
                  [[m.tick, m.t, list(m.q), m.heading, m.speed, m.omega, m.omega_rate, m.path_error] for m in rows]])


def decode_states(payload: bytes, n_vehicles: int | None = None) -> list[StateMsg] | str:
    """The rows of a telemetry batch, or the reason it was rejected (the whole batch is)."""
    if len(payload) > 96 * MAX_STATE_ROWS:
        return "oversized"
    try:
        obj = msgpack.unpackb(payload, raw=True, max_array_len=MAX_STATE_ROWS, max_map_len=0, max_str_len=0,
                              max_bin_len=0, max_ext_len=0)
    except Exception:
        return "malformed"
    if not isinstance(obj, list) or len(obj) != 3:
        return "malformed"
    v, sender, rows = obj
    if type(v) is not int or v != STATE_VERSION:
        return "version"
    if type(sender) is not int or not isinstance(rows, list) or not rows:
        return "type"
    if sender < 0 or (n_vehicles is not None and sender >= n_vehicles):
        return "unknown_sender"
    out = []
    for row in rows:
        if not isinstance(row, list) or len(row) != 8:
            return "malformed"
        tick, t, q, heading, speed, w, wd, pe = row
        if type(tick) is not int or tick < 0 or not isinstance(q, list) or len(q) not in (2, 3):
            return "type"
        floats = (t, heading, speed, w, wd, pe, *q)
        if not all(type(x) is float for x in floats):
            return "type"
        if not all(math.isfinite(x) for x in floats):
            return "non_finite"
        out.append(StateMsg(sender, tick, t, tuple(q), heading, speed, w, wd, pe))
    return out


# --------------------------------------------------------------------------- control maps

CONTROL_VERSION = 1
MAX_CONTROL_PAYLOAD = 4096

#: clock ops and the fields each carries (name -> type)
CLOCK_OPS: dict[str, dict[str, type]] = {
    "start": {"t0": float},  # realtime: tick 0 is at wall time t0 (time.time())
    "grant": {"until": int, "front": int},  # lockstep: step ticks <= until; a late joiner starts at front
    "stop": {},  # end of run: finish, report, exit
}

#: command ops and their fields; ``link`` and ``gains`` carry tables checked by their owners
COMMAND_OPS: dict[str, dict[str, type]] = {
    "pause": {},
    "resume": {},
    "stop": {},
    "set_gains": {"gains": dict},
    "link": {"link": dict, "at": float},  # a [link] table merged over the current one, from sim time `at`
    # scheduled vehicle faults: world -> launcher, and the launcher's acknowledgement
    "kill": {"vehicle": str},
    "pause_vehicle": {"vehicle": str},
    "resume_vehicle": {"vehicle": str},
    "restart": {"vehicle": str},
    "fault_done": {"vehicle": str},
}


@dataclass(frozen=True)
class Control:
    """A clock tick or a command: an op and its checked fields."""

    op: str
    fields: dict


def encode_control(op: str, **fields) -> bytes:
    return msgpack.packb({"v": CONTROL_VERSION, "op": op, **fields}, use_bin_type=True)


def decode_control(payload: bytes, ops: dict[str, dict[str, type]]) -> Control | str:
    """Decode a clock or command map against ``ops`` (CLOCK_OPS or COMMAND_OPS)."""
    if len(payload) > MAX_CONTROL_PAYLOAD:
        return "oversized"
    try:
        obj = msgpack.unpackb(payload, raw=False, max_array_len=64, max_map_len=64, max_str_len=256,
                              max_bin_len=0, max_ext_len=0)
    except Exception:
        return "malformed"
    if not isinstance(obj, dict) or obj.get("v") != CONTROL_VERSION or type(obj.get("v")) is not int:
        return "version" if isinstance(obj, dict) else "malformed"
    op = obj.get("op")
    if not isinstance(op, str) or op not in ops:
        return "unknown_op"
    out = {}
    for name, typ in ops[op].items():
        val = obj.get(name)
        if typ is float and type(val) is int:
            val = float(val)
        if type(val) is not typ:
            return "type"
        if typ is float and not math.isfinite(val):
            return "non_finite"
        out[name] = val
    return Control(op, out)

"""What goes over the radio and the fleet's wires: ω, telemetry and control messages.

The one source of truth for these schemas; every process imports it.

ω (msgpack, a 6-element array, at most 32 bytes for fleets of up to 256 vehicles):

    [version=1, sender index, seq, t_send (float64 s), ω (float64), ω̇ (float32)]

written with fixed widths (sender uint8, or uint16 past 256 vehicles; seq uint32), so
it is valid msgpack that the receive path reads with one ``struct`` call; any other
msgpack spelling of the same array is read too, and checked alike. ω is float64 on the
wire and everywhere else: it is unbounded (it decreases at 1/s forever) and a narrow
type would ruin it (docs/control.md). The sender's id travels in the key
(``.../omega/<id>``); the index inside the payload must agree with it. Decoders never
raise: they return a message or :class:`cdus.wire.rejected.Rejected` with the reason, so a
receiver can count and drop without a try/except in its loop (``decode_control`` still
returns the reason as a string).
"""

from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass
from typing import Any, Sequence

import msgpack

from cdus.wire.bounds import BOUNDS, finite
from cdus.wire.rejected import Rejected

OMEGA_VERSION = 1
MAX_OMEGA_PAYLOAD = 33  # 32 up to 256 vehicles (uint8 sender), 33 beyond (uint16)
F32_MAX = 3.0e38  # ω̇ is clamped to the float32 range on the wire
#: what msgpack raises on bytes that are not what we accept (malformed, too deep, too long, ...)
MSGPACK_ERRORS = (ValueError, TypeError, msgpack.UnpackException)
_OMEGA8 = struct.Struct(">BBBBBIBdBdBf")  # 0x96, 1, 0xcc, sender, 0xce, seq, 0xcb, t, 0xcb, ω, 0xca, ω̇
_OMEGA16 = struct.Struct(">BBBHBIBdBdBf")  # the same with 0xcd and a uint16 sender


@dataclass(frozen=True)
class OmegaMsg:
    sender: int  # index of the sender in the scenario's vehicle list
    seq: int  # per-sender sequence number: tick // broadcast period, strictly increasing
    t_send: float  # simulated seconds at the sender (every clock mode)
    omega: float
    omega_rate: float  # mean ω̇ over the sender's last control period


def encode_omega(m: OmegaMsg) -> bytes:
    """The payload of ``m`` (fixed widths; ω̇ packed as float32: a rate near -1 that is only
    used to extrapolate; everything else exact)."""
    wd = float(m.omega_rate)
    if math.isfinite(wd):  # a non-finite rate must stay so, for the receiver to reject it
        wd = max(-F32_MAX, min(F32_MAX, wd))
    if not 0 <= m.seq < 2**32 or not 0 <= m.sender < 2**16:  # out of the fixed layout: plain msgpack
        return _pack([OMEGA_VERSION, m.sender, m.seq, float(m.t_send), float(m.omega), wd])
    if m.sender < 256:
        return _OMEGA8.pack(0x96, OMEGA_VERSION, 0xcc, m.sender, 0xce, m.seq, 0xcb, m.t_send, 0xcb, m.omega, 0xca, wd)
    return _OMEGA16.pack(0x96, OMEGA_VERSION, 0xcd, m.sender, 0xce, m.seq, 0xcb, m.t_send, 0xcb, m.omega, 0xca, wd)


def decode_omega(payload: bytes, expected_sender: int | None = None, n_vehicles: int | None = None
                 ) -> OmegaMsg | Rejected:
    """A valid message, or Rejected with a short reason (``malformed``, ``version``, ...)."""
    size = len(payload)
    if size == 32 and payload[2] == 0xcc and payload[4] == 0xce and payload[:2] == b"\x96\x01":
        _, _, _, sender, _, seq, m1, t, m2, w, m3, wd = _OMEGA8.unpack(payload)
    elif size == 33 and payload[2] == 0xcd and payload[5] == 0xce and payload[:2] == b"\x96\x01":
        _, _, _, sender, _, seq, m1, t, m2, w, m3, wd = _OMEGA16.unpack(payload)
    else:
        return _decode_omega_any(payload, expected_sender, n_vehicles)
    if m1 != 0xcb or m2 != 0xcb or m3 != 0xca:
        return _decode_omega_any(payload, expected_sender, n_vehicles)
    return _checked(sender, seq, t, w, wd, expected_sender, n_vehicles)


def _decode_omega_any(payload: bytes, expected_sender: int | None, n_vehicles: int | None) -> OmegaMsg | Rejected:
    """Any msgpack spelling of the ω array (the slow path)."""
    if len(payload) > MAX_OMEGA_PAYLOAD:
        return Rejected("oversized")
    try:
        obj = msgpack.unpackb(payload, raw=True, strict_map_key=True, max_array_len=8,
                              max_map_len=0, max_str_len=0, max_bin_len=0, max_ext_len=0)
    except MSGPACK_ERRORS:
        return Rejected("malformed")
    if not isinstance(obj, list) or len(obj) != 6:
        return Rejected("malformed")
    v, sender, seq, t, w, wd = obj
    if type(v) is not int or v != OMEGA_VERSION:
        return Rejected("version")
    if type(sender) is not int or type(seq) is not int:
        return Rejected("type")
    if not all(type(x) is float for x in (t, w, wd)):
        return Rejected("type")
    return _checked(sender, seq, t, w, wd, expected_sender, n_vehicles)


def _checked(sender: int, seq: int, t: float, w: float, wd: float, expected_sender: int | None,
             n_vehicles: int | None) -> OmegaMsg | Rejected:
    if not (math.isfinite(t) and math.isfinite(w) and math.isfinite(wd)):
        return Rejected("non_finite")
    if seq < 0 or sender < 0 or (n_vehicles is not None and sender >= n_vehicles):
        return Rejected("unknown_sender")
    if expected_sender is not None and sender != expected_sender:
        return Rejected("unknown_sender")
    return OmegaMsg(sender, seq, t, w, wd)


_pack = msgpack.Packer(use_single_float=False, autoreset=True).pack


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


def _versioned_triple(payload: bytes, max_bytes: int, max_rows: int, version: int) -> tuple[Any, Any] | Rejected:
    """The (head, rows) of a ``[version, head, rows]`` msgpack array of numbers only, or the
    reason it is rejected (``oversized``, ``malformed``, ``version``); never raises."""
    if len(payload) > max_bytes:
        return Rejected("oversized")
    try:
        obj = msgpack.unpackb(payload, raw=True, max_array_len=max_rows, max_map_len=0, max_str_len=0,
                              max_bin_len=0, max_ext_len=0)
    except MSGPACK_ERRORS:
        return Rejected("malformed")
    if not isinstance(obj, list) or len(obj) != 3:
        return Rejected("malformed")
    v, head, rows = obj
    if type(v) is not int or v != version:
        return Rejected("version")
    return head, rows


def decode_states(payload: bytes, n_vehicles: int | None = None) -> list[StateMsg] | Rejected:
    """The rows of a telemetry batch, or the reason it was rejected (the whole batch is)."""
    obj = _versioned_triple(payload, 96 * MAX_STATE_ROWS, MAX_STATE_ROWS, STATE_VERSION)
    if isinstance(obj, Rejected):
        return obj
    sender, rows = obj
    if type(sender) is not int or not isinstance(rows, list) or not rows:
        return Rejected("type")
    if sender < 0 or (n_vehicles is not None and sender >= n_vehicles):
        return Rejected("unknown_sender")
    out = []
    for row in rows:
        if not isinstance(row, list) or len(row) != 8:
            return Rejected("malformed")
        tick, t, q, heading, speed, w, wd, pe = row
        if type(tick) is not int or tick < 0 or not isinstance(q, list) or len(q) not in (2, 3):
            return Rejected("type")
        floats = (t, heading, speed, w, wd, pe, *q)
        if not all(type(x) is float for x in floats):
            return Rejected("type")
        if not all(math.isfinite(x) for x in floats):
            return Rejected("non_finite")
        out.append(StateMsg(sender, tick, t, tuple(q), heading, speed, w, wd, pe))
    return out


# --------------------------------------------------------------------------- proximity contacts

CONTACTS_VERSION = 1
MAX_CONTACTS = 256


@dataclass(frozen=True)
class ContactsMsg:
    """What the world's proximity sensor saw around one vehicle at control tick ``tick``:
    per contact the other vehicle's index, the share of the pair constraint this vehicle
    takes (cdus.core.safety.Contact) and its position (2 or 3 coordinates)."""

    tick: int
    contacts: tuple[tuple[int, float, tuple[float, ...]], ...]


def encode_contacts(m: ContactsMsg) -> bytes:
    """[version, tick, [[index, share, [x, y(, z)]], ...]] in msgpack, every float as float64."""
    return _pack([CONTACTS_VERSION, m.tick, [[k, float(w), [float(x) for x in q]] for k, w, q in m.contacts]])


def decode_contacts(payload: bytes, n_vehicles: int | None = None, receiver: int | None = None,
                    dim: int | None = None) -> ContactsMsg | Rejected:
    """A valid contacts message, or the reason it is rejected (``malformed``, ``version``,
    ``type``, ``non_finite``, ``share``, ``unknown_sender``, ``oversized``, and given the
    receiving vehicle's index and dimension: ``self`` (a contact that is the receiver itself),
    ``duplicate`` (one vehicle listed twice), ``dimension`` (a position the receiver's filter
    cannot take: a USV is sent 2 coordinates, a UAV 3)); never raises."""
    obj = _versioned_triple(payload, 48 * MAX_CONTACTS + 16, MAX_CONTACTS, CONTACTS_VERSION)
    if isinstance(obj, Rejected):
        return obj
    tick, rows = obj
    if type(tick) is not int or tick < 0 or not isinstance(rows, list):
        return Rejected("type")
    out = []
    for row in rows:
        if not isinstance(row, list) or len(row) != 3:
            return Rejected("malformed")
        k, w, q = row
        if type(k) is not int or type(w) is not float or not isinstance(q, list) or len(q) not in (2, 3) \
                or not all(type(x) is float for x in q):
            return Rejected("type")
        if not (math.isfinite(w) and all(math.isfinite(x) for x in q)):
            return Rejected("non_finite")
        if not 0.0 < w <= 1.0:
            return Rejected("share")
        if k < 0 or (n_vehicles is not None and k >= n_vehicles):
            return Rejected("unknown_sender")
        if dim is not None and len(q) != dim:
            return Rejected("dimension")
        out.append((k, w, tuple(q)))
    if receiver is not None and any(k == receiver for k, _, _ in out):
        return Rejected("self")
    if len({k for k, _, _ in out}) != len(out):
        return Rejected("duplicate")
    return ContactsMsg(tick, tuple(out))


# --------------------------------------------------------------------------- radio geometry

GEOMETRY_VERSION = 1
MAX_GEOMETRY_VEHICLES = 4096
MAX_COORDINATE = 1.0e7  # m: a position further out than this is not a vehicle's (10,000 km)


@dataclass(frozen=True)
class GeometryMsg:
    """The world's radio geometry sample (docs/radio.md, "Integration"): every vehicle's
    position at control tick ``tick``, indexed like the scenario's vehicles; None for a
    vehicle that did not step that tick (not live). 2D vehicles are sent 2 coordinates."""

    tick: int
    positions: tuple[tuple[float, ...] | None, ...]


def encode_geometry(m: GeometryMsg) -> bytes:
    """[version, tick, [[x, y(, z)] | nil, ...]] in msgpack, every float as float64."""
    return _pack([GEOMETRY_VERSION, m.tick, [None if q is None else [float(x) for x in q] for q in m.positions]])


def decode_geometry(payload: bytes, n_vehicles: int | None = None,
                    dims: Sequence[int] | None = None) -> GeometryMsg | Rejected:
    """A valid geometry sample, or the reason it is rejected (``oversized``, ``malformed``,
    ``version``, ``type``, ``non_finite``, ``range`` (a coordinate beyond
    :data:`MAX_COORDINATE`), ``count`` (not one entry per vehicle of the fleet), and given every
    vehicle's dimension: ``dimension`` (a boat not sent 2 coordinates, a drone not 3: the world
    sends each its own)); never raises."""
    obj = _versioned_triple(payload, 30 * MAX_GEOMETRY_VEHICLES + 32, MAX_GEOMETRY_VEHICLES, GEOMETRY_VERSION)
    if isinstance(obj, Rejected):
        return obj
    tick, rows = obj
    if type(tick) is not int or tick < 0 or not isinstance(rows, list):
        return Rejected("type")
    out: list[tuple[float, ...] | None] = []
    for q in rows:
        if q is None:
            out.append(None)
            continue
        if not isinstance(q, list) or len(q) not in (2, 3) or not all(type(x) is float for x in q):
            return Rejected("type")
        if not all(math.isfinite(x) for x in q):
            return Rejected("non_finite")
        if not all(abs(x) <= MAX_COORDINATE for x in q):
            return Rejected("range")
        out.append(tuple(q))
    if n_vehicles is not None and len(out) != n_vehicles:
        return Rejected("count")
    if dims is not None and (len(dims) != len(out) or any(q is not None and len(q) != d for q, d in zip(out, dims))):
        return Rejected("dimension" if len(dims) == len(out) else "count")
    return GeometryMsg(tick, tuple(out))


# --------------------------------------------------------------------------- control maps

CONTROL_VERSION = 1
MAX_CONTROL_PAYLOAD = 4096
MAX_LINK_AT = BOUNDS["link.at"].hi  # s: a link change's latest time (the agents refuse a later one; past the run's end it never applies)

#: world -> vehicles (``ctl``), per op the fields it carries (name -> type)
CTL_OPS: dict[str, dict[str, type]] = {
    "start": {"t0": float},  # realtime: tick 0 is at wall time t0 (time.time())
    "join": {"tick": int},  # lockstep: the run starts (tick 0) or a (re)started process joins at tick
    "grant": {"until": int},  # lockstep: step ticks <= until
    "roster": {"vehicle": str, "tick": int, "state": str, "fresh": bool},  # cdus.core.events.RosterChange
    "pause": {},  # realtime: stop stepping until resume
    "resume": {"t0": float},  # realtime: carry on, the clock's origin moved by the pause
    "link": {"link": dict, "at": float},  # a [link] table merged over the current one, from sim time `at`
    "gains": {"gains": dict, "tick": int},  # k and/or c from tick `tick`
    "formation": {"phases": dict, "tick": int},  # {id: θ} (ω units) from tick `tick`; others keep theirs
    "path": {"vehicle": str, "path": dict, "tick": int},  # a path table for `vehicle` from tick `tick`
    "radio": {"radio": dict, "at": float},  # radio changes (tx_power, station) for messages sent from `at`
    "stop": {},  # end of run: finish, report, exit
}

#: the world's run-time commands to the vehicles (``ctl``) may carry ``seq``: their number in the
#: world's list of commands (an int >= 0). A process that hears one again (the commands are
#: replayed to a rejoining or resumed process, and said again if it stays silent) applies it once.
SEQUENCED = ("link", "gains", "formation", "path", "radio")
MAX_SEQ = 2**53

#: anyone -> the world (``to/+world+/cmd/<from>``); each op is a command of cdus.commands (its parse
#: checks the tables: cdus.commands.parse.decode_command gives the typed command or Rejected)
COMMAND_OPS: dict[str, dict[str, type]] = {
    "pause": {},
    "resume": {},
    "stop": {},
    "gains": {"gains": dict, "vehicle": str},  # vehicle "" = every vehicle (cdus.commands.gains)
    "set_gains": {"gains": dict, "vehicle": str},  # its older spelling: a ground station of 0.x before the commands room
    "link": {"link": dict, "at": float},  # at < 0: as soon as possible
    # phases {id: θ} or offsets [{i, k, delta}, ...] (exactly one non-empty); from the next tick the world can
    "formation": {"phases": dict, "offsets": list},
    "path": {"vehicle": str, "path": dict},  # a path table like the config's, for one vehicle
    "radio": {"radio": dict, "at": float},  # {tx_power, station}; at < 0: as soon as possible
    "kill": {"vehicle": str},
    "pause_vehicle": {"vehicle": str},
    "resume_vehicle": {"vehicle": str},
    "restart": {"vehicle": str},
    "fault_done": {"vehicle": str},  # the launcher: a vehicle fault carried out
}

#: the world -> the launcher: carry out a vehicle fault
LAUNCHER_OPS: dict[str, dict[str, type]] = {
    "kill": {"vehicle": str},
    "pause_vehicle": {"vehicle": str},
    "resume_vehicle": {"vehicle": str},
    "restart": {"vehicle": str},
}
VEHICLE_FAULTS = tuple(LAUNCHER_OPS)


@dataclass(frozen=True)
class Control:
    """A clock tick or a command: an op and its checked fields."""

    op: str
    fields: dict
    #: a ground station's own name (optional ``name`` of a command: several ground stations share
    #: the ``gs`` key, the world's event log names each); None when not given
    name: str | None = None


_NAME_RE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")


def encode_control(op: str, **fields) -> bytes:
    return msgpack.packb({"v": CONTROL_VERSION, "op": op, **fields}, use_bin_type=True)


def decode_control(payload: bytes, ops: dict[str, dict[str, type]]) -> Control | Rejected:
    """Decode a control map against ``ops`` (CTL_OPS, COMMAND_OPS or LAUNCHER_OPS): the Control,
    or Rejected(reason): oversized, malformed, version, unknown_op, type, non_finite, seq, name."""
    if len(payload) > MAX_CONTROL_PAYLOAD:
        return Rejected("oversized")
    try:
        obj = msgpack.unpackb(payload, raw=False, max_array_len=64, max_map_len=64, max_str_len=256,
                              max_bin_len=0, max_ext_len=0)
    except MSGPACK_ERRORS:
        return Rejected("malformed")
    if not isinstance(obj, dict) or obj.get("v") != CONTROL_VERSION or type(obj.get("v")) is not int:
        return Rejected("version" if isinstance(obj, dict) else "malformed")
    op = obj.get("op")
    if not isinstance(op, str) or op not in ops:
        return Rejected("unknown_op")
    out = {}
    for name, typ in ops[op].items():
        val = obj.get(name)
        if typ is float and type(val) is int:
            val = float(val)
        if type(val) is not typ:
            return Rejected("type")
        if typ is float and not finite(val):
            return Rejected("non_finite")
        out[name] = val
    if ops is CTL_OPS and op in SEQUENCED and "seq" in obj:
        seq = obj["seq"]
        if type(seq) is not int or not 0 <= seq < MAX_SEQ:
            return Rejected("seq")
        out["seq"] = seq
    who = obj.get("name")
    if who is not None and (not isinstance(who, str) or not _NAME_RE.match(who)):
        return Rejected("name")
    return Control(op, out, who)

"""The ground station: the operator's console, as the paper's base station.

It attaches to a running fleet at any time (a Zenoh client of the fleet's router),
watches it (vehicle telemetry, liveliness, the world's status and events) and sends
commands to the world, which relays them to the vehicles with the tick (or simulated
time) they apply from: pause/resume/stop the fleet, change link faults or gains at run
time, kill, pause, resume or restart a vehicle (the launcher carries those out).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from cdus.wire import keys
from cdus.wire.transport import Transport, open_session
from cdus.wire.messages import VEHICLE_FAULTS, StateMsg, decode_states, encode_control
from cdus.wire.schemas import FleetEvent, decode_event, decode_status
from cdus.wire.text import printable

MAX_NAMES = 10_000  # vehicles (telemetry, liveliness) the console tracks: names beyond are forged
MAX_EVENTS = 1000  # events the console keeps (it shows the newest 8)
BIG = 1e9  # numbers beyond this are shown in scientific notation, not as hundreds of digits


def num(x: Any, spec: str = ".3f", none: str = "-") -> str:
    """A number from the wire as text: a finite one formatted by ``spec`` (or as ``%.3g`` when
    huge), ``nan``/``inf`` as they are, anything else (a string, a list) escaped and marked ``?``."""
    if x is None:
        return none
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return "?" + printable(repr(x), 24)
    if not math.isfinite(x):
        return str(float(x))
    return format(x, spec) if abs(x) < BIG else f"{x:.3g}"


def _text(x: Any, limit: int = 64) -> str:
    return printable(x if isinstance(x, str) else repr(x), limit)


@dataclass
class FleetView:
    """What the console knows, updated from Zenoh's threads under one lock."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    states: dict[str, StateMsg] = field(default_factory=dict)
    alive: set[str] = field(default_factory=set)
    world: dict | None = None
    events: list[FleetEvent] = field(default_factory=list)
    rejected: int = 0


def status_table(view: FleetView, now: float | None = None) -> str:
    """A plain-text table of the fleet: one row per vehicle seen, then the world's line. Every
    string that came over the wire is escaped (cdus.wire.text.printable), every number that is
    not a finite one is shown as what it is."""
    with view.lock:
        w = view.world
        known = (w or {}).get("ids")
        known = [k for k in known if isinstance(k, str)] if isinstance(known, list) else []
        ids = sorted(set(view.states) | (view.alive - {keys.WORLD}) | set(known))
        rows = [f"{'vehicle':<10} {'alive':<5} {'t (s)':>8} {'|Φ| (m)':>9} {'ω':>11} {'ω̇':>8}  position"]
        for vid in ids:
            m = view.states.get(vid)
            alive = "yes" if vid in view.alive else "NO"
            name = _text(vid, 32)
            if m is None:
                rows.append(f"{name:<10} {alive:<5} {'-':>8}")
                continue
            pos = ", ".join(num(x, ".1f") for x in m.q)
            rows.append(f"{name:<10} {alive:<5} {num(m.t, '.2f'):>8} {num(m.path_error):>9} {num(m.omega):>11} "
                        f"{num(m.omega_rate):>8}  ({pos})")
        if w:
            coord = w.get("coord_error_max")
            path = w.get("path_error_max")
            paused = ", PAUSED" if w.get("paused") else ""
            alive_n = len(w["alive"]) if isinstance(w.get("alive"), list) else "?"
            rows.append(f"world: t = {num(w.get('t', 0), '.1f')} / {num(w.get('duration', 0), '.0f')} s "
                        f"({_text(w.get('clock'), 16)}{paused}), {alive_n}/{len(known)} vehicles alive, worst |Φ| "
                        f"{num(path)} m, worst edge error {num(coord, '.4f')} rad")
        else:
            rows.append("world: no status yet")
        events = view.events or (w or {}).get("events") or []  # heard live, else the world's recent ones
        events = [e for e in events if isinstance(e, FleetEvent)]
        if events:
            rows.append("events:")
            # the newest 8, drop bursts only where nothing else is left to show (a lossy link makes thousands)
            others = [e for e in events if e.kind != "link_burst"]
            bursts = len(events) - len(others)
            room = max(0, 8 - len(others))
            burst_list = [e for e in events if e.kind == "link_burst"]
            shown = others[-8:] + (burst_list[len(burst_list) - room:] if room else [])
            shown.sort(key=lambda e: e.t)
            rows += [f"  t = {num(e.t, '.2f')} s: {_text(e.text, 300)}"
                     + ("  [" + _text(e.severity.upper(), 8) + "]" if e.severity != "info" else "")
                     for e in shown[-8:]]
            if bursts > room:
                rows.append(f"  ({bursts} drop bursts heard; the newest shown only where room is left)")
        if view.rejected:
            rows.append(f"({view.rejected} malformed messages ignored)")
    return "\n".join(rows)


class GroundStation:
    def __init__(self, fleet: str, transport: Transport):
        self.fleet = keys.check_fleet(fleet)
        self.transport = transport
        self.view = FleetView()
        self.session = None

    def open(self, watch: bool = True) -> None:
        s = self.session = open_session(self.transport)
        f = self.fleet
        self._subs = []
        if watch:
            self._subs += [
                s.declare_subscriber(keys.any_state(f), self._on_state),
                s.declare_subscriber(keys.world_status(f), self._on_status),
                s.declare_subscriber(keys.world_events(f), self._on_event),
                s.liveliness().declare_subscriber(keys.any_alive(f), self._on_alive, history=True),
            ]

    def close(self) -> None:
        if self.session is not None:
            self.session.close()
            self.session = None

    # ------------------------------------------------------------------ watching
    def _on_state(self, sample: Any) -> None:
        rows = decode_states(sample.payload.to_bytes())
        _, vid = keys.leaf(str(sample.key_expr))
        with self.view.lock:
            if (isinstance(rows, str) or vid is None or not keys.FLEET_RE.match(vid)
                    or vid not in self.view.states and len(self.view.states) >= MAX_NAMES):
                self.view.rejected += 1
                return
            self.view.states[vid] = rows[-1]

    def _on_status(self, sample: Any) -> None:
        st = decode_status(sample.payload.to_bytes())
        with self.view.lock:
            if isinstance(st, str):
                self.view.rejected += 1
            else:
                self.view.world = st

    def _on_event(self, sample: Any) -> None:
        e = decode_event(sample.payload.to_bytes())
        with self.view.lock:
            if isinstance(e, str):
                self.view.rejected += 1
            else:
                self.view.events.append(e)
                del self.view.events[:-MAX_EVENTS]  # a flood of events cannot grow the console without bound

    def _on_alive(self, sample: Any) -> None:
        who = keys.alive_name(str(sample.key_expr))
        with self.view.lock:
            if str(sample.kind).endswith("DELETE"):
                self.view.alive.discard(who)
            elif who and keys.FLEET_RE.match(who) and len(self.view.alive) < MAX_NAMES:
                self.view.alive.add(who)
            else:
                self.view.rejected += 1

    def wait_for_status(self, timeout: float) -> bool:
        """Wait until the world's status has been heard (it is published about once a second)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.view.lock:
                if self.view.world is not None:
                    return True
            time.sleep(0.05)
        return False

    def sim_time(self) -> float | None:
        """The world's simulated time, None before its status or if it is not a finite number."""
        with self.view.lock:
            t = None if self.view.world is None else self.view.world.get("t")
        return float(t) if isinstance(t, (int, float)) and not isinstance(t, bool) and math.isfinite(t) else None

    # ------------------------------------------------------------------ commanding
    def send(self, op: str, **fields: Any) -> None:
        """A command to the world (cdus.wire.messages.COMMAND_OPS)."""
        self.session.put(keys.world_cmd(self.fleet, keys.GROUND), encode_control(op, **fields))

    def fleet_command(self, op: str) -> None:
        """pause | resume | stop the whole fleet."""
        self.send(op)

    def set_link(self, table: dict, at: float | None = None) -> None:
        """Change the link faults from simulated time ``at`` (default: as soon as the world can,
        a moment after its present)."""
        if at is not None and not (math.isfinite(at) and at >= 0):
            raise ValueError("at must be a finite time >= 0 s")
        self.send("link", link=table, at=-1.0 if at is None else float(at))

    def set_radio(self, change: dict, at: float | None = None) -> None:
        """Change the radio (``{"tx_power": dBm, "station": [x, y, z]}``) from simulated time ``at``
        (default: as soon as the world can)."""
        if at is not None and not (math.isfinite(at) and at >= 0):
            raise ValueError("at must be a finite time >= 0 s")
        self.send("radio", radio=change, at=-1.0 if at is None else float(at))

    def set_gains(self, gains: dict, vehicle: str | None = None) -> None:
        self.send("set_gains", gains=gains, vehicle=vehicle or "")

    def vehicle_fault(self, action: str, vehicle: str) -> None:
        """kill | pause | resume | restart one vehicle's process (the launcher carries it out)."""
        op = {"pause": "pause_vehicle", "resume": "resume_vehicle"}.get(action, action)
        if op not in VEHICLE_FAULTS:
            raise ValueError(f"unknown vehicle fault {action!r}")
        self.send(op, vehicle=vehicle)

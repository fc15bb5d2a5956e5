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
    """A plain-text table of the fleet: one row per vehicle seen, then the world's line."""
    with view.lock:
        known = (view.world or {}).get("ids") or []
        ids = sorted(set(view.states) | (view.alive - {keys.WORLD}) | set(known))
        rows = [f"{'vehicle':<10} {'alive':<5} {'t (s)':>8} {'|Φ| (m)':>9} {'ω':>11} {'ω̇':>8}  position"]
        for vid in ids:
            m = view.states.get(vid)
            alive = "yes" if vid in view.alive else "NO"
            if m is None:
                rows.append(f"{vid:<10} {alive:<5} {'-':>8}")
                continue
            pos = ", ".join(f"{x:.1f}" for x in m.q)
            rows.append(f"{vid:<10} {alive:<5} {m.t:8.2f} {m.path_error:9.3f} {m.omega:11.3f} "
                        f"{m.omega_rate:8.3f}  ({pos})")
        w = view.world
        if w:
            coord = w.get("coord_error_max")
            path = w.get("path_error_max")
            paused = ", PAUSED" if w.get("paused") else ""
            rows.append(f"world: t = {w.get('t', 0):.1f} / {w.get('duration', 0):.0f} s ({w.get('clock')}{paused}), "
                        f"{len(w.get('alive', []))}/{len(w.get('ids') or [])} vehicles alive, worst |Φ| "
                        f"{'-' if path is None else f'{path:.3f}'} m, worst edge error "
                        f"{'-' if coord is None else f'{coord:.4f}'} rad")
        else:
            rows.append("world: no status yet")
        events = view.events or (w or {}).get("events") or []  # heard live, else the world's recent ones
        if events:
            rows.append("events:")
            # the newest 8, drop bursts only where nothing else is left to show (a lossy link makes thousands)
            others = [e for e in events if e.kind != "link_burst"]
            bursts = len(events) - len(others)
            room = max(0, 8 - len(others))
            burst_list = [e for e in events if e.kind == "link_burst"]
            shown = others[-8:] + (burst_list[len(burst_list) - room:] if room else [])
            shown.sort(key=lambda e: e.t)
            rows += [f"  {e.line()}" + ("  [" + e.severity.upper() + "]" if e.severity != "info" else "")
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
            if isinstance(rows, str) or vid is None:
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

    def _on_alive(self, sample: Any) -> None:
        who = keys.alive_name(str(sample.key_expr))
        with self.view.lock:
            if str(sample.kind).endswith("DELETE"):
                self.view.alive.discard(who)
            else:
                self.view.alive.add(who)

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
        with self.view.lock:
            return None if self.view.world is None else float(self.view.world.get("t", 0.0))

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

    def set_gains(self, gains: dict, vehicle: str | None = None) -> None:
        self.send("set_gains", gains=gains, vehicle=vehicle or "")

    def vehicle_fault(self, action: str, vehicle: str) -> None:
        """kill | pause | resume | restart one vehicle's process (the launcher carries it out)."""
        op = {"pause": "pause_vehicle", "resume": "resume_vehicle"}.get(action, action)
        if op not in VEHICLE_FAULTS:
            raise ValueError(f"unknown vehicle fault {action!r}")
        self.send(op, vehicle=vehicle)

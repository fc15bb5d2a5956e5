"""What does the ground station hear from a fleet, and what can it tell it? The operator's console,
as the paper's base station.

It attaches to a running fleet at any time (a Zenoh client of the fleet's router),
watches it (vehicle telemetry, liveliness, the world's status and events) and sends
commands to the world, which relays them to the vehicles with the tick (or simulated
time) they apply from: pause/resume/stop the fleet, change link faults or gains at run
time, kill, pause, resume or restart a vehicle (the launcher carries those out).
"""

from __future__ import annotations

import json
import os
import re
import socket
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import zenoh

from cdus.wire import keys
from cdus.wire.access import GROUND_ROLE, ROS2_ROLE
from cdus.wire.bounds import finite, is_number
from cdus.wire.transport import Transport, endpoint_host, open_session
from cdus.wire.rejected import Rejected
from cdus.wire.messages import StateMsg, decode_states, encode_control
from cdus.wire.schemas import CommandReply, FleetEvent, decode_event, decode_reply, decode_settings, decode_status
from cdus.wire.status import WorldStatus
from cdus.sim.reports import LINK_GROUP_S, group_link_states  # noqa: F401 (LINK_GROUP_S: the console's too)
from cdus.wire.text import printable

#: exit codes of `cdus gs` (docs/ground_station.md)
EXIT_APPLIED, EXIT_REJECTED, EXIT_USAGE, EXIT_NO_ANSWER, EXIT_DENIED = 0, 1, 2, 3, 4
COMMAND_TIMEOUT = 10.0  # s a ground station waits for the world's answer (a restart under way delays a fault)
SNAPSHOT_VERSION = 1  # the JSON of `gs status --json`, `gs watch --jsonl`, `gs snapshot`
MAX_NAMES = 10_000  # vehicles (telemetry, liveliness) the console tracks: names beyond are forged
MAX_EVENTS = 1000  # events the console keeps (it shows the newest 8)
#: replies to a command are not consolidated (Zenoh keeps one per key by default, so a forged
#: one could hide the world's): every one is read
_ALL_REPLIES = zenoh.ConsolidationMode.NONE
WORLD_LEFT_WAIT = 1.0  # s: a query that ended with no reply waits this long for news of the world leaving
BIG = 1e9  # numbers beyond this are shown in scientific notation, not as hundreds of digits


def num(x: Any, spec: str = ".3f", none: str = "-") -> str:
    """A number from the wire as text: a finite one formatted by ``spec`` (or as ``%.3g`` when
    huge), ``nan``/``inf`` as they are, anything else (a string, a list) escaped and marked ``?``."""
    if x is None:
        return none
    if not is_number(x):
        return "?" + printable(repr(x), 24)
    if not finite(x):
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
    tokens: dict[str, set[str]] = field(default_factory=dict)  # name -> session ids of its tokens (keys.hold_token)
    world: WorldStatus | None = None  # the newest status, as decode_status checked it (replaced whole)
    events: list[FleetEvent] = field(default_factory=list)
    rejected: int = 0
    events_seen: int = 0  # events heard in all (``events`` keeps the newest MAX_EVENTS)
    status_at: float | None = None  # monotonic time of the newest status
    world_seen: bool = False  # the world's liveliness token was seen (its loss then ends the run)
    rejected_by_reason: Counter = field(default_factory=Counter)


@dataclass(frozen=True)
class Answer:
    """What became of a command: ``outcome`` ``applied`` | ``rejected`` (the world's reply in
    ``reply``) | ``denied`` (the router's access control refused it) | ``no_answer`` (nobody
    answered in time, or the answer could not be read); ``detail`` says it for a person."""

    outcome: str
    reply: CommandReply | None = None
    detail: str = ""

    @property
    def code(self) -> int:
        return {"applied": EXIT_APPLIED, "rejected": EXIT_REJECTED, "denied": EXIT_DENIED}.get(self.outcome,
                                                                                             EXIT_NO_ANSWER)


NOT_VEHICLES = frozenset({keys.WORLD, keys.GROUND, "launcher", ROS2_ROLE})  # liveliness tokens of the fleet that are no vehicle's


def row_ids(world: WorldStatus | None, states: Any, alive: set[str]) -> list[str]:
    """The vehicles a table shows a row for: the world's ids when it has spoken (other names on
    the fleet's keys are not vehicles of the run: ground stations' tokens, the ROS 2 bridge's,
    forgeries); before that, whoever sends telemetry or holds a token that is no process of the
    fleet's own (NOT_VEHICLES)."""
    known = list(world.ids) if world is not None else []
    return known or sorted(set(states) | (set(alive) - NOT_VEHICLES))


def vehicle_state(vid: str, world: WorldStatus | None, alive: set[str], tokens_in: bool = False) -> str:
    """live / paused / lost / ended (left when the run was over): the world's roster where its status has it, else its liveliness;
    a vehicle whose liveliness token is gone is lost unless the roster says it is paused.
    ``tokens_in``: our liveliness view has come in (the world's token was heard), so a vehicle
    missing from ``alive`` is gone even when no vehicle is left in it (the end of a run, where
    the world's last status still lists them all); before that, the world's ``alive`` stands in."""
    st = None
    if world is not None and world.states is not None and vid in world.ids:  # one state per id (decode_status)
        st = world.states[world.ids.index(vid)]
    tokens = alive if alive or tokens_in else set(world.alive if world is not None else ())
    if st == "paused":  # a stopped process's token lapses with the lease: paused still, as the operator asked
        return "paused"
    if st != "gone" and world is not None and world.completion and vid not in tokens:
        return "ended"  # left with the run's end (the world's last status says it is over)
    if (tokens or tokens_in) and vid not in tokens or st == "gone":
        return "lost"
    st = st or ("live" if vid in tokens else "lost")
    return "paused" if st == "live" and world is not None and world.paused else st


def status_table(view: FleetView, now: float | None = None) -> str:
    """A plain-text table of the fleet: one row per vehicle seen, then the world's line. Every
    string that came over the wire is escaped (cdus.wire.text.printable), every number that is
    not a finite one is shown as what it is."""
    with view.lock:
        w = view.world
        known = w.ids if w is not None else []
        ids = row_ids(w, view.states, view.alive)
        vehicles = view.alive - NOT_VEHICLES
        rows = [f"{'vehicle':<10} {'alive':<5} {'t (s)':>8} {'|Φ| (m)':>9} {'ω':>11} {'ω̇':>8}  position"]
        for vid in ids:
            m = view.states.get(vid)
            state = vehicle_state(vid, w, vehicles, view.world_seen)
            alive = "NO" if state in ("lost", "ended") else "yes"
            name = _text(vid, 32)
            why = _not_live(view, vid)
            if m is None:
                rows.append(f"{name:<10} {alive:<5} {'-':>8}  ({why or 'no data yet'})")
                continue
            pos = ", ".join(num(x, ".1f") for x in m.q)
            rows.append(f"{name:<10} {alive:<5} {num(m.t, '.2f'):>8} {num(m.path_error):>9} {num(m.omega):>11} "
                        f"{num(m.omega_rate):>8}  ({pos})" + (f"  [{why}]" if why else ""))
        if w is not None:
            paused = ", PAUSED" if w.paused else ""
            alive_n = sum(1 for v in known if vehicle_state(v, w, vehicles, view.world_seen) not in ("lost", "ended"))
            over = f"; the run is over: {w.completion}" if w.completion else ""
            rows.append(f"world: t = {num(w.t, '.1f')} / {num(w.duration, '.0f')} s "
                        f"({w.clock}{paused}), {alive_n}/{len(known)} vehicles alive, worst |Φ| "
                        f"{num(w.path_error_max)} m, worst edge error {num(w.coord_error_max, '.4f')} rad{over}")
        else:
            rows.append("world: no status yet")
        # heard live, else the world's recent ones
        events = group_link_states(view.events or (w.events if w is not None else []))
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


def _not_live(view: FleetView, vid: str) -> str | None:
    """Why a vehicle's values are not live ones (caller holds the lock): ``paused (fleet)``,
    ``paused``, ``gone``, ``the run ended``, ``not alive``; None when they are."""
    w = view.world
    roster = (w.roster if w is not None else None) or {}
    if roster.get(vid) == "gone":
        return "gone"
    if roster.get(vid) == "paused":
        return "paused"
    if w is not None and w.completion and vid not in view.alive:
        return "the run ended"  # it left with the run's end (the world's last status)
    if w is not None and w.paused:
        return "paused (fleet)"
    if vid not in view.alive:
        return "not alive"
    return None


def default_name() -> str:
    """A ground station's name in the world's event log: host and process id."""
    host = re.sub(r"[^A-Za-z0-9_-]", "-", socket.gethostname())[:40] or "host"
    return f"{host}-{os.getpid()}"


def credentials_user(config_file: str | None) -> str | None:
    """The user name of a Zenoh config file cdus wrote (JSON), None if it has none or is not one."""
    if not config_file:
        return None
    try:
        with open(config_file) as fh:
            user = json.load(fh)["transport"]["auth"]["usrpwd"]["user"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return printable(user, 64) if isinstance(user, str) else None


_FLEET_SPACE = re.compile(r"cdus/([A-Za-z0-9_-]{1,64})/\*\*")


def credentials_fleet(config_file: str | None) -> str | None:
    """The fleet a ground station's credentials are for: cdus writes them beside the fleet's
    router settings (RUN/secure/router.json5), whose access control names its key space
    ``cdus/<fleet>/**``. None if that cannot be read or names no single fleet."""
    if not config_file:
        return None
    try:
        with open(os.path.join(os.path.dirname(os.path.abspath(config_file)), "router.json5")) as fh:
            rules = json.load(fh)["access_control"]["rules"]  # as cdus.wire.access.fleet_acl writes them
        found = {m[1] for rule in rules for expr in rule["key_exprs"]
                 if isinstance(expr, str) and (m := _FLEET_SPACE.fullmatch(expr))}
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return found.pop() if len(found) == 1 else None


def config_endpoints(config_file: str | None) -> list[str]:
    """The ``connect/endpoints`` of a Zenoh config file cdus wrote (JSON), [] if none."""
    if not config_file:
        return []
    try:
        with open(config_file) as fh:
            eps = json.load(fh)["connect"]["endpoints"]
    except (OSError, ValueError, KeyError, TypeError):
        return []
    return [e for e in eps if isinstance(e, str)] if isinstance(eps, list) else []


def listening(endpoint: str, timeout: float = 1.0) -> bool | None:
    """Does something accept connections at a Zenoh endpoint? None: cannot tell (a protocol that
    is not TCP-based or a unix socket)."""
    proto, _, rest = endpoint.partition("/")
    rest = rest.split("#", 1)[0].split("?", 1)[0]
    try:
        if proto in ("tcp", "tls", "quic", "ws"):
            port = int(rest.rsplit(":", 1)[1])
            with socket.create_connection((endpoint_host(endpoint), port), timeout=timeout):
                return True
        if proto == "unixsock-stream":
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
                sock.settimeout(timeout)
                sock.connect(rest)
                return True
    except (OSError, ValueError, IndexError):
        return False
    return None


class GroundStation:
    def __init__(self, fleet: str, transport: Transport, name: str | None = None):
        """``name``: how the world's event log names this ground station's commands (``gs:<name>``;
        letters, digits, ``_`` and ``-``); None: ``gs`` alone."""
        self.fleet = keys.check_fleet(fleet)
        if name is not None and not keys.FLEET_RE.match(name):
            raise ValueError(f"ground station name {name!r}: use 1-64 letters, digits, '_' or '-'")
        self.name = name
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
            if (isinstance(rows, Rejected) or vid is None or not keys.FLEET_RE.match(vid)
                    or vid not in self.view.states and len(self.view.states) >= MAX_NAMES):
                self.view.rejected += 1
                return
            self.view.states[vid] = rows[-1]

    def _on_status(self, sample: Any) -> None:
        st = decode_status(sample.payload.to_bytes())
        with self.view.lock:
            if isinstance(st, Rejected):
                self.view.rejected += 1
                self.view.rejected_by_reason[f"status_{st.reason}"] += 1
            else:
                self.view.world = st
                self.view.status_at = time.monotonic()

    def _on_event(self, sample: Any) -> None:
        e = decode_event(sample.payload.to_bytes())
        with self.view.lock:
            if isinstance(e, Rejected):
                self.view.rejected += 1
            else:
                self.view.events.append(e)
                self.view.events_seen += 1
                del self.view.events[:-MAX_EVENTS]  # a flood of events cannot grow the console without bound

    def _on_alive(self, sample: Any) -> None:
        key, up = str(sample.key_expr), not str(sample.kind).endswith("DELETE")
        with self.view.lock:
            if up and keys.alive_name(key) not in self.view.alive and len(self.view.alive) >= MAX_NAMES:
                self.view.rejected += 1
                return
            news = keys.hold_token(self.view.tokens, key, up)
            if news is None:  # a token on a key expression (alive/**) or no process's key
                self.view.rejected += 1
            elif news[1]:
                self.view.alive.add(news[0])
                self.view.world_seen |= news[0] == keys.WORLD
            else:
                self.view.alive.discard(news[0])

    def wait_for_status(self, timeout: float) -> bool:
        """Wait until the world's status has been heard: asked for at once (the world answers
        with its newest), else as it is published, about once a second."""
        deadline = time.monotonic() + timeout
        try:
            for reply in self.session.get(keys.world_status(self.fleet), timeout=min(timeout, 1.0)):
                with self.view.lock:
                    heard = self.view.world is not None  # a published one came first: it is as new
                if reply.ok is not None and not heard:
                    self._on_status(reply.ok)  # checked as a published one is
        except (zenoh.ZError, RuntimeError):
            pass  # not answered (a world older than the query, a router that refuses it): the subscription's
        while time.monotonic() < deadline:
            with self.view.lock:
                if self.view.world is not None:
                    return True
            time.sleep(0.05)
        return False

    def sim_time(self) -> float | None:
        """The world's simulated time, None before its status."""
        with self.view.lock:
            w = self.view.world
        return None if w is None else w.t

    def fetch_last(self, timeout: float = 2.0) -> int:
        """Ask the world for every vehicle's newest telemetry (``world/last/*``): a fleet that is
        paused sends none, and a ground station attaching then would know nothing. Fills the
        vehicles not heard live yet; returns how many replies were taken."""
        taken = 0
        for reply in self.session.get(keys.world_last(self.fleet, "*"), timeout=timeout):
            sample = reply.ok
            if sample is None:
                continue
            rows = decode_states(sample.payload.to_bytes())
            vid = str(sample.key_expr).rsplit("/", 1)[-1]
            with self.view.lock:
                if isinstance(rows, Rejected) or not keys.FLEET_RE.match(vid) \
                        or vid not in self.view.states and len(self.view.states) >= MAX_NAMES:
                    self.view.rejected += 1
                    continue
                have = self.view.states.get(vid)
                if have is None or rows[-1].tick > have.tick:
                    self.view.states[vid] = rows[-1]
                    taken += 1
        return taken

    def fetch_settings(self, timeout: float = 2.0) -> dict[str, Any] | None:
        """The run's settings in force, from the world (``world/settings``, decoded by
        cdus.wire.schemas.decode_settings): the run-time changes made, the formation's phases and
        the [link] table. None when no world answered with readable settings (an older world);
        a reply that cannot be read is counted as rejected."""
        try:
            replies = list(self.session.get(keys.world_settings(self.fleet), timeout=timeout))
        except (zenoh.ZError, RuntimeError):
            return None
        with self.view.lock:
            known = (list(self.view.world.ids) if self.view.world is not None else []) or None
        for reply in replies:
            sample = reply.ok
            if sample is None:
                continue
            got = decode_settings(sample.payload.to_bytes(), known)
            if isinstance(got, dict):
                return got
            with self.view.lock:
                self.view.rejected += 1
                self.view.rejected_by_reason[got.reason] += 1
        return None

    def fleets_here(self, timeout: float = 1.0) -> list[str]:
        """The fleets whose world holds a liveliness token at this router (sorted, at most 50),
        for a mistyped ``--fleet``: [] when there are none or the router's access control does
        not let this ground station see them."""
        found: set[str] = set()
        try:
            for reply in self.session.liveliness().get(keys.ANY_FLEET_WORLD, timeout=timeout):
                sample = reply.ok
                fleet = keys.fleet_of(str(sample.key_expr)) if sample is not None else None
                if fleet is not None and keys.alive_name(str(sample.key_expr)) == keys.WORLD:
                    found.add(fleet)
                if len(found) >= 50:
                    break
        except (zenoh.ZError, RuntimeError):
            return []
        return sorted(found)

    def world_up(self) -> bool:
        """Is the world there: its liveliness token, or a status within the last 3 s?"""
        with self.view.lock:
            recent = self.view.status_at is not None and time.monotonic() - self.view.status_at < 3.0
            return keys.WORLD in self.view.alive or recent

    def _world_left(self, wait: float) -> bool:
        """Was the world seen and is its liveliness token gone now, or within ``wait`` s (its
        session closing ends the queries it held a moment before the router says it left)?"""
        deadline = time.monotonic() + wait
        while True:
            with self.view.lock:
                if not self.view.world_seen:
                    return False
                if keys.WORLD not in self.view.alive:
                    return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.02)

    def world_gone(self) -> bool:
        """The world was seen and its token is gone: the run is over."""
        with self.view.lock:
            return self.view.world_seen and keys.WORLD not in self.view.alive

    # ------------------------------------------------------------------ commanding
    def command(self, op: str, timeout: float = COMMAND_TIMEOUT, **fields: Any) -> Answer:
        """Ask the world to carry out a command (cdus.wire.messages.COMMAND_OPS) and wait, at most
        ``timeout`` s, for its answer: applied (from a tick) or rejected (a reason). A query the
        router's access control refuses comes back at once with no reply, as one that reaches
        no world does: with the world up (its token or status heard) it is reported as denied."""
        if self.name is not None:
            fields["name"] = self.name
        t0 = time.monotonic()
        payload = encode_control(op, **fields)
        problems: list[str] = []
        answers: list[CommandReply] = []
        # every reply until the query ends: the world's is one, and more than one that differ means
        # something else answers on the command key (a fleet run with --insecure lets anyone)
        for r in self.session.get(keys.world_command(self.fleet, keys.GROUND), payload=payload, timeout=timeout,
                                  consolidation=_ALL_REPLIES):
            if r.ok is None:
                said = r.err.payload.to_bytes().decode("utf-8", "replace")
                if said.strip() != "Timeout":  # Zenoh's own word for a query whose time ran out: said below
                    problems.append("an error reply: " + printable(said, 200))
                continue
            reply = decode_reply(r.ok.payload.to_bytes())
            if isinstance(reply, Rejected):
                with self.view.lock:
                    self.view.rejected += 1
                    self.view.rejected_by_reason[f"reply_{reply.reason}"] += 1
                problems.append(f"an answer that could not be read ({reply.reason})")
                continue
            if reply not in answers:
                answers.append(reply)
        if len(answers) == 1:
            return Answer(answers[0].status, answers[0])
        if answers:
            said = "; ".join(f"{a.status}" + (f" ({a.reason})" if a.reason else "") + (f" by {a.by}" if a.by else "")
                             for a in answers[:4])
            with self.view.lock:
                self.view.rejected_by_reason["reply_conflict"] += 1
            return Answer("no_answer", None, f"{len(answers)} different answers came back ({printable(said, 300)}): "
                                             "something besides the fleet's world answers on its command key (a fleet "
                                             "run with --insecure lets anyone); check the run's event log for what "
                                             "the world did")
        waited = time.monotonic() - t0
        if problems:
            return Answer("no_answer", None, "; ".join(problems))
        user = credentials_user(self.transport.config_file)
        if waited < timeout * 0.9 and self._world_left(WORLD_LEFT_WAIT):
            return Answer("no_answer", None, "the world left before answering (its process ended or the run is "
                                             "over): the command may or may not have been carried out; see the "
                                             "run's summary and event log")
        # the ground role may ask: no reply to it is not the router's access control (nor on a
        # fleet without credentials, which has none)
        if waited < timeout * 0.9 and self.world_up() and user is not None and user != GROUND_ROLE:
            who = f" (these are the credentials of {user!r})" if user else ""
            return Answer("denied", None,
                          f"denied: the fleet's router refused this command{who}; only the ground station's "
                          "credentials may command a secured fleet: use --zenoh-config RUN/secure/ground.json5 "
                          "(the launcher prints the whole line)")
        if waited < timeout * 0.9:
            return Answer("no_answer", None, "the query ended with no answer: no world took the command "
                                             "(is the fleet still running?)")
        return Answer("no_answer", None, f"no answer from the world within {timeout:g} s (a vehicle's "
                                         "kill, pause, resume or restart is answered when it is carried out: "
                                         "give more time with --timeout S; the run's event log says what was done)")

    def snapshot(self, settings: bool = False) -> dict[str, Any]:
        """The fleet as this ground station knows it, as one versioned JSON object
        (docs/ground_station.md): the run, then every vehicle with its newest values (or null)
        and why they are not live ones (null when they are); with ``settings``, the run's
        settings in force asked of the world (:meth:`fetch_settings`; null if it did not say)."""
        extra = {"settings": self.fetch_settings()} if settings else {}
        with self.view.lock:
            w = self.view.world
            known = w.ids if w is not None else []
            ids = sorted(set(known) | set(self.view.states) | (self.view.alive - {keys.WORLD}))
            vehicles = []
            for vid in ids:
                m = self.view.states.get(vid)
                why = _not_live(self.view, vid)
                roster = ((w.roster if w is not None else None) or {}).get(vid)
                vehicles.append({
                    "id": vid, "alive": vid in self.view.alive, "state": roster,
                    "telemetry": None if m is None else {
                        "tick": m.tick, "t": _json_num(m.t), "q": [_json_num(x) for x in m.q],
                        "heading": _json_num(m.heading), "speed": _json_num(m.speed), "omega": _json_num(m.omega),
                        "omega_rate": _json_num(m.omega_rate), "path_error": _json_num(m.path_error)},
                    "reason": "no data yet" if m is None else why})
            world_gone = self.view.world_seen and keys.WORLD not in self.view.alive
            if w is None:
                run = "world_gone" if world_gone else "no_status"
            elif world_gone:
                run = "ended"
            elif w.completion or w.t >= w.duration - 1e-9:
                run = "finishing"
            else:
                run = "paused" if w.paused else "running"
            return {
                "v": SNAPSHOT_VERSION, "kind": "status", "fleet": self.fleet, "wall_time": time.time(),
                "run": run,
                "t": None if w is None else w.t, "duration": None if w is None else w.duration,
                "completion": None if w is None else w.completion,
                "clock": None if w is None else w.clock, "paused": None if w is None else w.paused,
                "alive": sum(1 for v in ids if v in self.view.alive),
                "path_error_max": None if w is None else w.path_error_max,
                "coord_error_max": None if w is None else w.coord_error_max,
                "vehicles": vehicles,
                # heard live, else the world's recent ones (as the text status): a one-shot
                # `status --json` hears none live
                "events": [e.as_dict() for e in (self.view.events or (w.events if w is not None else []))[-20:]],
                "rejected": self.view.rejected,
            } | extra

    def events_since(self, seen: int) -> tuple[list[FleetEvent], int]:
        """The events heard after the first ``seen`` (and the new count); those pushed out of
        the kept window meanwhile are skipped."""
        with self.view.lock:
            total = self.view.events_seen
            new = min(total - seen, len(self.view.events))
            return (self.view.events[len(self.view.events) - new:] if new > 0 else []), total


def _json_num(x: float) -> float | None:
    """A number for JSON: a finite float, else null (the decoders let only finite ones through)."""
    return float(x) if finite(x) else None

"""What does `cdus gs ... console` show? The live console, a terminal UI (Textual) on a GroundStation.

It shows, refreshed twice a second from what the ground station hears (the world's status,
each vehicle's telemetry and liveliness, the fleet's events):

- a header: the fleet, the world's simulated time and clock, vehicles alive, the worst
  errors, PAUSED while the fleet is;
- the vehicle table: id, kind, state (live / paused / lost), its telemetry's time,
  position, ω, ω̇, |Φ|, the worst error of its coordination edges, the ω messages
  addressed to it and how many its link dropped;
- the edges and their errors; the links the emulator decides, with sent and dropped counts;
- the alarms (ground_station.alarms), active ones and a history stamped with simulated time;
- a log: the outcome of each command and the fleet's events.

Keys (docs/console.md): ↑/↓ select a vehicle; p / r pause / resume it, k kill it (asks
y/n first), t restart it; P / R pause / resume the fleet; q quit. Every command goes
through :func:`send_command`, the one place the console sends (an acknowledged command).
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import replace
from typing import Any, Callable

import zenoh
from rich.text import Text
from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal
from textual.css.query import NoMatches
from textual.message import Message
from textual.screen import ModalScreen
from textual.widgets import DataTable, Footer, RichLog, Static

from cdus.commands.base import Rejected
from cdus.commands.parse import parse_cli, parse_event
from cdus.wire import keys
from cdus.wire.bounds import finite
from cdus.wire.schemas import FleetEvent
from cdus.wire.status import WorldStatus
from ground_station.alarms import Alarms
from cdus.sim.reports import EventHold, group_link_states
from ground_station.console import NOT_VEHICLES, _text, num, row_ids, vehicle_state

REFRESH_S = 0.5
STALE_S = 3.0  # the world publishes its status every second: this long without one is news
#: (title, width): fixed widths, so a longer value later (paused, lost) is never cut
VEHICLE_COLUMNS = (("vehicle", 12), ("kind", 4), ("state", 6), ("t (s)", 9), ("x (m)", 8), ("y (m)", 8),
                   ("z (m)", 6), ("ω", 10), ("ω̇", 7), ("|Φ| (m)", 8), ("edge err", 9), ("rx ω", 8), ("dropped", 7))
EDGE_COLUMNS = (("edge", 25), ("error (rad)", 11))
LINK_COLUMNS = (("link / receiver", 27), ("sent", 9), ("dropped", 8), ("state", 6))


def before_line(events: list[FleetEvent]) -> str:
    """The world's recent events, heard before this console came, as one line of its log (they
    were a line each, up to ten "event (before)" lines the log started with): how many of each
    kind, a link change of many links as one (group_link_states), the newest in full."""
    grouped = group_link_states(sorted(events, key=lambda e: e.t))
    if not grouped:
        return ""
    if len(grouped) == 1:
        return f"event (before this console) {grouped[0].line()}"
    kinds = Counter(e.kind for e in grouped)
    return (f"before this console: {len(grouped)} events from t = {grouped[0].t:.2f} to {grouped[-1].t:.2f} s "
            f"({', '.join(f'{n} {k}' for k, n in kinds.most_common())}); the newest: {grouped[-1].line()}")


def send_command(gs: Any, op: str, vehicle: str | None = None) -> tuple[bool, str]:
    """Send one operator command, wait for the world's answer and say what became of it: (ok, a
    line for the log). ``op``: pause | resume (the fleet, without ``vehicle``) or pause | resume |
    kill | restart (one vehicle). Runs off the UI thread: the answer can take the command's
    timeout (GroundStation.command: applied from a tick, rejected with the reason, denied, or no
    answer)."""
    what = f"{op} {vehicle}" if vehicle else f"{op} fleet"
    # the vehicle's fault by its event word (pause -> pause_vehicle), or the fleet's command
    command = parse_event({"action": op, "vehicle": vehicle}) if vehicle else parse_cli(op)
    if isinstance(command, Rejected):
        return False, f"{what}: FAILED, {_text(str(command), 200)}"
    try:
        answer = gs.command(command.NAMES.op, **command.fields())
    except (zenoh.ZError, ValueError, RuntimeError, AttributeError) as e:
        return False, f"{what}: FAILED, {_text(str(e), 200)}"
    r = answer.reply
    if answer.outcome == "applied" and r is not None:
        when = f"tick {r.tick}" + (f" (t = {r.t:.2f} s)" if isinstance(r.t, float) else "")
        return True, f"{what}: applied from {when}"
    if answer.outcome == "rejected" and r is not None:
        return False, f"{what}: REJECTED, {_text(r.reason or 'no reason given', 200)}"
    return False, f"{what}: {answer.outcome.replace('_', ' ').upper()}, {_text(answer.detail, 200)}"


def snapshot(view: Any) -> dict[str, Any]:
    """What the screen shows, read once under the view's lock: plain values, no widgets
    (tested without a terminal)."""
    with view.lock:
        w = view.world  # replaced whole by each status, never changed in place
        states = dict(view.states)
        alive = set(view.alive) - NOT_VEHICLES
        tokens_in = view.world_seen  # our liveliness view is in: an empty one means every vehicle left
        over = view.world_seen and keys.WORLD not in view.alive  # the world has left (its last status unheard)
        events = list(view.events[-200:])
        rejected = view.rejected
    ids = row_ids(w, states, alive)
    kinds = dict(zip(w.ids, w.kinds or [])) if w else {}
    rx = dict(zip(w.ids, w.rx or [])) if w else {}
    edges = (w.edges if w else None) or []
    worst_edge: dict[str, float] = {}
    for a, b, e in edges:
        if e is not None:
            for v in (a, b):
                worst_edge[v] = max(worst_edge.get(v, 0.0), e)
    rows = []
    for vid in ids:
        m = states.get(vid)
        q = list(m.q) + [None] * 3 if m is not None else [None] * 3
        r = rx.get(vid)
        rows.append((vid, kinds.get(vid, "?"), vehicle_state(vid, w, alive, tokens_in),
                     num(m.t if m else None, ".2f"), num(q[0], ".1f"), num(q[1], ".1f"),
                     num(q[2], ".1f") if m is not None and len(m.q) > 2 else "",
                     num(m.omega if m else None), num(m.omega_rate if m else None), num(m.path_error if m else None),
                     num(worst_edge.get(vid), ".4f"), "-" if r is None else str(r[0]), "-" if r is None else str(r[1])))
    if w:
        n_alive = sum(1 for v in ids if vehicle_state(v, w, alive, tokens_in) not in ("lost", "ended"))
        header = (f"t = {w.t:.1f} / {w.duration:.0f} s  ({w.clock})"
                  f"   {n_alive}/{len(ids)} vehicles alive" + ("   FLEET PAUSED" if w.paused else "")
                  + (f"   RUN OVER: {w.completion}" if w.completion
                     else "   RUN OVER (the world has left)" if over else "")
                  + f"\nworst |Φ| {num(w.path_error_max)} m   worst edge error "
                  f"{num(w.coord_error_max, '.4f')} rad"
                  + ("   closest {} - {} {} m".format(*w.closest[:2], num(w.closest[2], ".2f"))
                     if w.closest else "")
                  + (f" (safety radius {w.safety_radius:g} m)" if w.safety_radius else ""))
    else:
        header = "no status from the world yet"
    if rejected:
        header += f"   ({rejected} malformed messages ignored)"
    telemetry_t = {v: m.t for v, m in states.items() if v in ids and finite(m.t)}
    now = max(telemetry_t.values(), default=None)
    return {"world": w, "header": header, "rows": rows, "edges": edges, "links": (w.links if w else None) or [],
            "events": events, "alive": alive, "now": now, "heard": telemetry_t, "tokens_in": tokens_in, "over": over}


def alarm_status(world: WorldStatus, alive: set[str], now: float | None = None, tokens_in: bool = False) -> WorldStatus:
    """The world's status as the alarms read it: each vehicle's roster state, but ``gone`` as
    soon as its liveliness token is (a killed process's token goes at once, the status comes
    once a second), as the vehicle table shows it; its time the newest the console knows
    (``now``: the newest telemetry's, ahead of the status's), so an alarm is not stamped
    before what it reports); ``tokens_in``: as vehicle_state's."""
    calm = replace(world, paused=False)  # the fleet's pause is not a vehicle's state
    states = [vehicle_state(v, calm, alive, tokens_in) for v in world.ids]
    # a vehicle that left with the run's end is not lost: as the roster had it
    states = ["gone" if x == "lost" else "live" if x == "ended" else x for x in states]
    return replace(world, t=max(world.t, now) if now is not None else world.t, states=states)


class ConfirmKill(ModalScreen[bool]):
    """Kill <vehicle>? y / n."""

    BINDINGS = [Binding("y", "answer(True)", "yes, kill"), Binding("n", "answer(False)", "no"),
                Binding("escape", "answer(False)", "no")]
    DEFAULT_CSS = """
    ConfirmKill { align: center middle; }
    ConfirmKill > Static { width: 60; height: 5; border: thick $error; padding: 1 2; background: $surface; }
    """

    def __init__(self, vehicle: str):
        super().__init__()
        self.vehicle = vehicle

    def compose(self) -> ComposeResult:
        yield Static(Text(f"Kill {self.vehicle}'s process?  y: kill   n / Esc: keep it"))

    def action_answer(self, yes: bool) -> None:
        self.dismiss(yes)


class CommandDone(Message):
    """A command's outcome, posted from its worker thread (post_message is thread-safe and never
    waits: call_from_thread waits for the app, which, quitting meanwhile, waited for the worker)."""

    def __init__(self, line: str) -> None:
        self.line = line
        super().__init__()


class ConsoleApp(App):
    """The live console on ground station ``gs`` (anything with ``fleet``, ``view`` (a
    FleetView) and ``command``, the acknowledged call)."""

    TITLE = "cdus console"
    CSS = """
    #header { height: auto; background: $primary-background; }
    #vehicles { height: auto; max-height: 50%; }
    #middle { height: 1fr; min-height: 6; }
    #edges, #links { width: 1fr; }
    #alarms { height: auto; max-height: 8; border-top: solid $error; }
    #log { height: 1fr; border-top: solid $secondary; }
    """
    BINDINGS = [
        Binding("p", "vehicle('pause')", "pause vehicle"),
        Binding("r", "vehicle('resume')", "resume vehicle"),
        Binding("k", "kill", "kill vehicle"),
        Binding("t", "vehicle('restart')", "restart vehicle"),
        Binding("P", "fleet('pause')", "pause fleet"),
        Binding("R", "fleet('resume')", "resume fleet"),
        Binding("q", "quit", "quit"),
    ]

    def __init__(self, gs: Any, refresh_s: float = REFRESH_S, send: Callable = send_command):
        super().__init__()
        self.gs = gs
        self.refresh_s = refresh_s
        self.send = send
        self.alarms = Alarms()
        self._status_seen: Any = None
        self._status_at = time.monotonic()
        self._last_event: FleetEvent | None = None  # the newest event already in the log (by identity)
        self._held = EventHold()  # live events, held a moment to be logged in time order (see refresh)

    def compose(self) -> ComposeResult:
        yield Static(Text(f"fleet {self.gs.fleet}"), id="header")
        yield DataTable(id="vehicles", cursor_type="row", zebra_stripes=True)
        with Horizontal(id="middle"):
            yield DataTable(id="edges", cursor_type="none")
            yield DataTable(id="links", cursor_type="none")
        yield Static(Text("alarms: none"), id="alarms")
        yield RichLog(id="log", max_lines=500, markup=False, wrap=True)
        yield Footer()

    def on_mount(self) -> None:
        for table, columns in (("#vehicles", VEHICLE_COLUMNS), ("#edges", EDGE_COLUMNS), ("#links", LINK_COLUMNS)):
            t = self.query_one(table, DataTable)
            for title, width in columns:
                t.add_column(title, width=width)
        self.query_one("#vehicles", DataTable).focus()
        self.refresh_view()
        self.set_interval(self.refresh_s, self.refresh_view)

    # ------------------------------------------------------------------ the screen
    def log_line(self, line: str) -> None:
        try:
            self.query_one("#log", RichLog).write(Text(line))
        except NoMatches:  # an outcome that comes back as the console closes
            pass

    def selected(self) -> str | None:
        table = self.query_one("#vehicles", DataTable)
        if not table.row_count:
            return None
        row = table.get_row_at(table.cursor_coordinate.row)
        return str(row[0]) if row else None

    def refresh_view(self) -> None:
        try:
            self._refresh_view()
        except NoMatches:  # a refresh due while the screen is being set up or torn down
            pass

    def _refresh_view(self) -> None:
        snap = snapshot(self.gs.view)
        w = snap["world"]
        now = time.monotonic()
        if w is not None and w is not self._status_seen:
            self._status_at = now
        quiet = now - self._status_at
        stale = (f"   NO STATUS for {quiet:.0f} s (the world ended or the link to the router is down)"
                 if quiet > STALE_S and not snap["over"] else "")
        head, _, rest = snap["header"].partition("\n")
        self.query_one("#header", Static).update(Text(f"fleet {self.gs.fleet}   {head}{stale}\n{rest}".rstrip()))
        _fill(self.query_one("#vehicles", DataTable), snap["rows"])
        _fill(self.query_one("#edges", DataTable),
              [(f"{a}-{b}", num(e, ".4f", none="end down")) for a, b, e in snap["edges"]])
        links = [(f"{s}->{d}", str(n), str(x), st or "-") for s, d, n, x, st in snap["links"]]
        if not links and w:  # no emulated link faults: what each vehicle received
            links = [(f"-> {v}", str(r[0]), str(r[1]), "") for v, r in zip(w.ids, w.rx or [])
                     if r is not None]
        _fill(self.query_one("#links", DataTable), links)
        if w is not None and self._status_seen is None:  # what happened before the console came: one line
            line = before_line([e for e in w.events if e.kind != "link_burst"])
            if line:
                self.log_line(line)
        if w is not None:  # every refresh: a vehicle's token going is news before the next status
            self._status_seen = w
            status = alarm_status(w, snap["alive"], snap["now"], snap["tokens_in"])
            for ch in self.alarms.update(status, snap["heard"]):
                self.log_line(ch.line())
        self._show_alarms()
        events = snap["events"]
        # the events after the newest one logged (the view keeps its newest MAX_EVENTS: count by identity)
        start = next((i + 1 for i in range(len(events) - 1, -1, -1) if events[i] is self._last_event), 0)
        for e in events[start:]:
            if isinstance(e, FleetEvent) and e.kind != "link_burst":
                self._held.hold(e, now)
        if events:
            self._last_event = events[-1]
        # as the launcher prints them: held a moment, in time order, a change of many links one line
        ready = self._held.flush() if snap["over"] or w is not None and w.completion else self._held.due(now)
        for e in group_link_states(ready):
            self.log_line(f"event {e.line()}" + (f"  [{e.severity.upper()}]" if e.severity != "info" else ""))

    def _show_alarms(self) -> None:
        active = sorted(self.alarms.active.values(), key=lambda a: a.t)
        lines = [f"ALARM t = {a.t:.2f} s: {a.text}" for a in active] or ["alarms: none"]
        lines += self.alarms.notes
        self.query_one("#alarms", Static).update(Text("\n".join(lines)))

    # ------------------------------------------------------------------ commands
    def _dispatch(self, op: str, vehicle: str | None) -> None:
        what = f"{op} {vehicle}" if vehicle else f"{op} fleet"
        self.log_line(f"> {what}")
        self.run_worker(lambda: self.post_message(CommandDone(self.send(self.gs, op, vehicle)[1])),
                        thread=True, exclusive=False, group="commands")

    def on_command_done(self, message: CommandDone) -> None:
        self.log_line(message.line)

    def action_vehicle(self, op: str) -> None:
        vid = self.selected()
        if vid is None:
            self.log_line(f"{op}: no vehicle selected")
            return
        self._dispatch(op, vid)

    def action_fleet(self, op: str) -> None:
        self._dispatch(op, None)

    def action_kill(self) -> None:
        vid = self.selected()
        if vid is None:
            self.log_line("kill: no vehicle selected")
            return

        def answered(yes: bool | None) -> None:
            if yes:
                self._dispatch("kill", vid)
            else:
                self.log_line(f"kill {vid}: cancelled")

        self.push_screen(ConfirmKill(vid), answered)


def _fill(table: DataTable, rows: list[tuple]) -> None:
    """Show ``rows`` (first cell: the row's key) in ``table``, keeping its cursor where it is."""
    keys_now = [str(r[0]) for r in rows]
    if [k.value for k in table.rows] != keys_now:
        cursor = table.cursor_coordinate
        table.clear()
        for r in rows:
            table.add_row(*(Text(str(c)) for c in r), key=str(r[0]))
        if table.row_count:
            table.move_cursor(row=min(cursor.row, table.row_count - 1))
        return
    for r in rows:
        for col, c in zip(table.columns, r):
            table.update_cell(str(r[0]), col, Text(str(c)))

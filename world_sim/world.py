"""The world process: sees every vehicle, owns the clock, computes the metrics.

Everything addressed to the world (telemetry, counters, commands, and its own
liveliness watch) arrives through one subscription into one channel; the main thread
waits there alone. It records tick n once every vehicle live at n has reported it,
writes the metrics JSON with the same builder as `cdus sim` (cdus.sim.summary), streams
to the sink (Rerun), publishes its status and the fleet's events, and relays an
operator's commands to the vehicles with the tick (or simulated time) they apply from.

- lockstep: the decisions (grants, the roster, faults on their ticks, joins) are
  cdus.sim.lockstep.Lockstep's; this process carries them out.
- the proximity sensor (with the safety filter on): it samples the positions at the
  sensor ticks and sends each vehicle its contacts (cdus.sim.sensing); in lockstep on
  Lockstep's Sense decisions, from the telemetry of exactly that tick; in realtime as
  the wall clock passes a sample tick, from the newest telemetry it has.
- realtime: it publishes a start time t0 once every vehicle is up, records tick n a
  little after it is due with each vehicle's newest telemetry at or before n, and turns
  liveliness changes into roster changes for the vehicles (a vehicle lost is out of its
  neighbours' sums at once).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, NamedTuple

import numpy as np
import zenoh

from cdus.core.events import RosterChange
from cdus.core.link import LinkCounters, merge_link_summaries
from cdus.core.node import gains_problem
from cdus.core.radiolink import RadioCounters
from cdus.core.metrics import Recorder
from cdus.core.quota import Quota
from cdus.core.schedule import total_ticks
from cdus.files import METRICS_ELSEWHERE_EXIT, keep_json, metrics_fallbacks
from cdus.scenario.config import ConfigError, nesting_problem
from cdus.scenario.link import merge_link_tables, validate_link
from cdus.scenario.model import Scenario
from cdus.scenario.events import check_offsets, check_path, check_phases, offsets_to_phases
from cdus.sim.build import (
    build_vehicle, formation_schedule, metric_edges, radio_channel_for, radio_schedule, sensor_schedule,
)
from cdus.sim.lockstep import CatchUp, Decided, Fault, Grant, Join, Lockstep, RadioSample, Roster, Sense, horizon_window
from cdus.sim.reports import (
    ConsoleQuota, formation_changed, graph_event, link_state_event, newest_events, path_changed,
    scheduled_change_events, vehicle_back, vehicle_lost,
)
from cdus.sim.radio import RadioWatch, apply_radio_change, geometry_sample, radio_block, radio_change_problem
from cdus.sim.sensing import sense_tick
from cdus.sim.sink import UPDATE_EVERY, NullSink, Sink
from cdus.sim.summary import COMPLETED, link_block, run_metrics
from cdus.wire import keys
from cdus.wire.rejected import Rejected
from cdus.wire.messages import (
    COMMAND_OPS, MAX_LINK_AT, StateMsg, decode_control, decode_geometry, decode_states, encode_contacts,
    encode_control, encode_geometry, encode_states,
)
from cdus.wire.schemas import (
    ID_RE, MAX_REASON, MAX_TEXT as MAX_EVENT_TEXT, ORIGIN_WORLD, AgentStats, CommandReply, FleetEvent,
    MAX_SETTINGS_CHANGES, STATUS_KEY_ENV, StatusExtra, decode_stats, encode_event, encode_reply,
    encode_settings, encode_status, status_signature,
)
from cdus.wire.text import printable
from cdus.wire.transport import Transport, open_session

REALTIME_LAG = 8  # ticks the world waits before recording a realtime tick (> the telemetry batch)
STATUS_PERIOD = 1.0  # s
FAULT_TIMEOUT = 10.0  # s the launcher may take to carry out a fault
JOIN_TIMEOUT = 30.0  # s a restarted process may take to come up
STOP_GRACE_ALIVE_S = 0.5  # s a stop before the start waits for liveliness tokens already on their way
GRANT_RESEND = 0.5  # s: grants and start times are said again for processes that missed them
#: lockstep: a resumed or restarted process that has reported no tick this long (s) after its
#: catch-up gets the catch-up again (a resumed process whose session lapsed reconnects: the world
#: sees its token back before the router has its subscriptions again, and what it sent then was
#: lost; the process then waited for its roster for ever, and its neighbours for its ω)
CATCHUP_RESEND = 1.0
CATCHUP_RESEND_MAX = 8.0
#: realtime: a ground station's vehicle fault is answered when the launcher says it carried it
#: out; none within this (s): not carried out (a --remote vehicle, a launcher gone)
RT_FAULT_CONFIRM = 5.0
LINK_LEAD = 0.5  # s of simulated time between a link command and when it applies, if not given
INBOX_CAPACITY = 8192
RADIO_KEEP = 8  # radio geometry samples kept to send a (re)joining vehicle (it needs those in force from its join)
#: realtime: telemetry may be this far (s) ahead of the world's own clock (clock skew between
#: hosts, a batch sent at once); beyond it, a row is from a tick nobody can have stepped yet
REALTIME_SLACK = 1.0
#: the reject reasons of the agents' ω checks that say someone forges a vehicle's ω (docs/metrics.md)
SUSPECT_REASONS = ("future", "conflict", "implausible")
#: ... and those that say someone forges the world's own messages to the vehicles (an open fleet)
SUSPECT_WORLD_REASONS = ("radio_conflict",)
#: ... and those of the agents' watch of the world's liveliness token: a token on a key no process
#: declares (a wildcard, ``alive/**``), a second world token while the world's is up (docs/security.md)
SUSPECT_TOKEN_REASONS = ("token_key", "token_extra")
SUSPECT_EVERY = 5.0  # s: at most one suspect event per (vehicle, reason) in this time
#: s a lockstep world waits for a fleet that dropped all at once (the router or the network went,
#: not the vehicles: their processes keep their state) before it declares them lost. A router
#: frozen or restarted comes back in seconds, and the agents' sessions reconnect every <= 0.5 s
#: (cdus.wire.transport), so 30 s covers that with room; a fleet gone longer is not coming back.
OUTAGE_GRACE = 30.0
#: lockstep: the grant window is about this much wall time at the fleet's speed (measured every
#: HORIZON_EVERY s), so the vehicles rarely meet a grant, and a command that applies past every
#: grant (an operator's kill, link or gains) lands this soon
HORIZON_S = 0.25
HORIZON_EVERY = 0.25
DROP_WINDOW = 0.3  # s: liveliness losses this close together count as one (a lapsed router drops them all)
MAX_LOGGED_REJECTS = 200  # (sender, reason) pairs logged; beyond, counted only


class _Change(NamedTuple):
    """A run-time change the world sent to the vehicles (its ctl payload, numbered), kept for
    (re)joiners and world/settings."""

    kept_for: str | None  # one vehicle; None: every vehicle
    payload: bytes
    op: str
    tick: int | None  # a gains change's tick (None for the others, which are all replayed)


@dataclass(frozen=True)
class Verdict:
    """What the world made of one command: applied from ``tick`` (``t`` s of simulated time; a
    link change's exact time), or rejected with a reason (nothing changed). A command handler
    returns a Verdict, a reason string (rejected), None (applied from the next tick nobody has
    stepped) or LATER (a lockstep vehicle fault: Lockstep decides it, a Decided action answers)."""

    applied: bool
    reason: str = ""
    tick: int | None = None
    t: float | None = None

    @staticmethod
    def no(reason: str) -> "Verdict":
        return Verdict(False, reason)


LATER = Verdict(True, "decided when its tick comes")  # a sentinel: never sent as it is
MAX_WAITING = 1024  # queries held for a lockstep fault's decision; beyond, answered at once
MAX_QUEUED_QUERIES = 256  # command queries waiting for the main thread; beyond, answered busy at once
#: refused commands go to the event log (published, logged, kept in metrics.json) at most this
#: many at once, then REJECTED_EVENTS_PER_S: a flood of bad commands (each answered, each counted
#: in the rejects) is not amplified into as many events; the next one logged says how many were not
REJECTED_EVENTS_BURST = 20
REJECTED_EVENTS_PER_S = 1.0
#: the same for the changes commands made (gains, link, formation, path): a flood of valid commands
#: is not a flood of events either; each change is still made, answered and listed in world/settings
CHANGE_EVENTS_BURST = 20
CHANGE_EVENTS_PER_S = 1.0
#: commands from the ground credentials (every ground station together: Zenoh does not tell the
#: world which session asked, and they share the credentials), queries and puts alike: at most
#: COMMANDS_PER_S a second on average, COMMANDS_BURST at once; past it, answered at once, rejected
#: "busy: at most ... commands per second" and counted as `rate` (docs/ground_station.md)
COMMANDS_PER_S = 20.0
COMMANDS_BURST = 40
#: queries of the world's status, its settings and every vehicle's last telemetry (world/last/*, the
#: ground station's; not a restarting vehicle's own world/last/<id>): at most QUERIES_PER_S a second
#: on each of the three keys, QUERIES_BURST at once; past it, an error reply that says so, counted as
#: `query_rate` (any member of a fleet may ask them, and Zenoh does not tell the world who asked)
QUERIES_PER_S = 20.0
QUERIES_BURST = 40
#: command queries the main thread answers between two looks at the fleet (grants, recording): a
#: burst of them waits its turn rather than holding the fleet's ticks
ANSWERS_PER_PASS = 16
RATE_REFUSAL = (f"busy: at most {COMMANDS_PER_S:g} commands per second from the ground credentials "
                f"({COMMANDS_BURST} at once; a flood): try again")


def closest_live_pair(q: np.ndarray, live: np.ndarray, kinds: list[str], ids: list[str]) -> tuple | None:
    """(a, b, distance) of the closest pair of live vehicles of one kind at one instant (boats on
    the water in x, y; drones in 3-D, as cdus.core.metrics.min_separation), None without a pair
    at a finite distance. ``q``: (vehicles, 3) positions, ``live``: (vehicles,) bools."""
    best = None
    for kind, axes in (("usv", 2), ("uav", 3)):
        idx = [j for j, k in enumerate(kinds) if k == kind and live[j]]
        if len(idx) < 2:
            continue
        p = np.asarray(q, dtype=float)[idx, :axes]
        with np.errstate(invalid="ignore", over="ignore"):
            d = np.sqrt(((p[:, None, :] - p[None, :, :]) ** 2).sum(axis=-1))
        d[np.tril_indices(len(idx))] = np.inf  # each pair once, never a vehicle with itself
        d[~np.isfinite(d)] = np.inf
        a, b = np.unravel_index(int(np.argmin(d)), d.shape)
        if math.isfinite(d[a, b]) and (best is None or d[a, b] < best[2]):
            best = (ids[idx[a]], ids[idx[b]], float(d[a, b]))
    return best


@dataclass
class WorldState:
    """What the world has heard (main thread only)."""

    rows: dict[int, dict[int, StateMsg]] = field(default_factory=dict)  # tick -> sender -> row
    latest: dict[int, StateMsg] = field(default_factory=dict)
    acked: dict[int, int] = field(default_factory=dict)  # realtime: newest tick per sender
    alive: set[str] = field(default_factory=set)
    stats: dict[str, AgentStats] = field(default_factory=dict)  # the newest of each vehicle's process
    retired: list[AgentStats] = field(default_factory=list)  # the last of each process a restart replaced
    #: per vehicle, how many times its liveliness token went; and that count when its newest
    #: process's stats were first believed: a new process (incarnation) is believed only after
    #: the old one's token went, so stats forged with ever-new incarnations cannot pile up
    downs: dict[str, int] = field(default_factory=dict)
    downs_at_stats: dict[str, int] = field(default_factory=dict)
    latencies: LinkCounters = field(default_factory=LinkCounters)  # every sample the agents sent, thinned
    link_commanded: bool = False  # a ground station changed the link faults during the run
    link_changes: set[tuple[float, str, str]] = field(default_factory=set)
    rejects: Counter = field(default_factory=Counter)  # reason -> messages the world dropped

    @property
    def rejected(self) -> int:
        return sum(self.rejects.values())


@dataclass
class _CatchingUp:
    """A process caught up (lockstep), until it reports a tick past ``acked``."""

    acked: int  # the newest tick it had reported when caught up
    at: float  # monotonic s: say the catch-up again then
    join: int | None = None  # the join tick of a restart
    told: bool = False  # the log says it once
    every: float = CATCHUP_RESEND / 2  # s between resends, doubled each time (CATCHUP_RESEND_MAX at most)


class World:
    def __init__(self, scenario: Scenario, fleet: str, transport: Transport, clock: str = "lockstep",
                 duration: float | None = None, metrics_out: str | None = None, trace_out: str | None = None,
                 start_timeout: float = 60.0, log: Callable[[str], None] | None = None, sink: Sink | None = None,
                 policy: str | None = None, run_dir: str | None = None):
        self.scenario = scenario
        self.fleet = keys.check_fleet(fleet)
        self.transport = transport
        self.clock = clock
        self.ids = list(scenario.ids)
        self.index = {vid: j for j, vid in enumerate(self.ids)}
        self.period = 1.0 / scenario.rates.control
        self.duration = scenario.duration if duration is None else duration
        self.last_tick = total_ticks(self.duration, self.period)
        self.metrics_out = metrics_out
        self.trace_out = trace_out
        self.run_dir = run_dir  # where the metrics go when metrics_out cannot be written (metrics_fallbacks)
        #: the outputs not written where asked (a full disk): "the metrics" / "the trace"; the
        #: world then exits METRICS_ELSEWHERE_EXIT (run_world)
        self.not_written: list[str] = []
        self.start_timeout = start_timeout
        self.sink = sink or NullSink()
        self.sink.on_stop = self._recording_stopped  # a file recording that stops (a full disk) is said as the run goes on
        self.policy = policy or scenario.link.policy
        self._link_table = scenario.link_table  # the [link] table as run-time commands have left it
        self.recorder = Recorder(self.ids, [v.dim for v in scenario.vehicles], metric_edges(scenario))
        self.recorder.set_formation(formation_schedule(scenario), self.period)  # measured against the offsets in force
        #: the scenario's formation and path changes, reported when their tick is recorded
        self._change_events = scheduled_change_events(scenario, self.period)
        self.events_scheduled = scenario.events
        self.sensing = sensor_schedule(scenario)  # (every, latency) ticks, None: no proximity sensor
        self.radio = radio_schedule(scenario)  # (every, lag) ticks, None: no [radio]
        self._dims = [v.dim for v in scenario.vehicles]  # a geometry entry has the vehicle's dimension
        self._radio_rows: dict[int, dict[int, tuple]] = {}  # radio sample tick -> vehicle -> q (lockstep)
        self._radio_sent: deque[tuple[int, bytes]] = deque(maxlen=RADIO_KEEP)  # newest samples, for joiners
        self._next_radio = 0  # realtime: the next radio sample tick
        #: the world's own channel: utilisation, link probabilities and splits of each sample
        self.radio_watch = None if self.radio is None else RadioWatch(
            self.ids, [(e.i, e.k) for e in scenario.edges], radio_channel_for(scenario), self.period)
        self.lockstep = Lockstep(self.ids, self.period, self.last_tick, self.events_scheduled,
                                 sense_every=self.sensing[0] if self.sensing else None,
                                 sense_latency=self.sensing[1] if self.sensing else 1,
                                 radio_every=self.radio[0] if self.radio else None,
                                 radio_lag=self.radio[1] if self.radio else 1)
        self._sample_rows: dict[int, dict[int, tuple]] = {}  # sample tick -> vehicle -> q (lockstep)
        self._next_sample = 0  # realtime: the next sample tick
        self._realtime_faults = list(scenario.events)  # realtime: carried out when their time comes
        self.st = WorldState()
        self.pairs = [(e.i, e.k) for e in scenario.edges]
        #: run-time commands (link, radio, gains, formation, path), for (re)joiners and world/settings;
        #: each carries a number of its own (``seq``) so a process that hears it again applies it once
        self._commands: list[_Change] = []
        self._seq = 0  # the next command's seq
        self._settings_from: tuple = ()  # what the settings reply is made of now (_settings_changed)
        self._settings_cache: tuple[tuple, bytes] | None = None  # (made of, reply): made on a query
        self._settings_changed("")
        self._status_payload: bytes | None = None  # the newest status published (_publish_status)
        #: the launcher's per-run key (STATUS_KEY_ENV): each status is signed with it, so the
        #: launcher tells this world's statuses from forged ones; None: started by hand, unsigned
        self._status_key = _status_key(os.environ.get(STATUS_KEY_ENV))
        self._console = ConsoleQuota(scenario=scenario)
        self._rt_expect: dict[str, set[str]] = {}  # realtime: liveliness changes a fault we asked for explains
        self._faulted: dict[str, str] = {}  # "killed" | "paused", by the faults carried out (both clocks)
        self.log = log or _say
        self.next_tick = 0  # next tick to record
        self._initial: dict[int, StateMsg] = {}  # vehicle -> its state before its first tick (made when needed)
        self.events: list[FleetEvent] = []
        self.started = False
        self.cpu_s = 0.0  # CPU time of the process over the run
        self.finished = False
        self.stop_requested = False
        self._stop_tick: int | None = None  # the tick a stop command said the run ends after
        self.paused_at: float | None = None  # realtime: wall time of a fleet pause
        self.t0: float | None = None
        self.session: Any = None
        self._fault_since: float | None = None
        self._catching: dict[int, _CatchingUp] = {}  # lockstep: caught-up processes not heard from since
        #: realtime: vid -> (query ref, action, monotonic deadline) of the faults the launcher has not
        #: yet said it carried out, oldest first (ref None: the scenario's, nobody waits: the
        #: launcher says `fault_done` for each fault in the order asked, theirs too)
        self._rt_asked: dict[str, deque[tuple[object | None, str, float]]] = {}
        self._t_start = 0.0
        self._lock = threading.Lock()  # guards st.latest for the queryable's thread
        self._alive_news: deque[tuple[str, bool]] = deque()  # liveliness callbacks (key, up) -> main thread
        self.zid: str | None = None  # this process's Zenoh session id (its token's key ends with it)
        self._token_of: dict[str, str] = {}  # vehicle -> the session id of the token taken as its process's
        self._not_taken: set[str] = set()  # session ids of tokens refused once: never taken afterwards
        #: what may have altered the run, by reason (docs/metrics.md, ``integrity``), and the first of each
        self.integrity: Counter = Counter()
        self._integrity_notes: dict[str, str] = {}
        self._logged_rejects: set[tuple[str, str]] = set()
        self._recorded: dict[int, StateMsg] = {}  # the row each vehicle was last recorded with
        #: per vehicle, its processes' filter interventions as last reported (stats, every ~1 s of
        #: wall time): what the recorder's rows carry, so the marks in Rerun lag the counts by that much
        self._interventions = [0] * len(self.ids)
        self._suspect_seen: dict[tuple[str, str], float] = {}  # (vehicle, reason) -> last suspect event
        self._drops_since: float | None = None  # monotonic time of the first undecided liveliness loss
        self._outage_since: float | None = None  # the whole fleet dropped at once: waiting for it
        self.completion: str | None = None  # why the run ended early (docs/metrics.md, completion)
        self.outage_grace = OUTAGE_GRACE
        self._rt_lost: set[str] = set()  # realtime: lost with nobody asking, not back
        self._queries: deque[Any] = deque()  # command queries -> main thread
        self._waiting: dict[int, tuple[Any, str, str]] = {}  # ref -> (query, op, by): lockstep faults
        self._next_ref = 0
        #: what Zenoh's threads refused (busy, rate, query_rate), moved into st.rejects by the main thread
        self._refused_offthread: Counter[str] = Counter()
        self._refused_moved: Counter[str] = Counter()
        self._quota_clock = time.monotonic  # the quotas' clock
        now = self._quota_clock()
        self._quota_lock = threading.Lock()  # the quotas Zenoh's threads take
        self._command_quota = Quota(COMMANDS_PER_S, COMMANDS_BURST, now)
        self._ground_key = keys.world_command(self.fleet, keys.GROUND)  # the key the quota is for
        self._query_quotas = {name: Quota(QUERIES_PER_S, QUERIES_BURST, now) for name in ("status", "settings", "last")}
        #: events a flood may not multiply (kind -> quota): refused commands, changes made by command
        self._event_quotas = {"rejected": Quota(REJECTED_EVENTS_PER_S, REJECTED_EVENTS_BURST, now),
                              "change": Quota(CHANGE_EVENTS_PER_S, CHANGE_EVENTS_BURST, now)}
        self._command_ref: int | None = None  # the ref of the command being handled, if it asked
        self._current_op = ""  # the op of the command being handled
        #: op -> handler(fields, by) -> Verdict | reason str | None | LATER (see Verdict); other
        #: parts add theirs here (formation, path, radio)
        self.command_handlers: dict[str, Callable[[dict, str], Any]] = {
            "stop": self._cmd_stop, "pause": self._cmd_pause, "resume": self._cmd_resume,
            "set_gains": self._cmd_gains, "link": self._cmd_link, "fault_done": self._cmd_fault_done,
            "formation": self._relay_formation, "path": self._relay_path, "radio": self._cmd_radio,
            "kill": self._cmd_vehicle_fault, "pause_vehicle": self._cmd_vehicle_fault,
            "resume_vehicle": self._cmd_vehicle_fault, "restart": self._cmd_vehicle_fault,
        }

    # ------------------------------------------------------------------ wiring
    def open(self) -> None:
        s = self.session = open_session(self.transport)
        f = self.fleet
        self.inbox = s.declare_subscriber(keys.inbox(f, keys.WORLD), zenoh.handlers.FifoChannel(INBOX_CAPACITY))
        # Everything the vehicles and the launcher act on blocks rather than drops under congestion
        # (Zenoh's default for a put is to drop): a grant, a roster change, a join, a command, a
        # proximity sample or a fault request lost would change the run (_put). Blocking waits
        # only for room in this session's queue to the router, which the router drains whatever
        # the receivers do (it holds a message for a full link at most wait_before_close, then
        # closes that link: cdus.wire.transport.BLOCK_BEFORE_CLOSE), as the grants always have.
        # The status (said again every second) and the events (kept whole in metrics.json) drop.
        block = zenoh.CongestionControl.BLOCK
        self.pub_ctl = s.declare_publisher(keys.ctl(f, self.ids), congestion_control=block)
        self.pub_launcher = s.declare_publisher(keys.launcher_cmd(f), congestion_control=block)
        self.pub_radio = (s.declare_publisher(keys.radio(f, self.ids), congestion_control=zenoh.CongestionControl.BLOCK)
                          if self.radio is not None else None)
        self.pub_status = s.declare_publisher(keys.world_status(f))
        self.pub_events = s.declare_publisher(keys.world_events(f))
        wake = s.declare_publisher(keys.wake(f, keys.WORLD), allowed_destination=zenoh.Locality.SESSION_LOCAL)
        self._wake = lambda payload=b"": wake.put(payload)
        # liveliness and the last-state queries are rare: callbacks that hand over to the main thread
        self._subs = [
            s.liveliness().declare_subscriber(keys.any_alive(f), self._on_alive_sample, history=True),
            s.declare_queryable(keys.world_last(f, "*"), self._on_last_query),
            s.declare_queryable(keys.world_settings(f), self._on_settings_query),
            s.declare_queryable(keys.world_status(f), self._on_status_query),
            s.declare_queryable(keys.any_world_command(f), self._on_command_query),
        ]
        self.zid = str(s.zid())
        self.token = s.liveliness().declare_token(keys.alive(f, keys.WORLD, self.zid))
        self._ticker = threading.Thread(target=self._tick_thread, daemon=True, name="ticker")
        self._ticker.start()
        self.log(f"ready: fleet {f!r}, {len(self.ids)} vehicles, clock {self.clock}, "
                 f"{self.duration:g} s at {self.scenario.rates.control:g} Hz")

    def close(self) -> None:
        if self.session is None:
            return
        self._answer_the_rest("the world is shutting down: the run is over")
        try:
            self.token.undeclare()
            self.session.close()
        except zenoh.ZError as e:
            self.log(f"while closing the session: {e}")
        self.session = None

    def _tick_thread(self) -> None:
        """Wakes the main loop a few times a second (status, re-sent grants, timeouts)."""
        while self.session is not None and not self.finished:
            time.sleep(min(0.25, self.period * 5) if self.clock == "realtime" else 0.25)
            try:
                self._wake()
            except zenoh.ZError:
                return

    def _on_alive_sample(self, sample: Any) -> None:
        """Liveliness news (Zenoh's thread): queued for the main thread (:meth:`_on_token`), which a
        wake fetches. The wake carries nothing: the news never travels over the wire."""
        self._alive_news.append((str(sample.key_expr), not str(sample.kind).endswith("DELETE")))
        try:
            self._wake()
        except zenoh.ZError:
            pass

    def request_stop(self) -> None:
        self.stop_requested = True
        self._wake()

    def _over_quota(self, quota: Quota, reason: str) -> bool:
        """Zenoh's thread: has the asker of a query gone past ``quota``? Counted as ``reason``."""
        with self._quota_lock:
            if quota.take(self._quota_clock()):
                return False
            self._refused_offthread[reason] += 1
            return True

    def _query_refused(self, query: Any, name: str, key: str) -> bool:
        """A query of the world's status, settings or every vehicle's last telemetry past its
        quota (QUERIES_PER_S): answered at once with an error reply that says so, counted."""
        if not self._over_quota(self._query_quotas[name], "query_rate"):
            return False
        try:
            query.reply_err(f"busy: at most {QUERIES_PER_S:g} queries per second on {key} "
                            f"(a flood); try again".encode())
        except zenoh.ZError:
            pass
        return True

    def _on_last_query(self, query: Any) -> None:
        """A restarted agent asks where its vehicle was: reply with its newest telemetry. A ground
        station asks ``world/last/*``: one reply per vehicle heard from (on its own key), at most
        QUERIES_PER_S such queries a second (a vehicle's own key has no quota: a flood on it must
        not keep a restarting vehicle from where it was; its reply is one row)."""
        vid = str(query.key_expr).rsplit("/", 1)[-1]
        wanted = self.ids if vid in ("*", "**") else [vid] if vid in self.index else []
        if len(wanted) > 1 and self._query_refused(query, "last", keys.world_last(self.fleet, "*")):
            return
        with self._lock:
            rows = [(v, self.st.latest.get(self.index[v])) for v in wanted]
        for v, m in rows:
            if m is not None:
                query.reply(keys.world_last(self.fleet, v), encode_states([m]))

    def _on_status_query(self, query: Any) -> None:
        """A ground station attaching asks for the status at once rather than wait up to a second
        for the next one: the newest published (none before the first)."""
        payload = self._status_payload
        if payload is not None and not self._query_refused(query, "status", keys.world_status(self.fleet)):
            query.reply(keys.world_status(self.fleet), payload)

    def _on_settings_query(self, query: Any) -> None:
        """A ground station asks what the run's settings are now (``gs snapshot``): the reply is
        made here, on the first query after a change, from what the main thread last said the
        settings are made of (:meth:`_settings_changed`), and kept for the next queries. A change
        costs the main thread no encoding (it cost the whole list's at each change: a flood of
        commands was quadratic)."""
        if self._query_refused(query, "settings", keys.world_settings(self.fleet)):
            return
        made_of = self._settings_from
        cached = self._settings_cache
        if cached is None or cached[0] is not made_of:
            count, phases, link = made_of[1:]
            kept = self._commands[max(0, count - MAX_SETTINGS_CHANGES):count]  # one atomic slice (the GIL)
            cached = (made_of, encode_settings([(c.kept_for, c.payload) for c in kept], phases, link, total=count))
            self._settings_cache = cached
        query.reply(keys.world_settings(self.fleet), cached[1])

    def _settings_changed(self, op: str) -> None:
        """Main thread, at each change: what the settings reply is made of now (a new tuple, which
        a query reads whole): the number of changes listed, the phases (made again only when a
        change can move them) and the [link] table in force. O(1) for a gains change."""
        old = self._settings_from
        if op in ("gains", "link", "radio") and old:
            phases = old[2]
        else:
            phases = (tuple(zip(self.ids, self.recorder.formation.phases_at(2**62)))
                      if self.recorder.formation is not None else ())
        self._settings_from = (object(), len(self._commands), phases, self._link_table)

    def _on_command_query(self, query: Any) -> None:
        """A command as a query (Zenoh's thread): handed to the main thread, which answers it. Past
        the ground credentials' rate (COMMANDS_PER_S) or MAX_QUEUED_QUERIES waiting (a flood),
        answered at once: rejected, busy."""
        # the ground credentials' key only: a query on world/** (an open fleet, or a vehicle's if the
        # router lets it through) must not spend the ground stations' rate; the main thread refuses it
        if str(query.key_expr) == self._ground_key and self._over_quota(self._command_quota, "rate"):
            self._reply(query, "?", "", Verdict.no(RATE_REFUSAL))
            return
        if len(self._queries) >= MAX_QUEUED_QUERIES:
            with self._quota_lock:
                self._refused_offthread["busy"] += 1
            self._reply(query, "?", "", Verdict.no("busy: too many commands waiting; try again"))
            return
        self._queries.append(query)
        try:
            self._wake()
        except zenoh.ZError:
            pass

    # ------------------------------------------------------------------ receiving
    def _drain(self, block: bool) -> None:
        """Handle what is waiting (and, if ``block`` and no command waits, wait for at least one
        sample), then answer at most ANSWERS_PER_PASS of the command queries waiting: the rest
        wait for the next pass, after the fleet's grants and recording."""
        if block and not self._queries:
            self._handle(self.inbox.recv(), answer=False)
        while (sample := self.inbox.try_recv()) is not None:
            self._handle(sample, answer=False)
        self._answer_waiting()

    def _handle_alive_news(self) -> None:
        while self._alive_news:
            key, up = self._alive_news.popleft()
            self._on_token(key, up)

    def _handle(self, sample: Any, answer: bool = True) -> None:
        """One sample of the inbox (anything anyone can put on a key addressed to the world):
        handled, or counted by reason and dropped. Never raises. ``answer``: then answer command
        queries waiting (at most ANSWERS_PER_PASS)."""
        try:
            self._dispatch(sample)
        except Exception as e:  # a bug of ours, not the sender's: counted, logged once, the run goes on
            self._reject("?", "internal", f"{type(e).__name__}: {e}")
        self._handle_alive_news()
        if answer:
            self._answer_waiting()

    def _answer_waiting(self) -> None:
        """Answer at most ANSWERS_PER_PASS command queries, oldest first; count what Zenoh's
        threads refused meanwhile."""
        for _ in range(min(ANSWERS_PER_PASS, len(self._queries))):
            self._answer(self._queries.popleft())
        with self._quota_lock:
            refused = +self._refused_offthread
        if refused != self._refused_moved:
            self.st.rejects.update(refused - self._refused_moved)
            self._refused_moved = refused

    def _dispatch(self, sample: Any) -> None:
        key = str(sample.key_expr)
        parts = key.split("/")
        kind, src = keys.leaf(key)
        if kind == "wake":
            return  # the ticker, or liveliness news (queued by _on_alive_sample)
        payload = sample.payload.to_bytes()
        if kind not in ("state", "stats", "cmd") or len(parts) != 6 or parts[1] != self.fleet:
            return self._reject("?", "key")
        if kind == "state":
            self._on_state(src, payload)
        elif kind == "stats":
            self._on_stats(src, payload)
        else:
            self._on_command(src, payload)

    def _reject(self, sender: str, reason: str, detail: str = "") -> None:
        """Count a dropped message by reason; log the first of each (sender, reason)."""
        self.st.rejects[reason] += 1
        pair = (sender[:64], reason)
        if pair in self._logged_rejects or len(self._logged_rejects) > MAX_LOGGED_REJECTS:
            return
        self._logged_rejects.add(pair)
        more = "" if len(self._logged_rejects) <= MAX_LOGGED_REJECTS else " (further senders are counted only)"
        self.log(f"rejected from {printable(sender, 64)}: {reason}"
                 + (f" ({printable(detail, 200)})" if detail else "") + more)

    def _tick_limit(self) -> int:
        """The newest tick a vehicle can have stepped: the grant (lockstep), the wall clock's tick
        plus REALTIME_SLACK (realtime; before the start, the first ticks)."""
        if self.clock == "lockstep":
            return self.lockstep.granted
        return self._tick_now() + math.ceil(REALTIME_SLACK / self.period)

    def _on_state(self, vid: str, payload: bytes) -> None:
        if vid not in self.index:
            return self._reject(vid, "unknown_sender")
        rows = decode_states(payload, len(self.ids))
        if isinstance(rows, Rejected):
            return self._reject(vid, rows.reason)
        j = self.index[vid]
        if any(m.sender != j for m in rows):
            return self._reject(vid, "sender_mismatch")
        limit = self._tick_limit()
        if any(m.tick > limit for m in rows):  # the whole batch: it cannot all be genuine
            return self._reject(vid, "future", f"tick {max(m.tick for m in rows)} > {limit}")
        st = self.st
        by_tick, first, every = st.rows, self.next_tick, self.sensing[0] if self.sensing is not None else 0
        newest = None  # the batch's newest row taken: latest, acked and the report once per batch
        for m in rows:
            if m.tick >= first:
                have = by_tick.setdefault(m.tick, {}).setdefault(j, m)
                if have is not m and have != m:  # a second, different row for a tick: the first stands
                    self._reject(vid, "conflict", f"tick {m.tick}")
                    continue
            if every and m.tick % every == 0 and m.tick > self.lockstep.sensed:
                self._sample_rows.setdefault(m.tick, {}).setdefault(j, m.q)
            if (self.radio is not None and self.clock == "lockstep" and m.tick % self.radio[0] == 0
                    and m.tick > self.lockstep.radioed):  # realtime samples from the newest telemetry
                self._radio_rows.setdefault(m.tick, {}).setdefault(j, m.q)
            if newest is None or m.tick >= newest.tick:
                newest = m
        if newest is None:
            return
        prev = st.latest.get(j)
        if prev is None or newest.tick >= prev.tick:
            with self._lock:
                st.latest[j] = newest
        st.acked[j] = max(st.acked.get(j, -1), newest.tick)
        self.lockstep.on_report(j, newest.tick)

    def _on_stats(self, vid: str, payload: bytes) -> None:
        if vid not in self.index:
            return self._reject(vid, "unknown_sender")
        s = decode_stats(payload, self.index)
        if isinstance(s, Rejected):
            return self._reject(vid, s.reason)
        if s.id != vid:
            return self._reject(vid, "sender_mismatch")
        old = self.st.stats.get(vid)
        if old is not None and old.incarnation != s.incarnation:  # a restarted process: its counters start anew
            if self.st.downs.get(vid, 0) == self.st.downs_at_stats.get(vid, 0):  # the old one never went away
                return self._reject(vid, "incarnation")  # forged (a genuine restart's next report is believed)
            self.st.retired.append(old)
            old = None
        if old is None:
            self.st.downs_at_stats[vid] = self.st.downs.get(vid, 0)
        self.st.stats[vid] = s
        j = self.index[vid]
        self._interventions[j] = s.interventions + sum(x.interventions for x in self.st.retired if x.id == vid)
        for x in s.latencies_ms:  # each message carries the samples since the previous one
            self.st.latencies.record_latency(x / 1000.0)
        if s.faults is not None:
            self._forward_link_changes(s.faults)
        for b in s.bursts:  # rebuilt by the decoder from its numbers and ids
            self._note(b.event(origin=vid))
        self._suspects(vid, s, old)

    def _suspects(self, vid: str, s: AgentStats, old: AgentStats | None) -> None:
        """A vehicle that counts new ω it cannot trust (from beyond its sender's possible seq, a
        second different message for a seq, a jump its dynamics cannot make) or a second, different
        radio geometry sample for a tick (someone else speaks as the world): a ``suspect``
        event, at most one per (vehicle, reason) per SUSPECT_EVERY seconds."""
        now = time.monotonic()
        for reason in SUSPECT_REASONS + SUSPECT_WORLD_REASONS + SUSPECT_TOKEN_REASONS:
            new = s.rejected_by_reason.get(reason, 0) - (old.rejected_by_reason.get(reason, 0) if old else 0)
            last = self._suspect_seen.get((vid, reason))
            if new <= 0 or last is not None and now - last < SUSPECT_EVERY:
                continue
            self._suspect_seen[(vid, reason)] = now
            what = ("ω" if reason in SUSPECT_REASONS else "radio geometry not the world's"
                    if reason in SUSPECT_WORLD_REASONS else "a liveliness token not the world's")
            self._note(FleetEvent.of(self._sim_now(), "suspect",
                                     f"{vid} received {what} it cannot trust: {new} new {reason!r} rejects "
                                     f"({s.rejected_by_reason[reason]} in all)", vehicle=vid, origin=vid))

    def _forward_link_changes(self, faults: dict) -> None:
        """New link state changes an agent reports (checked by decode_stats): to the event log and
        the recording."""
        for ch in faults["state_changes"]:
            key = (ch["t"], ch["link"], ch["state"])
            if key in self.st.link_changes:
                continue
            self.st.link_changes.add(key)
            src, _, dst = key[1].partition("->")
            self.sink.link_state(key[0], src, dst, key[2])
            if self.started:
                self._note(link_state_event(*key))

    # ------------------------------------------------------------------ commands
    def _answer(self, query: Any) -> None:
        """A command query (main thread): decide it, answer it (a lockstep vehicle fault: once
        Lockstep decides it, see _act), never raise."""
        parts = str(query.key_expr).split("/")
        sender = parts[4] if len(parts) == 5 and parts[1] == self.fleet and parts[2:4] == ["world", "cmd"] else "?"
        payload = query.payload.to_bytes() if query.payload is not None else b""
        ref = self._next_ref
        self._next_ref += 1
        waiting = len(self._waiting) < MAX_WAITING
        try:
            if sender != keys.GROUND:  # the launcher puts; by query, only ground stations command
                self._reject(sender, "sender")
                op, by, verdict = "?", "", Verdict.no(f"commands by query are asked as {keys.GROUND!r} "
                                                      f"({keys.world_command(self.fleet, keys.GROUND)})")
            else:
                op, by, verdict = self._command(sender, payload, ref if waiting else None)
        except Exception as e:  # a bug of ours: the asker hears it, the run goes on
            self._reject(sender, "internal", f"{type(e).__name__}: {e}")
            op, by, verdict = "?", sender, Verdict.no(f"internal error in the world: {type(e).__name__}")
        if verdict is LATER:
            self._waiting[ref] = (query, op, by)
            return
        self._reply(query, op, by, verdict)

    def _reply(self, query: Any, op: str, by: str, v: Verdict) -> None:
        t = v.t if v.t is not None else (None if v.tick is None else v.tick * self.period)
        reply = CommandReply("applied" if v.applied else "rejected", op, printable(v.reason, MAX_REASON),
                             v.tick if v.applied else None, t if v.applied else None, by if ID_RE.match(
                                 by.replace(":", "_", 1)) else "")
        try:
            query.reply(str(query.key_expr), encode_reply(reply))
        except zenoh.ZError as e:  # the asker left (a ground station killed mid-command): nothing to tell
            self.log(f"could not answer {by}'s {op}: {printable(str(e), 120)}")
        finally:
            query.drop()

    def _decided(self, a: Decided) -> None:
        """Lockstep decided a vehicle fault a ground station waits on."""
        waiting = self._waiting.pop(a.ref, None)
        if waiting is not None:
            query, op, by = waiting
            self._reply(query, op, by, Verdict(True, "", a.tick) if a.reason is None else Verdict.no(a.reason))

    def _answer_the_rest(self, reason: str) -> None:
        """At the end: every query still waiting is answered (rejected: its fault never came)."""
        undecided = dict(self.lockstep.undecided())
        for ref, (query, op, by) in list(self._waiting.items()):
            tick = undecided.get(ref)
            self._reply(query, op, by, Verdict.no(reason + ("" if tick is None else f" (before its tick {tick})")))
        self._waiting.clear()
        self._rt_asked.clear()
        while self._queries:
            q = self._queries.popleft()
            self._reply(q, "?", "", Verdict.no(reason))

    def _on_command(self, sender: str, payload: bytes) -> None:
        """A command put on ``to/+world+/cmd/<sender>`` (the launcher, older clients): carried out
        as a query's would be; nobody is told the verdict (a vehicle fault is decided likewise). The
        ground credentials' puts share their queries' rate (COMMANDS_PER_S): past it, counted as
        `rate` and dropped."""
        if sender == keys.GROUND and self._over_quota(self._command_quota, "rate"):
            return
        self._command(sender, payload, None)

    def _command(self, sender: str, payload: bytes, ref: int | None) -> tuple[str, str, Verdict]:
        """Decide one command: (op, who sent it, verdict). Bad input is counted by reason."""
        if not ID_RE.match(sender):
            self._reject(sender, "key")
            return "?", "", Verdict.no("the command's key names no sender")
        c = decode_control(payload, COMMAND_OPS)
        if isinstance(c, str):
            self._reject(sender, c)
            return "?", sender, Verdict.no(f"the command could not be read: {c}")
        by = sender if c.name is None else f"{sender}:{c.name}"
        if c.op == "fault_done" or c.op == "stop" and sender == keys.LAUNCHER:
            pass  # the launcher's own, whatever the run's state
        elif self.stop_requested or self.finished:
            return c.op, by, Verdict.no("the run is over" if self.finished else "the run is stopping")
        handler = self.command_handlers.get(c.op)
        if handler is None:
            self._reject(sender, "unknown_op")
            return c.op, by, Verdict.no(f"this world does not carry out {c.op!r}")
        self._command_ref, self._current_op = ref, c.op
        try:
            out = handler(c.fields, by)
        finally:
            self._command_ref, self._current_op = None, ""
        if out is LATER:  # decided later; with nobody waiting, said applied from the next tick
            return c.op, by, LATER if ref is not None else Verdict(True, out.reason, self._effect_tick())
        if out is None:
            out = Verdict(True, "", self._effect_tick())
        elif isinstance(out, str):
            out = Verdict.no(out)
        return c.op, by, out

    def _effect_tick(self) -> int:
        """The first tick a command can change: one nobody has been granted (lockstep), the wall
        clock's next (realtime)."""
        return self.lockstep.granted + 1 if self.clock == "lockstep" else self._tick_now() + 1

    def _cmd_stop(self, f: dict, by: str) -> Verdict | str:
        if self.stop_requested:
            return "the run is stopping"
        # the launcher asks only when it was interrupted (Ctrl-C, SIGTERM); anyone else's stop is an operator's
        interrupted = by == keys.LAUNCHER
        self._note(FleetEvent.of(self._sim_now(), "fleet", "fleet stopped: the launcher was interrupted"
                                 if interrupted else f"fleet stopped by {by}"))
        self.completion = self.completion or ("interrupted" if interrupted else "stopped")
        self.stop_requested = True
        # the tick of the event (and of the run's last record): the answer said the next one, a tick later
        tick = round(self._sim_now() / self.period)
        self._stop_tick = tick
        return Verdict(True, "the run ends after this tick: its metrics are written", tick)

    def _cmd_fault_done(self, f: dict, by: str) -> Verdict | str:
        if by != keys.LAUNCHER:
            self._reject(by, "sender")
            return "only the launcher reports a fault carried out"
        if f["vehicle"] in self.index:
            self.lockstep.on_fault_done(self.index[f["vehicle"]])
            if self.clock != "lockstep":
                self._rt_fault_done(f["vehicle"])
        return Verdict(True, "", max(0, self.lockstep.granted))

    def _cmd_pause(self, f: dict, by: str) -> Verdict | str | None:
        return self._fleet_pause(True, by)

    def _cmd_resume(self, f: dict, by: str) -> Verdict | str | None:
        return self._fleet_pause(False, by)

    def _cmd_gains(self, f: dict, by: str) -> Verdict | str:
        return self._relay_gains(f["gains"], f["vehicle"], by)

    def _cmd_link(self, f: dict, by: str) -> Verdict | str:
        if f["at"] >= self.duration:  # it would be answered "applied" and never apply
            return self._refuse(by, "link", "link command",
                                f"--at {f['at']:g} s is not before the end of the run ({self.duration:g} s): "
                                "it would change nothing; give a time within the run")
        merged = merge_link_tables(self._link_table, f["link"])
        try:  # the agents' own checks, made before relaying: a change they would refuse is no change
            if f["at"] > MAX_LINK_AT:
                raise ValueError(f"link command: at = {f['at']:.6g} s is beyond the latest time a link change "
                                 f"may name ({MAX_LINK_AT:g} s of simulated time)")
            validate_link(merged, self.ids, "link command")
        except (ConfigError, ValueError) as e:
            self._reject(by, "link")
            self._note(FleetEvent.of(self._sim_now(), "rejected",
                                     f"link command from {printable(by, 64)}: {printable(str(e), 200)}"))
            return printable(str(e), 280)
        # Never before what a vehicle may already have sent (lockstep: past the grant), so
        # every receiver applies it from the same message on; a past --at means "now".
        earliest = ((self.lockstep.granted + 1) * self.period if self.clock == "lockstep"
                    else self._sim_now() + self.period)
        at = max(f["at"], earliest) if f["at"] >= 0 else max(self._sim_now() + LINK_LEAD, earliest)
        late = self._never_applies(max(0, math.ceil(at / self.period - 1e-9)))
        if late:
            return self._refuse(by, "link", "link command", late)
        self._link_table = merged
        self._send_command(None, None, "link", link=f["link"], at=float(at))
        self.st.link_commanded = True
        self._note(FleetEvent.of(self._sim_now(), "link_changed",
                                 f"link faults changed from t = {at:.2f} s by {by}: {printable(f['link'], 200)}"),
                   by_command=True)
        late = (f"t = {f['at']:g} s asked had passed: from the first time every receiver can take it"
                if 0 <= f["at"] < at else "")
        return Verdict(True, late, max(0, math.ceil(at / self.period - 1e-9)), float(at))

    def _cmd_vehicle_fault(self, f: dict, by: str) -> Verdict | str:
        """kill | pause_vehicle | resume_vehicle | restart, by the op in the fields' command."""
        vid = f["vehicle"]
        if vid not in self.index:
            self._reject(by, "unknown_vehicle")
            return f"no vehicle {printable(vid, 64)!r} in this fleet (its vehicles: {', '.join(self.ids)})"
        op = self._current_op
        action = {"pause_vehicle": "pause", "resume_vehicle": "resume"}.get(op, op)
        if self.clock == "lockstep":
            tick = self.lockstep.vehicle_fault(action, self.index[vid], by=by, ref=self._command_ref)
            return LATER if self._command_ref is not None else Verdict(True, "", tick)
        moot = self._rt_moot(vid, action)
        if moot:
            self._note(FleetEvent.of(self._sim_now(), "rejected", f"{action} of {vid} by {by}: {moot}", vehicle=vid))
            return moot
        self.pub_launcher.put(encode_control(op, vehicle=vid))
        self._expect_news(vid, action)
        self._note(FleetEvent.of(self._sim_now(), "fault", f"{action} of {vid} by {by}", vehicle=vid))
        # every fault asked holds its place (the launcher says fault_done for each, in order): one
        # put or past MAX_WAITING, nobody waiting (ref None), too, or its word answers a later query
        self._rt_asked.setdefault(vid, deque()).append((self._command_ref, action,
                                                        time.monotonic() + RT_FAULT_CONFIRM))
        if self._command_ref is not None:  # answered when the launcher says it is done (_rt_fault_done)
            return LATER
        return Verdict(True, "realtime: the launcher carries it out now", self._tick_now())

    def _rt_fault_done(self, vid: str) -> None:
        """Realtime: the launcher carried out a fault on ``vid``: the oldest ground station's
        fault on it waiting is answered, applied from the present tick."""
        waiting = self._rt_asked.get(vid)
        if waiting:
            ref, _, _ = waiting.popleft()
            if ref is not None:  # else a scheduled fault's: not a ground station's answer
                self._decided(Decided(ref, self._tick_now()))

    def _rt_faults_unconfirmed(self, now: float) -> None:
        """Realtime: the ground stations' faults the launcher has not confirmed in RT_FAULT_CONFIRM s
        are answered: not carried out."""
        for vid, waiting in self._rt_asked.items():
            while waiting and waiting[0][2] <= now:
                ref, action, _ = waiting.popleft()
                if ref is None:  # a scheduled fault's (the launcher's log says why it was not done)
                    continue
                why = (f"the launcher did not say it carried out the {action} of {vid} within "
                       f"{RT_FAULT_CONFIRM:g} s: not done here (a vehicle started with --remote on another "
                       "host is faulted there; see the launcher's log)")
                self._note(FleetEvent.of(self._sim_now(), "fault_missed", f"the {action} of {vid} was not "
                                         "confirmed by the launcher", vehicle=vid))
                self._decided(Decided(ref, self._tick_now(), why))

    def _relay_radio(self, fields: dict, sender: str) -> Verdict | str | None:
        """A ground station's radio change ``{"radio": {tx_power, station}, "at": s}``: checked,
        then relayed to every vehicle with the send time it applies from, never before what a
        vehicle may already have sent (lockstep: past the grant; a past ``at`` means as soon as
        possible), like a link command. The verdict (applied from that time), else why it was not."""
        change = fields["radio"]
        if self.radio is None:
            return "this scenario has no [radio] table"
        problem = radio_change_problem(change, self.radio_watch.channel.spec.topology)
        if problem is not None:
            return problem
        earliest = ((self.lockstep.granted + 1) * self.period if self.clock == "lockstep"
                    else self._sim_now() + self.period)
        at = max(fields["at"], earliest) if fields["at"] >= 0 else max(self._sim_now() + LINK_LEAD, earliest)
        end = self.last_tick * self.period
        if at > end:  # it would never apply, and epochs go in time order: it would refuse every later change
            return (f"--at {at:g} s is past the run's end (t = {end:g} s): it would never apply; give --at "
                    f"from now to {end:g} s, or no --at (as soon as possible)")
        later = self.radio_watch.channel.epochs[-1][0] if self.radio_watch is not None else -math.inf
        if at < later:  # changes apply in time order (epochs): a scheduled or earlier command's comes later
            return (f"a radio change from t = {later:g} s is already in force later (scheduled or commanded); "
                    f"give --at {later:g} or later")
        self._send_command(None, None, "radio", radio=change, at=float(at))
        if self.radio_watch is not None:
            apply_radio_change(self.radio_watch.channel, change, float(at))
        self._note(FleetEvent.of(self._sim_now(), "radio_changed",
                                 f"radio changed from t = {at:.2f} s by {printable(sender, 64)}: "
                                 f"{printable(change, 200)}"), by_command=True)
        late = (f"t = {fields['at']:g} s asked had passed: from the first time every vehicle can take it"
                if 0 <= fields["at"] < at else "")
        return Verdict(True, late, max(0, math.ceil(at / self.period - 1e-9)), float(at))

    def _cmd_radio(self, f: dict, by: str) -> Verdict | str:
        """The ``radio`` command: relayed (:meth:`_relay_radio`) or refused, counted and reported."""
        out = self._relay_radio(f, by)
        if isinstance(out, str):
            self._reject(by, "radio")
            self._note(FleetEvent.of(self._sim_now(), "rejected",
                                     f"radio command from {printable(by, 64)}: {printable(out, 200)}"))
        return out

    def _relay_gains(self, gains: dict, vehicle: str, sender: str) -> Verdict | str:
        targets = self.ids if vehicle == "" else [vehicle] if vehicle in self.index else []
        problems = {gains_problem(gains, self.scenario.vehicle(v).dim, **self.scenario.gain_context(v))
                    for v in targets} - {None}
        if not targets or problems:  # all or nothing: no fleet with gains half changed
            self._reject(sender, "gains")
            why = f"no vehicle {printable(vehicle, 64)!r}" if not targets else printable("; ".join(sorted(problems)))
            self._note(FleetEvent.of(self._sim_now(), "rejected",
                                     f"gains {printable(gains, 120)} from {sender}: {why}"))
            return why
        tick = self.lockstep.granted + 1 if self.clock == "lockstep" else self._tick_now() + 1
        late = self._never_applies(tick)
        if late:
            return self._refuse(sender, "gains", f"gains {printable(gains, 120)}", late)
        self._send_command(targets, vehicle or None, "gains", gains=gains, tick=tick)
        self._note(FleetEvent.of(tick * self.period, "gains_changed",
                                 f"gains {gains} for {vehicle or 'every vehicle'} from tick {tick} by {sender}"),
                   by_command=True)
        return Verdict(True, "", tick)

    def _change_tick(self) -> int:
        """The first tick a run-time change can apply from on every vehicle alike: past the grant
        in lockstep (no vehicle may have stepped it yet), a moment ahead of the wall clock's tick
        in realtime."""
        if self.clock == "lockstep":
            return self.lockstep.granted + 1
        return self._tick_now() + max(1, math.ceil(LINK_LEAD / self.period))

    def _never_applies(self, tick: int) -> str | None:
        """Why a change from ``tick`` would never apply (past the run's last tick: near the end the
        grant has reached it, or the wall clock nearly has), else None. It was answered "applied
        from tick N+1" and `cdus gs` exited 0."""
        if tick <= self.last_tick:
            return None
        return (f"the run's last tick is {self.last_tick} (t = {self.last_tick * self.period:.2f} s) and the first "
                f"this change could apply from is {tick}: it would never apply (the run is ending)")

    def _refuse(self, sender: str, reason: str, what: str, why: str) -> str:
        """Count and report a refused command; returns the reason (for an acknowledgement)."""
        self._reject(sender, reason)
        self._note(FleetEvent.of(self._sim_now(), "rejected",
                                 f"{what} from {printable(sender, 64)}: {printable(why, 200)}"))
        return printable(why, MAX_REASON)  # the ground station's reply keeps all a reply may hold

    def _relay_formation(self, fields: dict, sender: str) -> Verdict | str:
        """A ground station's formation change: phases ``{id: θ}`` or offsets ``[{i, k, delta}]``
        (exactly one), checked as the config's are (offsets with the Δs in force on the other
        edges must close around every cycle) and turned into phases, relayed to every vehicle
        with the tick they apply from (:meth:`_change_tick`), and measured against from that
        tick. Returns the verdict (applied from that tick), else the reason it was refused."""
        phases, offsets = fields["phases"], fields["offsets"]
        if bool(phases) == bool(offsets):
            return self._refuse(sender, "formation", "formation", "give either phases or offsets (exactly one)")
        tick = self._change_tick()
        late = self._never_applies(tick)
        if late:
            return self._refuse(sender, "formation", "formation", late)
        sc = self.scenario
        if phases:
            checked = check_phases(phases, self.ids)
            if isinstance(checked, tuple):
                where = f"phases.{checked[0]}" if checked[0] else "phases"
                return self._refuse(sender, "formation", "formation", f"{where}: {checked[1]}")
        else:
            given = check_offsets(offsets, self.ids, sc.edges, sc.directed)
            if isinstance(given, tuple):
                return self._refuse(sender, "formation", "formation", f"offsets{given[0]}: {given[1]}")
            checked = offsets_to_phases(self.ids, self.recorder.formation.phases_at(tick), sc.edges, given,
                                        sc.directed)
            if isinstance(checked, str):
                return self._refuse(sender, "formation", "formation", checked)
        ordered = [(vid, checked[vid]) for vid in self.ids if vid in checked]
        self.recorder.formation.add(tick, {self.index[vid]: theta for vid, theta in ordered})
        for lo in range(0, len(ordered), 32):  # a control map holds at most 64 entries (decode_control)
            self._send_command(None, None, "formation", phases=dict(ordered[lo:lo + 32]), tick=tick)
        self._note(formation_changed(tick, self.period, ordered, sender), by_command=True)
        return Verdict(True, "" if ordered else "no phase changed: the offsets given were in force", tick)

    def _relay_path(self, fields: dict, sender: str) -> Verdict | str:
        """A ground station's new path for one vehicle, checked as the config's paths are, relayed
        to that vehicle with the tick it applies from. Returns the verdict, else the reason."""
        vid, table = fields["vehicle"], fields["path"]
        if vid not in self.index:
            return self._refuse(sender, "unknown_vehicle", "path", f"no vehicle {printable(vid, 64)!r}")
        path = "nested too deep" if nesting_problem(table, 2) else check_path(table, self.scenario.vehicle(vid).dim)
        if isinstance(path, (tuple, str)):
            why = path if isinstance(path, str) else f"path{'.' + path[0] if path[0] else ''}: {path[1]}"
            return self._refuse(sender, "path", f"path of {vid}", why)
        tick = self._change_tick()
        late = self._never_applies(tick)
        if late:
            return self._refuse(sender, "path", f"path of {vid}", late)
        self._send_command([vid], vid, "path", vehicle=vid, path=table, tick=tick)
        self._note(path_changed(tick, self.period, vid, sorted(table.items()), sender), by_command=True)
        return Verdict(True, "", tick)

    def _fleet_pause(self, pause: bool, by: str = "") -> Verdict | str:
        if pause == (self.lockstep.paused if self.clock == "lockstep" else self.paused_at is not None):
            return "the fleet is already paused" if pause else "the fleet is not paused"  # not news
        tick = self._effect_tick() if self.clock == "lockstep" else self._tick_now()
        if self.clock == "lockstep":
            (self.lockstep.pause if pause else self.lockstep.resume)()
        elif pause and self.paused_at is None:
            self.paused_at = time.time()
            self.pub_ctl.put(encode_control("pause"))
        elif not pause and self.paused_at is not None and self.t0 is not None:
            self.t0 += time.time() - self.paused_at  # the fleet's clock stood still
            self.paused_at = None
            self.pub_ctl.put(encode_control("resume", t0=self.t0))
        self._note(FleetEvent.of(self._sim_now(), "fleet", ("fleet paused" if pause else "fleet resumed")
                                 + (f" by {by}" if by else "")))
        self._publish_status()  # at once: a ground station attaching is answered the newest status
        return Verdict(True, "", tick)

    def _on_token(self, key: str, up: bool) -> None:
        """A liveliness token came (``up``) or went: whose it is, then :meth:`_on_alive`.

        A vehicle's process is the session whose token the world took for it: the first token
        of that vehicle (``alive/<id>/<zid>``) while it has none; its loss is that token's going,
        whatever other token of the vehicle is up. Zenoh merges tokens of one key (a second is no
        news, and keeps the key up after the first goes): the session id in the key makes each
        process's token its own. Ignored, and counted in :attr:`integrity`: a token on a key no
        process declares (``alive/**``: it intersects every watch), of a name not in the fleet,
        a second token of a vehicle (or of the world) while one is up, and any later token of a
        session refused once or holding another vehicle's (docs/security.md, "Liveliness")."""
        token = keys.alive_token(key)
        if token is None:
            if up:
                self._tamper("token_key", f"a liveliness token on {printable(key, 80)}, no process's key: ignored")
            return
        name, zid = token
        if name == keys.WORLD or name not in self.index:
            if up and zid != self.zid:
                self._tamper("token_extra" if name == keys.WORLD else "token_unknown",
                             f"a liveliness token {printable(name, 64)} of session {zid}: "
                             + ("not this world's" if name == keys.WORLD else "no process of this fleet"))
            return
        taken = self._token_of.get(name)
        if not up:
            if taken == zid:
                del self._token_of[name]
                self._on_alive(name, False)
            return
        if taken == zid:
            return
        if taken is None and zid not in self._not_taken and zid not in self._token_of.values():
            self._token_of[name] = zid
            self._on_alive(name, True)
            return
        self._not_taken.add(zid)
        self._tamper("token_extra", f"a second liveliness token of {name} (session {zid}) while "
                     + (f"session {taken}'s is up" if taken else "it has none it can take") + ": ignored")

    def _tamper(self, reason: str, note: str) -> None:
        """Something that may have altered the run (a forged or unexplained token): counted by
        reason for the metrics (``integrity``), the first of each logged and made an event."""
        self.integrity[reason] += 1
        if reason not in self._integrity_notes:
            self._integrity_notes[reason] = note
            self._note(FleetEvent.of(self._sim_now(), "suspect", note + " (docs/security.md)"))

    def integrity_block(self) -> dict:
        """``integrity`` of the metrics JSON: ``tampered`` when the world, or a vehicle watching the
        world's token, saw a token that is no process's (docs/metrics.md)."""
        reasons = Counter(self.integrity)
        notes = list(self._integrity_notes.values())
        for s in self._processes():
            for reason in SUSPECT_TOKEN_REASONS:
                if s.rejected_by_reason.get(reason):
                    reasons["vehicle_" + reason] += s.rejected_by_reason[reason]
                    notes.append(f"{s.id} counted {s.rejected_by_reason[reason]} {reason!r}: a liveliness token "
                                 f"on its watch of the world's that is not the world's")
        return {"tampered": bool(reasons), "reasons": dict(sorted(reasons.items())), "notes": notes}

    def _on_alive(self, name: str, up: bool) -> None:
        st = self.st
        if name not in self.index:
            return
        if up:
            st.alive.add(name)
        else:
            st.alive.discard(name)
            st.downs[name] = st.downs.get(name, 0) + 1
        if self.finished:
            return  # agents leaving after the stop are not news
        j = self.index[name]
        if self.clock == "lockstep":
            self.lockstep.on_alive(j, up)
            if self.lockstep.pending and self._drops_since is None:
                self._drops_since = time.monotonic()
            self._act(self.lockstep.poll())
        elif self.started:
            n = self._tick_now()
            if up:
                self._rt_lost.discard(name)
                if self._faulted.get(name) == "paused":  # a stopped process declares nothing: this one runs
                    del self._faulted[name]
                self._send_roster(RosterChange(n, j, "live", fresh=True))
                self.pub_ctl.put(encode_control("start", t0=self.t0))
                self._replay_commands(name)
                self._note(vehicle_back(n * self.period, name))
            else:
                self._send_roster(RosterChange(n, j, "gone"))
                expected = self._rt_expect.get(name, set())
                if "down" in expected:  # the fault we asked for, already reported as such
                    expected.discard("down")
                else:
                    self._rt_lost.add(name)
                    self._note(vehicle_lost(n * self.period, name))
        if self.started:
            self._check_graph()

    def _expect_news(self, vid: str, action: str) -> None:
        """Realtime: the liveliness changes a kill | pause | resume | restart we asked the
        launcher for will cause (a paused process's token lapses with the lease)."""
        self._rt_expect[vid] = {"kill": {"down"}, "pause": {"down"}, "resume": set(),
                                "restart": {"down"}}.get(action, set())
        self._note_fault(vid, action)

    def _note_fault(self, vid: str, action: str) -> None:
        """Keep which vehicles a fault killed or paused (realtime: asked of the launcher; lockstep:
        landed on its tick): realtime decides moot faults by it, and the status shows a vehicle
        paused by a fault as paused after its token lapses (the lockstep roster says gone then)."""
        if action == "kill" or action == "pause" and self._faulted.get(vid) != "killed":
            self._faulted[vid] = "killed" if action == "kill" else "paused"
        elif action in ("resume", "restart") and (action == "restart" or self._faulted.get(vid) == "paused"):
            self._faulted.pop(vid, None)

    def _rt_moot(self, vid: str, action: str) -> str | None:
        """Realtime: why a ground station's fault would do nothing (as Lockstep finds it on its
        tick: a pause of a vehicle not live, a resume of a live or killed one, a kill of a killed
        one), else None."""
        now = self._faulted.get(vid) or ("live" if vid in self.st.alive else "gone")
        moot = {"pause": now != "live", "resume": now in ("live", "killed"), "kill": now == "killed"}.get(action)
        return f"{vid} is {now} (nothing done)" if moot else None

    def _send_command(self, to: list[str] | None, kept_for: str | None, op: str, **fields: Any) -> None:
        """A run-time command to the vehicles ``to`` (None: the ctl publisher, every vehicle), kept
        for (re)joiners (``kept_for`` one vehicle, None all) and numbered (``seq``: a process that
        hears it again applies it once). A gains change for the same vehicles on the same tick as
        the change kept last replaces it there (a vehicle applies both at that tick, the later
        last: the earlier one never shows): a flood of them in one grant is one entry."""
        seq = self._seq
        self._seq += 1
        payload = encode_control(op, **fields, seq=seq)
        if to is None:
            self.pub_ctl.put(payload)
        else:
            self._put(keys.ctl(self.fleet, to), payload)
        change = _Change(kept_for, payload, op, fields["tick"] if op == "gains" else None)
        last = self._commands[-1] if self._commands else None
        if change.tick is not None and last is not None and (last.op, last.kept_for, last.tick) == (
                op, kept_for, change.tick):
            self._commands[-1] = change
        else:
            self._commands.append(change)
        self._settings_changed(op)

    def _put(self, key: str, payload: bytes) -> None:
        """A put to some of the vehicles (a roster change, a join, a command, contacts, a radio
        sample): blocking, never dropped under congestion, as the ctl publisher's (:meth:`open`)."""
        self.session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)

    def _replay_commands(self, vid: str) -> None:
        """A (re)started or resumed process missed the ground stations' run-time commands (a new
        one starts from the scenario file): send it each again, in order. Each applies from the
        time or tick it did (link changes at once if that is past), so it ends where the rest of
        the fleet is. Of the gains changes that apply before the first tick it can step, only the
        last is sent (it applies them all at that tick, the last last): a restart after a flood
        of gains changes is sent the one in force and those still to come, not the history."""
        first = self._first_step(vid)
        mine = [c for c in self._commands if c.kept_for is None or c.kept_for == vid]
        in_force = max((i for i, c in enumerate(mine) if c.tick is not None and c.tick <= first), default=None)
        for i, c in enumerate(mine):
            if c.tick is None or c.tick > first or i == in_force:
                self._put(keys.ctl(self.fleet, [vid]), c.payload)

    def _first_step(self, vid: str) -> int:
        """A tick no later than the first one ``vid``'s process (restarted, resumed) can step now:
        after the newest it reported or joins past (lockstep), the wall clock's less the slack
        (realtime)."""
        if self.clock == "lockstep":
            return self.lockstep.acked.get(self.index[vid], -1) + 1
        return self._tick_now() - math.ceil(REALTIME_SLACK / self.period)

    def _send_roster(self, ch: RosterChange, to: int | None = None) -> None:
        targets = self.ids if to is None else [self.ids[to]]
        self._put(keys.ctl(self.fleet, targets),
                         encode_control("roster", vehicle=self.ids[ch.vehicle], tick=ch.tick, state=ch.state,
                                        fresh=ch.fresh))

    def _note(self, event: FleetEvent, by_command: bool = False) -> None:
        """An event the world built (from validated fields only), marked with its origin. A refused
        command's (kind ``rejected``) and a change a command made (``by_command``) go out at most
        as their quota lets (_event_quotas): the next one that does says how many did not."""
        if event.origin is None:
            event = replace(event, origin=ORIGIN_WORLD)
        kind = "change" if by_command else event.kind
        quota = self._event_quotas.get(kind)
        if quota is not None:
            if not quota.take(self._quota_clock()):
                return
            held = quota.passed()
            if held:
                more = (f" ({held} refused commands since the last one logged were not: a flood; each was "
                        f"answered and counted in the world's rejects)" if kind == "rejected" else
                        f" ({held} changes by command since the last one logged were not: a flood; each was "
                        f"made, answered and is listed in world/settings)")
                event = replace(event, text=event.text[:MAX_EVENT_TEXT - len(more)] + more)
        self.events.append(event)
        self.sink.event(event)
        for line in self._console.lines(event):
            self.log(line)
        if self.session is not None:
            self.pub_events.put(encode_event(event))

    def _check_graph(self) -> None:
        """The live graph after a liveliness change, at the tick of the roster change it belongs
        to when there is one (lockstep: a kill at 150 s is news of tick 7500, not of the newest
        tick recorded, 7499), as the in-process fleet stamps it."""
        news = self.lockstep.news_tick if self.clock == "lockstep" else None
        t = self._sim_now() if news is None else news * self.period
        self._note(graph_event(t, self.ids, self.pairs, self.st.alive))

    def _sim_now(self) -> float:
        """The fleet's present in simulated seconds: the newest tick recorded (lockstep), the wall
        clock's tick (realtime)."""
        if self.clock == "realtime":
            return self._tick_now() * self.period
        return max(0, self.next_tick - 1) * self.period

    def _tick_now(self) -> int:
        if self.t0 is None:
            return 0
        now = self.paused_at if self.paused_at is not None else time.time()
        return max(0, int((now - self.t0) / self.period))

    # ------------------------------------------------------------------ the run
    def run(self) -> dict:
        deadline = time.monotonic() + self.start_timeout
        while len(self.st.alive) < len(self.ids) and not self.stop_requested:
            if time.monotonic() > deadline:
                missing = [v for v in self.ids if v not in self.st.alive]
                raise TimeoutError(f"vehicles not up after {self.start_timeout:g} s: {', '.join(missing)}")
            self._drain(block=True)
        if self.stop_requested:  # a stop can overtake the last liveliness tokens (the launcher saw them first)
            grace = time.monotonic() + STOP_GRACE_ALIVE_S
            while len(self.st.alive) < len(self.ids) and time.monotonic() < grace:
                time.sleep(0.02)
                self._handle_alive_news()
        # stopped while waiting for vehicles that never all came up: the run never began; a fleet
        # that was all up and was stopped before its first tick was interrupted
        self.started = not self.stop_requested or len(self.st.alive) >= len(self.ids)
        self._t_start = time.perf_counter()
        cpu0 = time.process_time()
        self.sink.start(self.scenario)
        if not self.stop_requested:
            self._run_lockstep() if self.clock == "lockstep" else self._run_realtime()
        self.cpu_s = time.process_time() - cpu0
        return self.finish()

    def _act(self, actions: list) -> None:
        for a in actions:
            if isinstance(a, Roster):
                self._send_roster(a.change, a.to)
            elif isinstance(a, Grant):
                self._last_grant = time.monotonic()
                self.pub_ctl.put(encode_control("grant", until=a.until))
            elif isinstance(a, Join):
                self._put(keys.ctl(self.fleet, [self.ids[a.vehicle]]), encode_control("join", tick=a.tick))
                if a.vehicle in self._catching:
                    self._catching[a.vehicle].join = a.tick
            elif isinstance(a, CatchUp):
                self._replay_commands(self.ids[a.vehicle])
                self._replay_geometry(self.ids[a.vehicle])
                self._catching[a.vehicle] = _CatchingUp(self.lockstep.acked.get(a.vehicle, -1),
                                                        time.monotonic() + CATCHUP_RESEND)
            elif isinstance(a, Sense):
                self._send_contacts(a.tick, self._sample_rows.pop(a.tick, {}))
            elif isinstance(a, RadioSample):
                self._send_geometry(a.tick, self._radio_rows.pop(a.tick, {}))
            elif isinstance(a, Fault):
                self._fault_since = time.monotonic()
                self._note_fault(self.ids[a.vehicle], {"pause_vehicle": "pause", "resume_vehicle": "resume"}.get(
                    a.op, a.op))
                self.pub_launcher.put(encode_control(a.op, vehicle=self.ids[a.vehicle]))
            elif isinstance(a, FleetEvent):
                self._note(a)
            elif isinstance(a, Decided):
                self._decided(a)

    def _send_contacts(self, tick: int, positions: dict[int, tuple]) -> None:
        """The proximity sensor at ``tick``: each sampled vehicle its contacts (cdus.sim.sensing);
        a vehicle not sampled (killed, paused) stays an obstacle where it was last seen."""
        for old in [k for k in self._sample_rows if k < tick]:
            del self._sample_rows[old]
        with self._lock:
            gone = {j: m.q for j, m in self.st.latest.items() if j not in positions}
        for j, msg in sense_tick(self.scenario, tick, positions, gone).items():
            self._put(keys.contacts(self.fleet, self.ids[j]), encode_contacts(msg))

    def _send_geometry(self, tick: int, positions: dict[int, tuple]) -> None:
        """The radio geometry at ``tick`` (cdus.sim.radio), as the in-process fleet samples it: the
        positions of the vehicles that stepped it, to every vehicle, then watched (events, views)."""
        for old in [k for k in self._radio_rows if k < tick]:
            del self._radio_rows[old]
        payload = encode_geometry(geometry_sample(tick, positions, len(self.ids), self._dims))
        self.pub_radio.put(payload)
        self._radio_sent.append((tick, payload))
        msg = decode_geometry(payload, len(self.ids))  # what the vehicles read: the same numbers
        if isinstance(msg, Rejected) or self.radio_watch is None:
            return
        for ev in self.radio_watch.observe(msg):
            self._note(ev)
        self.sink.radio(tick * self.period, self.radio_watch)

    def _replay_geometry(self, vid: str) -> None:
        """A (re)joining process needs the radio samples in force from its join on: the newest ones."""
        for _, payload in self._radio_sent:
            self._put(keys.radio(self.fleet, [vid]), payload)

    def _radio_realtime(self) -> None:
        """Realtime: once the clock has passed a radio sample tick, sample the newest telemetry of
        the vehicles alive under that tick (once each of them has sent some; never past the run)."""
        if self.radio is None or self.t0 is None or self.paused_at is not None:
            return
        n = self._tick_now()
        if n < self._next_radio or n > self.last_tick:
            return
        every = self.radio[0]
        # a vehicle a fault paused or killed is not live in the sample (as in lockstep), and one
        # paused from the start, which reports nothing, holds no sample back
        alive = {self.index[v] for v in self.st.alive if v not in self._faulted}
        with self._lock:
            positions = {j: m.q for j, m in self.st.latest.items() if j in alive}
        if not self.st.latest or len(positions) < len(alive):
            return  # a live vehicle not heard from yet (the start): it would look out of range
        self._next_radio = (n // every + 1) * every
        self._send_geometry(n // every * every, positions)

    def _sense_realtime(self) -> None:
        """Realtime: once the clock has passed a sample tick, sample the newest telemetry of the
        vehicles alive and publish their contacts under the present tick."""
        if self.sensing is None or self.t0 is None or self.paused_at is not None:
            return
        n = self._tick_now()
        if n < self._next_sample:
            return
        every = self.sensing[0]
        self._next_sample = (n // every + 1) * every
        alive = {self.index[v] for v in self.st.alive}
        with self._lock:
            positions = {j: m.q for j, m in self.st.latest.items() if j in alive}
        self._send_contacts(n, positions)

    def _run_lockstep(self) -> None:
        ls = self.lockstep
        for j, vid in enumerate(self.ids):
            ls.on_alive(j, vid in self.st.alive)
        ls.start()
        self._last_grant = 0.0
        last_status = 0.0
        mark = (time.monotonic(), self.next_tick)
        while self.next_tick <= self.last_tick and not self.stop_requested:
            self._act(ls.poll())
            self._record_complete()
            now = time.monotonic()
            if now - mark[0] >= HORIZON_EVERY:
                mark = self._widen_horizon(now, mark)
            if self._supervise_outage(now):
                break
            if self._catching:
                self._catch_up_again(now)
            if now - self._last_grant > GRANT_RESEND and ls.granted >= 0:  # for anyone who missed it
                self._last_grant = now
                self.pub_ctl.put(encode_control("grant", until=ls.granted))
            if self._fault_since is not None and ls._current is not None and ls._current.stage != "done":
                limit = JOIN_TIMEOUT if ls._current.stage == "waiting_token" else FAULT_TIMEOUT
                if now - self._fault_since > limit:
                    ls.give_up(ls._current.vehicle)
                    self._fault_since = None
            if now - last_status > STATUS_PERIOD:
                last_status = now
                self._publish_status()
            if self.next_tick <= self.last_tick:
                self._drain(block=True)

    def _catch_up_again(self, now: float) -> None:
        """Lockstep: a process caught up (CatchUp) that has reported no tick since hears it all
        again, in the first one's order (its roster, the commands and radio samples, the join tick
        of a restart, the grant): each is told once to a process that had it (roster changes are
        kept once, commands by their seq). After CATCHUP_RESEND s, then twice as long each time up
        to 8 s, while its liveliness token is up, until it reports. Not while it is down: a
        restart's fault_done can come before the old process's token goes, so the first catch-up
        went to a process not yet started (seen in the suite: the new uav2 waited for its join for
        ever); when the new one's token comes, it hears it."""
        ls = self.lockstep
        for j, c in list(self._catching.items()):
            vid = self.ids[j]
            if ls.acked.get(j, -1) > c.acked:
                del self._catching[j]
                continue
            if now < c.at or vid not in self.st.alive:
                continue
            if not c.told:
                c.told = True
                self.log(f"{vid} has reported nothing since its catch-up: saying it again")
            c.every = min(2 * c.every, CATCHUP_RESEND_MAX)
            c.at = now + c.every
            for ch in ls.changes:
                self._send_roster(ch, j)
            self._replay_commands(vid)
            self._replay_geometry(vid)
            if c.join is not None:  # last, as the first time: it starts stepping when it hears it
                self._put(keys.ctl(self.fleet, [vid]), encode_control("join", tick=c.join))
            self.pub_ctl.put(encode_control("grant", until=ls.granted))

    def _widen_horizon(self, now: float, mark: tuple[float, int]) -> tuple[float, int]:
        """Lockstep: size the grant window to the fleet's speed since ``mark`` (wall s, next tick
        to record then); a grant moves by a quarter window at a time. Returns the new mark."""
        ls = self.lockstep
        ls.window = horizon_window((self.next_tick - mark[1]) / (now - mark[0]), HORIZON_S)
        ls.grant_step = max(1, ls.window // 4)
        return now, self.next_tick

    def _supervise_outage(self, now: float) -> bool:
        """Decide liveliness losses once those of the moment are in (DROP_WINDOW); wait for a fleet
        that dropped all at once up to ``outage_grace``. True: the run cannot go on."""
        ls = self.lockstep
        if not ls.pending:
            self._drops_since = None
        elif self._drops_since is not None and now - self._drops_since > DROP_WINDOW:
            self._drops_since = None
            if ls.decide_drops() == "outage":
                self._outage_since = now
                self.log(f"every vehicle dropped at once: waiting up to {self.outage_grace:g} s for them")
            self._act(ls.poll())
        if not ls.outage:
            self._outage_since = None
        elif self._outage_since is not None and now - self._outage_since > self.outage_grace:
            self.completion = "router_lost" if self._router_lost() else "vehicles_lost"
            ls.end_outage()
            self._act(ls.poll())
            self.log(f"the fleet did not come back within {self.outage_grace:g} s: the run ends ({self.completion})")
            return True
        return False

    def _router_lost(self) -> bool:
        """Has this process (a client) lost its router? (A router of its own cannot be lost.)"""
        if self.session is None or self.transport.mode == "router":
            return False
        try:
            return not list(self.session.info.routers_zid())
        except (zenoh.ZError, AttributeError):
            return False

    def _record_complete(self) -> None:
        while self.next_tick <= self.last_tick and self.lockstep.recordable(self.next_tick):
            if not self._record(self.next_tick):
                return

    def _record(self, n: int) -> bool:
        """Record tick n: each vehicle's own row of tick n; one that did not step it (not live, or
        realtime: its row is late) repeats the row it was last recorded with, or its newest at or
        before n. Never a row of another tick as n's, never one nobody sent."""
        st = self.st
        row = st.rows.get(n, {})
        states = []
        for j in range(len(self.ids)):
            m = row.get(j)
            if m is None:
                latest, last = st.latest.get(j), self._recorded.get(j)
                m = max((x for x in (latest, last) if x is not None and x.tick <= n), key=lambda x: x.tick,
                        default=last)
            if m is None and (self.lockstep.state_at(j, n) != "live" if self.clock == "lockstep" else
                              self.ids[j] in self._faulted or latest is not None):  # (its rows come in order)
                m = self._initial_row(j)  # paused or killed from tick 0: where it starts, as cdus sim has it
            if m is None:
                return False  # a vehicle never reported: nothing to record yet
            states.append(m)
        st.rows.pop(n, None)
        for j, m in enumerate(states):
            self._recorded[j] = m
        self.recorder.record(n * self.period, states, self._live_at(n), self._interventions)
        self.next_tick = n + 1
        for event in self._change_events.pop(n, ()):
            self._note(event)
        if n % UPDATE_EVERY == 0:
            self.sink.update(self.recorder)
        return True

    def _initial_row(self, j: int) -> StateMsg:
        """Vehicle j's state before its first tick (a scheduled pause or kill at t = 0 keeps it
        from ever reporting one until it is back; the world recorded nothing and waited for ever)."""
        if j not in self._initial:
            tel = build_vehicle(self.scenario.vehicles[j], self.scenario.rates, self.scenario.seed,
                                self.scenario.safety).telemetry()
            self._initial[j] = StateMsg(j, 0, tel.t, tuple(tel.q), tel.heading, tel.speed, tel.omega, tel.omega_rate,
                                        tel.path_error)
        return self._initial[j]

    def _live_at(self, n: int) -> list[bool]:
        """Which vehicles step tick n: the lockstep roster's word, or (realtime) whose liveliness
        token is up (a frozen process's lapses with the lease)."""
        if self.clock == "lockstep":
            return [self.lockstep.state_at(j, n) == "live" for j in range(len(self.ids))]
        return [vid in self.st.alive for vid in self.ids]

    def _run_realtime(self) -> None:
        st, T = self.st, self.period
        self.t0 = time.time() + 0.5
        self.pub_ctl.put(encode_control("start", t0=self.t0))
        last_status = last_start = time.monotonic()
        while self.next_tick <= self.last_tick and not self.stop_requested:
            self._drain(block=True)
            if self._rt_asked:
                self._rt_faults_unconfirmed(time.monotonic())
            self._sense_realtime()
            self._radio_realtime()
            now = time.monotonic()
            if now - last_start > STATUS_PERIOD:  # again, for late joiners
                last_start = now
                self.pub_ctl.put(encode_control("start", t0=self.t0))
            if now - last_status > STATUS_PERIOD:
                last_status = now
                self._publish_status()
            if self.paused_at is not None:
                continue
            self._realtime_faults_due(self._tick_now() * T)
            due = min(self._tick_now() - REALTIME_LAG, self.last_tick)
            while self.next_tick <= due and self._record(self.next_tick):
                pass
            for old in [k for k in st.rows if k < self.next_tick]:
                st.rows.pop(old)
        if self.stop_requested and self._stop_tick is None:  # a signal: no tick was said
            return
        # a stop ends the run after the tick it said (the wall clock's, REALTIME_LAG ahead of the
        # newest recorded: a stop said "t = 17.36 s" and the metrics ended at 17.2 s)
        last = self.last_tick if self._stop_tick is None else min(self._stop_tick, self.last_tick)
        # give the final tick's telemetry a moment, then record what is left with the newest states
        end = time.monotonic() + 2.0
        live = [self.index[v] for v in st.alive]
        while (any(st.acked.get(j, -1) < last for j in live) and time.monotonic() < end
               and (not self.stop_requested or self._stop_tick is not None)):
            self._drain(block=True)
        while self.next_tick <= last and self._record(self.next_tick):
            pass

    def _realtime_faults_due(self, now: float) -> None:
        """Realtime: ask the launcher for the scheduled vehicle faults whose time has come (the
        world does not wait for them; their liveliness news makes the roster changes)."""
        while self._realtime_faults and self._realtime_faults[0].at <= now:
            ev = self._realtime_faults.pop(0)
            op = {"pause": "pause_vehicle", "resume": "resume_vehicle"}.get(ev.action, ev.action)
            self.pub_launcher.put(encode_control(op, vehicle=ev.vehicle))
            # its fault_done must not answer a ground station's fault asked after it
            self._rt_asked.setdefault(ev.vehicle, deque()).append((None, ev.action,
                                                                   time.monotonic() + RT_FAULT_CONFIRM))
            self._expect_news(ev.vehicle, ev.action)
            self._note(FleetEvent.of(now, "fault", f"scheduled {ev.action} of {ev.vehicle} (t = {ev.at:g} s)",
                                     vehicle=ev.vehicle))

    def _publish_status(self, completion: str | None = None) -> None:
        """The fleet's status; ``completion`` once the run is over (its last status)."""
        n = len(self.recorder)
        t = (self.next_tick - 1) * self.period
        path = coord = None
        if n:  # over the live formation, as the metrics (docs/metrics.md)
            worst_path, worst_coord = self.recorder.worst_errors(start=n - 1)
            path = None if math.isnan(worst_path[-1]) else float(worst_path[-1])
            coord = None if math.isnan(worst_coord[-1]) or not self.recorder.edges else float(worst_coord[-1])
        paused = self.lockstep.paused if self.clock == "lockstep" else self.paused_at is not None
        extra = replace(self._status_extra(), completion=completion)
        payload = encode_status(t, self.duration, self.clock, sorted(self.st.alive), self.ids, path, coord,
                                newest_events(self.events), paused, roster=dict(zip(self.ids, extra.states)),
                                extra=extra)
        self._status_payload = payload  # what a status query is answered (bytes: replaced whole, never changed)
        if self._status_key is None:
            self.pub_status.put(payload)
        else:
            self.pub_status.put(payload, attachment=status_signature(self._status_key, payload))

    def _status_extra(self) -> StatusExtra:
        """What a live console shows beyond the summary (cdus.wire.schemas.STATUS_EXTRA), at the
        newest recorded tick: each vehicle's kind and roster state, each edge's error, each
        emulated link's counters, each vehicle's received and dropped ω, the [safety] radius and
        the closest pair of live vehicles of one kind."""
        rec, n = self.recorder, len(self.recorder)
        kinds = [v.kind for v in self.scenario.vehicles]
        tick = max(0, self.next_tick - 1)
        if self.clock == "lockstep":
            states = [self.lockstep.state_at(j, tick) for j in range(len(self.ids))]
            # a vehicle a fault paused is gone from the roster once its lease lapses: still paused to an operator
            states = ["paused" if st == "gone" and self._faulted.get(vid) == "paused" else st
                      for vid, st in zip(self.ids, states)]
        else:
            states = ["paused" if self._faulted.get(vid) == "paused" else "live" if vid in self.st.alive
                      else "gone" for vid in self.ids]
        edges = closest = path_errors = None
        if n:
            omega, live, q = rec.omega[n - 1], rec.live[n - 1], rec.q[n - 1]
            path_errors = [float(x) if live[j] else None for j, x in enumerate(rec.path_error[n - 1])]
            # the offsets in force at that row (a formation change moves them), as coord_error_max
            d = rec.deltas(n - 1, n)
            deltas = [e.delta for e in rec.edges] if d is None else [float(x) for x in d[0]]
            edges = [(self.ids[e.i], self.ids[e.k],
                      float(abs(omega[e.i] - omega[e.k] - delta)) if live[e.i] and live[e.k] else None)
                     for e, delta in zip(rec.edges, deltas)]
            closest = closest_live_pair(q, live, kinds, self.ids)
        # a restarted vehicle's links and receipts add up over its processes, as in the metrics
        links: dict[tuple[str, str], tuple] = {}
        rx: list[tuple[int, int] | None] = [None] * len(self.ids)
        for s in self._processes():  # the retired first: the newest process says a link's state
            if isinstance(s.faults, dict):
                last_state = {c["link"]: c["state"] for c in s.faults["state_changes"]}
                for name, c in s.faults["links"].items():
                    src, _, dst = name.partition("->")
                    _, _, sent, dropped, state = links.get((src, dst), (src, dst, 0, 0, None))
                    links[(src, dst)] = (src, dst, sent + c["sent"], dropped + min(c["dropped"], c["sent"]),
                                         last_state.get(name, state))
            j = self.index[s.id]
            sent, dropped = rx[j] or (0, 0)
            rx[j] = (sent + s.sent_to_me, dropped + min(s.dropped, s.sent_to_me))
        return StatusExtra(kinds=kinds, states=states, edges=edges, links=[links[k] for k in sorted(links)], rx=rx,
                           safety_radius=self.scenario.safety.radius, closest=closest, path_errors=path_errors,
                           directed=self.scenario.directed)

    def _processes(self) -> list[AgentStats]:
        """The last stats of every agent process of the run, restarted ones' included."""
        return [*self.st.retired, *self.st.stats.values()]

    def link_block(self) -> dict:
        """``link`` of the metrics JSON, as the in-process fleet builds it (cdus.sim.summary):
        every process's counters, every latency sample, and ``faults`` only when the
        scenario's link has faults or a ground station set some."""
        total = LinkCounters(latencies=list(self.st.latencies.latencies))
        missed = 0
        rejected = self.st.rejected
        for s in self._processes():
            total.add(LinkCounters(sent=s.sent_to_me, delivered=s.delivered, dropped=s.dropped,
                                   duplicated=s.duplicated))
            rejected += s.rejected
            missed += s.missed_deadlines
        total.rejected = rejected
        faults = [s.faults for s in self._processes() if isinstance(s.faults, dict)]
        merged = None
        if faults and (not self.scenario.link.is_ideal or self.st.link_commanded):
            try:
                merged = merge_link_summaries(faults)
            except (KeyError, TypeError) as e:  # an agent's summary that does not parse
                self.log(f"link fault summaries could not be merged: {e!r}")
            else:  # every change seen during the run, not just each agent's newest
                merged["state_changes"] = [{"t": t, "link": link, "state": state}
                                           for t, link, state in sorted(self.st.link_changes)]
        return link_block(total, merged, missed_deadlines=missed)

    def _radio_metrics(self) -> dict:
        """``radio`` of the metrics JSON (with [radio] only): every process's radio counters summed,
        the utilisation and splits the world saw."""
        if self.radio is None or self.radio_watch is None:
            return {}
        total = RadioCounters()
        for s in self._processes():
            if isinstance(s.radio, dict):
                total.add(RadioCounters.from_dict(s.radio))
        return {"radio": radio_block(total, self.radio_watch)}

    def _completion(self) -> str:
        """COMPLETED if every tick to the end was stepped by the live fleet, else why not
        (docs/metrics.md, ``completion``)."""
        if not self.started:  # whatever stopped it (the launcher gave up waiting, a signal): nothing ran
            return "not_started"
        if self.completion is not None:
            return self.completion
        lost = self.lockstep.lost | self.lockstep.outage if self.clock == "lockstep" else self._rt_lost
        if self.next_tick > self.last_tick and not self.stop_requested:
            return "vehicles_lost" if lost else COMPLETED
        return "vehicles_lost" if lost else "interrupted"

    def rejects_by_reason(self) -> dict[str, dict[str, int]]:
        """What was dropped, by reason: by the world, and by the vehicles (every process's last counters)."""
        vehicles: Counter = Counter()
        for s in self._processes():
            vehicles.update(s.rejected_by_reason)
        return {"world": dict(sorted(self.st.rejects.items())), "vehicles": dict(sorted(vehicles.items()))}

    def finish(self) -> dict:
        """Tell the agents to stop, write the metrics (and trace). Safe to call after a stop."""
        self.finished = True
        # before the stop: the vehicles up then leave with it (a run that never began: who never came)
        never_up = {} if self.started else {"never_up": [v for v in self.ids if v not in self.st.alive]}
        completion = self._completion()  # decided by the run, not by the vehicles leaving at the stop
        if self.session is not None:
            self._publish_status(completion)  # first: a console reads the vehicles' leaving as the run's end
            self.pub_ctl.put(encode_control("stop"))
            deadline = time.monotonic() + 0.3  # let the agents' last counters arrive
            while time.monotonic() < deadline:
                self._drain(block=False)
                time.sleep(0.02)
        wall = time.perf_counter() - self._t_start if self.started else 0.0
        metrics = run_metrics(self.scenario, self.recorder, mode=self.clock, link=self.link_block(), wall_s=wall,
                              policy=self.policy, events=self.events,
                              interventions=sum(s.interventions for s in self._processes()),
                              completed=completion == COMPLETED, completion=completion,
                              rejected_by_reason=self.rejects_by_reason(), integrity=self.integrity_block(),
                              **never_up, **self._radio_metrics())
        if self.metrics_out:
            self._keep_metrics(metrics)
        if self.trace_out and len(self.recorder):
            try:
                self.recorder.save_trace(self.trace_out)
            except OSError as e:  # a full disk: said, the metrics (written first) are kept
                self.not_written.append("the trace")
                self.log(f"error: could not write the trace to {self.trace_out}: {e.strerror or e}")
                with contextlib.suppress(OSError):  # no half a trace that looks like one
                    if os.path.isfile(self.trace_out):
                        os.unlink(self.trace_out)
        self.sink.update(self.recorder)
        self.sink.close()
        return metrics

    def _recording_stopped(self, text: str) -> None:
        """The sink's file recording stopped (ENOSPC...): an event, so the launcher's console and
        the ground stations say it at once, and the metrics' events keep it."""
        self._note(FleetEvent.of(max(0, self.next_tick - 1) * self.period, "recording_stopped", text))

    def _keep_metrics(self, metrics: dict) -> None:
        """The metrics at metrics_out, or (a full disk, a read-only directory: which file and why
        said) at the first of :func:`cdus.files.metrics_fallbacks` that takes them, the launcher
        looking there too; where nothing takes them, printed whole as JSON on stdout."""
        fallbacks = metrics_fallbacks(self.metrics_out, self.run_dir, f"{self.fleet}-{os.getpid()}")
        at = keep_json(self.metrics_out, metrics, fallbacks, self.log)
        if at is not None and at == Path(self.metrics_out):
            self.log(f"metrics written to {self.metrics_out}")
            return
        self.not_written.append("the metrics")
        if at is None:
            self.log("the metrics could be written nowhere; here they are:")
            _say(json.dumps(metrics, default=str), prefix="")


def _status_key(text: str | None) -> bytes | None:
    """The launcher's status key from its hex form; None when there is none (or it is not hex)."""
    try:
        return bytes.fromhex(text) if text else None
    except ValueError:
        return None


def _say(text: str, prefix: str = "[world] ") -> None:
    """One line on stdout (the world's log); a log on a full disk is no reason to stop the world."""
    try:
        print(f"{prefix}{text}", flush=True)
    except OSError:
        pass


def _s(settle: float | None) -> str:
    return "never" if settle is None else f"{settle:.2f} s"


def run_world(world: World) -> int:
    """Open, run, write; SIGINT/SIGTERM stop the run and still write the metrics."""
    def _stop(signum, frame):
        world.completion = world.completion or "interrupted"
        world.stop_requested = True

    signal.signal(signal.SIGTERM, _stop)
    signal.signal(signal.SIGINT, _stop)
    try:
        world.open()
        m = world.run()
        ticks = max(1, len(world.recorder))
        world.log(f"done: path settle {_s(m['path_settle_s'])}, coordination settle {_s(m['coord_settle_s'])}; "
                  f"CPU in the run {world.cpu_s:.2f} s ({world.cpu_s / ticks * 1e6:.0f} µs per tick)")
        if len(world.recorder) and not m["live_final"] and not world.stop_requested:
            world.log("error: no vehicle was live at the end of the run (their logs say why)")
            return 1
        if world.not_written:  # the run is whole, its files are not where asked: not a lost world
            world.log(f"error: {' and '.join(world.not_written)} could not be written where asked (see above)")
            return METRICS_ELSEWHERE_EXIT
        return 0
    except TimeoutError as e:
        world.log(f"error: {e}")
        world.finish()
        return 1
    finally:
        world.close()

"""What is the world process made of, and how does a run go from start to metrics?

The world sees every vehicle, owns the clock, computes the metrics. Everything addressed to
it (telemetry, counters, commands, its own liveliness watch) arrives through one
subscription into one channel; the main thread waits there alone. It records tick n once
every vehicle live at n has reported it, writes the metrics JSON with the same builder as
`cdus sim`, streams to the sink (Rerun), publishes its status and the fleet's events, and
relays an operator's commands to the vehicles with the tick they apply from.

This module holds the World's state, its wiring (open, close, the ticker) and its run
(wait for the fleet, run the clock, finish). The rest is in rooms, one question each:

- world_sim/clocks.py: the clock, lockstep or realtime, chosen once here (its run loop,
  tick limit, effect tick, liveness, pause, vehicle faults);
- world_sim/intake.py: what came in, and what is dropped (counted by reason);
- world_sim/asking.py: how the world is asked (commands, queries) and answers;
- world_sim/commands.py: what each run-time command does (the handlers);
- world_sim/liveness.py: whose liveliness token is taken, and what its changes do;
- world_sim/status.py: the status and the events;
- world_sim/samples.py: the proximity contacts and radio geometry sent to the vehicles;
- world_sim/finish.py: the record of each tick, the metrics and the trace;
- world_sim/limits.py: the world's bounds and quotas; world_sim/verdict.py: a command's verdict.
"""
from __future__ import annotations

import os
import signal
import threading
import time
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any, Callable

import zenoh

from cdus.core.link import LinkCounters
from cdus.core.metrics import Recorder
from cdus.core.quota import Quota
from cdus.core.schedule import total_ticks
from cdus.files import METRICS_ELSEWHERE_EXIT
from cdus.scenario.model import Scenario
from cdus.sim.build import formation_schedule, metric_edges, radio_channel_for, radio_schedule, sensor_schedule
from cdus.sim.lockstep import Lockstep
from cdus.sim.radio import RadioWatch
from cdus.sim.reports import ConsoleQuota, scheduled_change_events
from cdus.sim.runmetrics import Metrics
from cdus.sim.sink import NullSink, Sink
from cdus.wire import keys
from cdus.wire.messages import StateMsg
from cdus.wire.schemas import AgentStats, FleetEvent, STATUS_KEY_ENV
from cdus.wire.transport import Transport, open_session
from world_sim.asking import Asking
from world_sim.clocks import (  # noqa: F401 (the clocks' figures: importable from here, as before the split)
    CATCHUP_RESEND, CATCHUP_RESEND_MAX, DROP_WINDOW, EFFECT_LEAD_S, FAULT_TIMEOUT, GRANT_RESEND, HORIZON_EVERY,
    HORIZON_S, JOIN_TIMEOUT, OUTAGE_GRACE, REALTIME_LAG, REALTIME_SLACK, RT_FAULT_CONFIRM, STATUS_PERIOD,
    LockstepClock, RealtimeClock, pick_clock,
)
from world_sim.commands import CommandHandlers, _Change
from world_sim.finish import Finishing
from world_sim.intake import Intake
from world_sim.limits import (  # noqa: F401 (the world's bounds: importable from here, as before the split)
    ANSWERS_PER_PASS, CHANGE_EVENTS_BURST, CHANGE_EVENTS_PER_S, COMMANDS_BURST, COMMANDS_PER_S, INBOX_CAPACITY,
    MAX_LOGGED_REJECTS, MAX_QUEUED_QUERIES, MAX_WAITING, QUERIES_BURST, QUERIES_PER_S, RADIO_KEEP, RATE_REFUSAL,
    REJECTED_EVENTS_BURST, REJECTED_EVENTS_PER_S, STOP_GRACE_ALIVE_S, SUSPECT_EVERY, SUSPECT_REASONS,
    SUSPECT_TOKEN_REASONS, SUSPECT_WORLD_REASONS,
)
from world_sim.liveness import Liveness
from world_sim.samples import Samples
from world_sim.status import Reporting, _say, _status_key, closest_live_pair  # noqa: F401
from world_sim.verdict import LATER, Verdict  # noqa: F401


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
    #: the vehicles whose last report (AgentStats.final) came since the world said stop: it
    #: waits for no more from them (world_sim.finish); None until the stop
    finals: set[str] | None = None

    @property
    def rejected(self) -> int:
        return sum(self.rejects.values())


class World(Intake, Asking, CommandHandlers, Liveness, Reporting, Samples, Finishing):
    """The world process: a main thread that waits on one inbox, and the rooms it is made of
    (each a mixin answering one question: intake, asking, commands, liveness, status, samples,
    finish), with its clock (world_sim.clocks) chosen once in ``__init__``."""

    def __init__(self, scenario: Scenario, fleet: str, transport: Transport, clock: str = "lockstep",
                 duration: float | None = None, metrics_out: str | None = None, trace_out: str | None = None,
                 start_timeout: float = 60.0, log: Callable[[str], None] | None = None, sink: Sink | None = None,
                 policy: str | None = None, run_dir: str | None = None):
        self.scenario = scenario
        self.fleet = keys.check_fleet(fleet)
        self.transport = transport
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
        #: the world's own channel: utilisation, link probabilities and splits of each sample
        self.radio_watch = None if self.radio is None else RadioWatch(
            self.ids, [(e.i, e.k) for e in scenario.edges], radio_channel_for(scenario), self.period)
        self.lockstep = Lockstep(self.ids, self.period, self.last_tick, self.events_scheduled,
                                 sense_every=self.sensing[0] if self.sensing else None,
                                 sense_latency=self.sensing[1] if self.sensing else 1,
                                 radio_every=self.radio[0] if self.radio else None,
                                 radio_lag=self.radio[1] if self.radio else 1)
        self._sample_rows: dict[int, dict[int, tuple]] = {}  # sample tick -> vehicle -> q (lockstep)
        self.st = WorldState()
        #: the clock, chosen here once: LockstepClock or RealtimeClock (world_sim.clocks)
        self.clock: LockstepClock | RealtimeClock = pick_clock(clock, self)
        self._radio_from_rows = self.radio is not None and self.clock.radio_from_rows
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
        self.session: Any = None
        self._t_start = 0.0
        self._lock = threading.Lock()  # guards st.latest for the queryable's thread
        self._alive_news: deque[tuple[str, bool]] = deque()  # liveliness callbacks (key, up) -> main thread
        self.zid: str | None = None  # this process's Zenoh session id (its token's key ends with it)
        # vehicle (or "ros2", the bridge) -> the session id of the token taken as its process's
        self._token_of: dict[str, str] = {}
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
        self._odometry_noted: dict[str, set[tuple[str, float]]] = {}  # robot -> its odometry events noted (kind, t)
        self.completion: str | None = None  # why the run ended early (docs/metrics.md, completion)
        self.outage_grace = OUTAGE_GRACE
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
        #: op -> handler(fields, by) -> Verdict | reason str | None | LATER (see Verdict); other
        #: parts add theirs here (formation, path, radio)
        self.command_handlers: dict[type, Callable[..., Any]] = self.handlers()

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
            *(s.declare_queryable(on, handler) for on, handler in self.queryables()),
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
            time.sleep(self.clock.wake_every)
            try:
                self._wake()
            except zenoh.ZError:
                return

    def request_stop(self) -> None:
        self.stop_requested = True
        self._wake()

    # ------------------------------------------------------------------ receiving

    # ------------------------------------------------------------------ commands

    def _put(self, key: str, payload: bytes) -> None:
        """A put to some of the vehicles (a roster change, a join, a command, contacts, a radio
        sample): blocking, never dropped under congestion, as the ctl publisher's (:meth:`open`)."""
        self.session.put(key, payload, congestion_control=zenoh.CongestionControl.BLOCK)

    def _sim_now(self) -> float:
        """The fleet's present in simulated seconds (the clock's)."""
        return self.clock.sim_now()

    # ------------------------------------------------------------------ the run
    def run(self) -> Metrics:
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
            self.clock.run()
        self.cpu_s = time.process_time() - cpu0
        return self.finish()

    def _router_lost(self) -> bool:
        """Has this process (a client) lost its router? (A router of its own cannot be lost.)"""
        if self.session is None or self.transport.mode == "router":
            return False
        try:
            return not list(self.session.info.routers_zid())
        except (zenoh.ZError, AttributeError):
            return False


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
        world.log(f"done: path settle {_s(m.path_settle_s)}, coordination settle {_s(m.coord_settle_s)}; "
                  f"CPU in the run {world.cpu_s:.2f} s ({world.cpu_s / ticks * 1e6:.0f} µs per tick)")
        if len(world.recorder) and not m.live_final and not world.stop_requested:
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

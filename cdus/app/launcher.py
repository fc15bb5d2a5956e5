"""How is a fleet of processes brought up, watched and stopped? The launcher: the world and one
process per vehicle, supervised, then stopped all together.

The launcher opens the fleet's Zenoh router itself (loopback TCP by default), so it sees
every liveliness token without polling: it starts world_sim, waits for the world's token,
starts the agents (but those started elsewhere, ``remote``: it prints their command
lines, docs/multihost.md), waits for all of theirs (naming the ones that did not come up, with the
tail of their logs), then watches: it shows the world's progress, restarts agents by the
scenario's ``[supervision]`` (restart never | on-failure | always, at most ``max_restarts``
times per vehicle, after a doubling back-off; docs/config.md), and at the end, on Ctrl-C,
on SIGTERM or on a failure, walks the shutdown ladder: ask the world to stop (it writes the
metrics), let everyone who came up exit for a grace period, SIGTERM their process groups
(at once for one that never came up: it cannot hear the stop), then SIGKILL.
Nothing it started outlives it, not even when the launcher itself is SIGKILLed: every child
is started with ``PR_SET_PDEATHSIG`` (Linux): the moment the launcher dies the kernel sends
the world SIGTERM (it still writes what it has) and the agents SIGKILL (nothing to save, and
a vehicle paused by a fault, SIGSTOPped, would never act on a SIGTERM). If the world dies, the
launcher writes the run's metrics.json itself (``completed: false``, ``completion:
"world_lost"``, what it knew from the world's last status), stops the fleet and exits 1. A world
that exits ``METRICS_ELSEWHERE_EXIT`` ended its run but could not write its metrics where asked
(a full disk): the launcher finds them where the world kept them (cdus.files.metrics_fallbacks)
instead. A run directory is held (:class:`RunDirLock`) while a fleet runs into it.

Its rooms: cdus.app.children (one child process), cdus.app.preflight (the run directory's lock,
the router's endpoints and rate limits), cdus.app.faults (the vehicle faults the world asks
for) and cdus.app.world_lost (the metrics of a lost world); their names import from here too.
"""

from __future__ import annotations

import json
import os
import secrets
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable

import zenoh

from cdus.app.children import LOG_TAIL, PR_SET_PDEATHSIG, Child, die_with_parent  # noqa: F401 (cdus.app.launcher's names)
from cdus.app.preflight import (  # noqa: F401 (cdus.app.launcher's names)
    COMMAND_HZ, LINKS, LOCK_NAME, OMEGA_MARGIN, ListenError, RunDirError, RunDirInUse, RunDirLock, check_listen,
    listen_problem, rate_limits,
)
from cdus.app.faults import FaultDispatch
from cdus.app.world_lost import WorldLostMetrics
from cdus.scenario.model import DEFAULT_RESTART, Scenario, Supervision
from cdus.app.report import WORLD_LOST, Progress  # noqa: F401 (WORLD_LOST: cdus.app.launcher's name)
from cdus.files import METRICS_ELSEWHERE_EXIT, metrics_fallbacks, write_json
from cdus.sim.reports import ConsoleQuota
from cdus.wire import keys
from cdus.wire.access import ROS2_ROLE
from cdus.commands.vehicle import VehicleFault
from cdus.wire.messages import CTL_OPS, decode_control, encode_control
from cdus.wire.rejected import Rejected
from cdus.wire.schemas import STATUS_KEY_ENV, FleetEvent, WorldStatus, decode_event, decode_status, encode_event, signed_by
from cdus.wire.text import printable
from cdus.wire.transport import (
    CHILD_RUNTIME, DEFAULT_LEASE_MS, ROUTER_RUNTIME, ROUTER_RUNTIME_ENV, Transport, children_runtime, client_of,
    open_session, use_runtime,
)

GRACE_S = 5.0
# Fewer Zenoh runtime threads per child process (cdus.wire.transport.CHILD_RUNTIME; the router,
# this process, keeps Zenoh's: ROUTER_RUNTIME): on a small machine running many processes the
# default thread pools cost more in context switches than they give. A user's own ZENOH_RUNTIME
# wins, for every process.
ZENOH_RUNTIME = CHILD_RUNTIME


_PRINT_LOCK = threading.Lock()


def print_line(s: str) -> None:
    """One whole line on stdout: the launcher logs from Zenoh's threads (events) and its own
    (faults, restarts), and print() writes the text and its newline apart, so two lines could
    interleave ("... (t = 1 s)  fault: kill usv2")."""
    with _PRINT_LOCK:
        sys.stdout.write(s + "\n")
        sys.stdout.flush()


# WORLD_LOST (cdus.app.report): the completion reason the launcher writes when the world died without metrics


class LaunchError(Exception):
    """The fleet could not be brought up; the message says who failed and why."""


@dataclass
class LaunchOptions:
    fleet: str
    clock: str = "lockstep"
    duration: float | None = None
    restart: str = DEFAULT_RESTART  # one of RESTART_POLICIES (cdus.scenario.model)
    metrics_out: Path | None = None
    trace_out: Path | None = None
    policy: str | None = None
    ready_timeout: float = 30.0
    grace: float = GRACE_S
    quiet: bool = False
    lease_ms: int | None = DEFAULT_LEASE_MS
    rerun: str = "off"
    zenoh_configs: dict[str, str] = field(default_factory=dict)  # child name -> its --zenoh-config (credentials)
    remote: tuple[str, ...] = ()  # vehicles started elsewhere (another host): waited for, not started or restarted
    links: str = "router"  # one of LINKS: ω between neighbours directly, or through the router


@dataclass
class Launcher(FaultDispatch, WorldLostMetrics):
    scenario: Scenario
    run_dir: Path
    router: Transport
    opts: LaunchOptions
    log: Callable[[str], None] = field(default=print_line)
    clock: Callable[[], float] = time.monotonic  # for restart back-offs (a test's own clock)

    def __post_init__(self) -> None:
        self.fleet = keys.check_fleet(self.opts.fleet)
        self.logs = self.run_dir / "logs"
        self.logs.mkdir(parents=True, exist_ok=True)
        self.config_path = self.run_dir / "scenario.json"
        write_json(self.config_path, self.scenario.raw, allow_inf=True)  # e.g. radio.shadowing_time = inf
        self.metrics_out = Path(self.opts.metrics_out or self.run_dir / "metrics.json")
        self.metrics_at: Path | None = None  # where the run's metrics are once it ended (launch), None: nowhere
        self.cond = threading.Condition()
        self.alive: set[str] = set()
        self.ever_alive: set[str] = set()  # whose token was seen at least once
        self._tokens: dict[str, set[str]] = {}  # name -> session ids of its tokens up (keys.hold_token)
        self.status: WorldStatus | None = None
        self.rejected: dict[str, int] = {}  # messages to the launcher dropped, by reason
        # what of the events to print (drop bursts per link are capped, links lossy by design said once)
        self._console = ConsoleQuota(scenario=self.scenario)
        self.children: dict[str, Child] = {}
        self.session = None
        self.stopping = False
        self.finished = False
        self.requests: list[VehicleFault] = []  # scheduled faults asked for by the world
        self.env = dict(os.environ)
        self.env["ZENOH_RUNTIME"] = children_runtime()  # the user's, else CHILD_RUNTIME (not the router's)
        self.env["PYTHONUNBUFFERED"] = "1"
        #: the world signs its statuses with this (cdus.wire.schemas.STATUS_KEY_ENV): only the world
        #: started here knows it, so a status forged on an open fleet is not believed
        self.status_key = secrets.token_bytes(16)
        self.env.pop(STATUS_KEY_ENV, None)  # an agent never holds one (not even one from our own environment)
        if self.opts.links == "direct" and (self.opts.remote or self.opts.zenoh_configs):
            raise ValueError("direct links are unix sockets on this host that skip the router: "
                             "vehicles on other hosts and a secured fleet need links='router'")
        self.sockets: Path | None = None  # direct links: each agent's unix socket, in a short temp dir
        if self.opts.links == "direct":
            self.sockets = Path(tempfile.mkdtemp(prefix="cdus-"))
        if self.opts.clock == "realtime":
            limits = rate_limits(self.fleet, self.scenario.ids, self.scenario.rates.broadcast)
            self.router = replace(self.router, extra=(*self.router.extra, ("downsampling", json.dumps(limits))))
        sv = self.scenario.supervision  # the policy from the command line, the limits from the scenario
        self.supervision = Supervision(self.opts.restart, sv.max_restarts, sv.backoff_s)

    # ------------------------------------------------------------------ processes
    def _common(self, name: str, t: Transport | None = None) -> list[str]:
        if t is None:
            t = Transport(mode="client", connect=client_of(self.router).connect,
                          config_file=self.opts.zenoh_configs.get(name), lease_ms=self.opts.lease_ms)
        out = ["--config", str(self.config_path), "--fleet", self.fleet, "--clock", self.opts.clock, *t.args()]
        if self.opts.duration is not None:
            out += ["--duration", str(self.opts.duration)]
        return out

    def _world(self) -> Child:
        argv = [sys.executable, "-m", "world_sim", *self._common("world"), "--metrics-out", str(self.metrics_out),
                "--start-timeout", str(self.opts.ready_timeout + 5)]
        if self.opts.trace_out:
            argv += ["--trace-out", str(self.opts.trace_out)]
        argv += ["--rerun", self.opts.rerun, "--run-dir", str(self.run_dir)]
        if self.opts.policy:
            argv += ["--policy", self.opts.policy]
        return Child("world", argv, self.logs / "world.log", death_signal=signal.SIGTERM)

    def world_env(self) -> dict[str, str]:
        """The world's environment: the children's, and the status key (the world's alone)."""
        return {**self.env, STATUS_KEY_ENV: self.status_key.hex()}
    def _bridge(self) -> Child:
        """The ROS 2 bridge ([ros2] enabled, docs/ros2.md): an observer, started after the world."""
        argv = [sys.executable, "-m", "cdus.ros2", *self._common(ROS2_ROLE)]
        return Child(ROS2_ROLE, argv, self.logs / "ros2.log", death_signal=signal.SIGTERM)

    def _agent(self, vid: str) -> Child:
        argv = [sys.executable, "-m", "vehicle_agent", *self._common(vid, self._agent_transport(vid)), "--id", vid]
        if self.opts.policy:
            argv += ["--policy", self.opts.policy]
        return Child(vid, argv, self.logs / f"{vid}.log", restart_args=("--rejoin",))

    def _agent_transport(self, vid: str) -> Transport | None:
        """Direct links: the agent is a peer listening on its own unix socket, connected to the
        router and to the sockets of the vehicles it hears or that hear it (no gossip: exactly
        these links). Its ω then goes straight to its neighbours; all else through the router."""
        if self.sockets is None:
            return None
        sc = self.scenario
        near = sorted({e.k for e in sc.edges if e.i == vid} | {e.i for e in sc.edges if e.k == vid})
        return Transport(mode="peer", connect=(*client_of(self.router).connect, *(self._socket(k) for k in near)),
                         listen=(self._socket(vid),), lease_ms=self.opts.lease_ms)

    def _socket(self, vid: str) -> str:
        assert self.sockets is not None
        return f"unixsock-stream/{self.sockets / (vid + '.sock')}"

    def remote_command(self, vid: str) -> str:
        """How to start vehicle ``vid`` on another host (docs/multihost.md): the launcher's own
        command line for it, ``python3`` for this interpreter."""
        argv = ["python3", *self._agent(vid).argv[1:]]
        return " ".join(shlex.quote(a) for a in argv)

    # ------------------------------------------------------------------ zenoh
    def _open(self) -> None:
        # the router's own runtime (ROUTER_RUNTIME: Zenoh's default pools, see there), before its
        # session starts Zenoh's; the children's is in self.env
        own = os.environ.get(ROUTER_RUNTIME_ENV) or ROUTER_RUNTIME
        if own != "default":
            use_runtime(own)
        try:
            s = self.session = open_session(self.router)
        except zenoh.ZError as e:  # a port taken since the check (cmd_launch), or else: Zenoh's words
            raise ListenError(f"the router cannot listen on {', '.join(self.router.listen) or 'its endpoints'}: "
                              f"{printable(str(e).split(' at /')[0], 400)}") from None
        f = self.fleet
        self._subs = [
            s.liveliness().declare_subscriber(keys.any_alive(f), self._on_alive, history=True),
            s.declare_subscriber(keys.world_status(f), self._on_status),
            s.declare_subscriber(keys.world_events(f), self._on_event),
            s.declare_subscriber(keys.ctl(f, [v.id for v in self.scenario.vehicles]), self._on_ctl),
            s.declare_subscriber(keys.launcher_cmd(f), self._on_fault_request),
        ]

    def _on_ctl(self, sample: Any) -> None:
        c = decode_control(sample.payload.to_bytes(), CTL_OPS)
        if not isinstance(c, Rejected) and c.op == "stop":
            with self.cond:
                self.finished = True  # the world ended the run: agents exiting now is expected
                self.cond.notify_all()

    def _on_alive(self, sample: Any) -> None:
        with self.cond:
            news = keys.hold_token(self._tokens, str(sample.key_expr), not str(sample.kind).endswith("DELETE"))
            if news is None:  # a token on a key expression (alive/**) or no process's key
                self.rejected["token_key"] = self.rejected.get("token_key", 0) + 1
                return
            who, up = news
            if up:
                self.alive.add(who)
                self.ever_alive.add(who)
            else:
                self.alive.discard(who)
            self.cond.notify_all()

    def _on_status(self, sample: Any) -> None:
        payload = sample.payload.to_bytes()
        attachment = getattr(sample, "attachment", None)
        if not signed_by(self.status_key, payload, None if attachment is None else attachment.to_bytes()):
            self._reject("status unsigned", "a world status not signed by the world started here (forged?)")
            return
        st = decode_status(payload)
        if isinstance(st, Rejected):
            self._reject(f"status {st.reason}", "a malformed world status")
            return
        t = st.t
        limit = 2 * (self.opts.duration or self.scenario.duration) + 1.0
        if not -1.0 <= t <= limit:  # -T before tick 0
            self._reject("status t", f"a world status with t = {printable(t, 40)} (not in [-1, {limit:g}] s)")
            return
        with self.cond:
            if self.status is not None and t < self.status.t:  # a signed status replayed: time only moves on
                stale = True
            else:
                stale = False
                self.status = st
                self.cond.notify_all()
        if stale:
            self._reject("status stale", f"a world status of t = {t:g} s, older than the last one (replayed?)")

    def _on_event(self, sample: Any) -> None:
        e = decode_event(sample.payload.to_bytes())
        if isinstance(e, Rejected):
            self._reject(f"event {e.reason}", "a malformed event")
            return
        if not self.opts.quiet:  # printed by the watch loop, in time order (_print_events)
            with self.cond:  # the quota is shared with the main thread
                self._console.hold(e, self.clock())

    def _print_events(self, final: bool = False) -> None:
        """The events heard HOLD_S ago or more (``final``: all), in time order, a link change of
        many links as one line: they used to be printed as heard, a line per link, the links'
        states a second late (with the agents' counters) after the events stamped later."""
        with self.cond:
            lines = self._console.flush() if final else self._console.due(self.clock())
        for line in lines:
            self.log(line)

    def _wait_alive(self, names: list[str], timeout: float) -> list[str]:
        """Wait for every name's liveliness token; returns the missing ones (early exits end the wait)."""
        deadline = time.monotonic() + timeout
        with self.cond:
            while True:
                missing = [n for n in names if n not in self.alive]
                dead = [n for n in missing if n in self.children and self.children[n].poll() is not None]
                if not missing or dead or time.monotonic() > deadline:
                    return missing
                self.cond.wait(timeout=0.2)

    def _fail_start(self, missing: list[str], timeout: float) -> LaunchError:
        parts = []
        for n in missing:
            if n not in self.children:
                parts.append(f"{n} (started elsewhere) did not connect within {timeout:g} s; start it on its host "
                             f"with:\n    {self.remote_command(n)}")
                continue
            c = self.children[n]
            code = c.poll()
            why = (f"exited with status {code} during start-up" if code is not None
                   else f"did not come up within {timeout:g} s, still starting (a large scenario, e.g. splines of "
                        f"thousands of waypoints, takes each process longer to check and build: give it more with "
                        f"--ready-timeout S)")
            parts.append(f"{n} {why}; its log ({c.log_path}) ends with:\n{c.tail()}")
        return LaunchError("\n".join(parts))

    # ------------------------------------------------------------------ the run
    def start(self) -> None:
        self._open()
        w = self.children["world"] = self._world()
        w.start(self.world_env())
        missing = self._wait_alive(["world"], self.opts.ready_timeout)
        if missing:
            raise self._fail_start(missing, self.opts.ready_timeout)
        if self.scenario.ros2.enabled:  # before the vehicles: it sees the run from its first tick
            b = self.children[ROS2_ROLE] = self._bridge()
            b.start(self.env)
            missing = self._wait_alive([ROS2_ROLE], self.opts.ready_timeout)
            if missing:
                raise self._fail_start(missing, self.opts.ready_timeout)
        ids = [v.id for v in self.scenario.vehicles]
        for vid in ids:
            if vid not in self.opts.remote:
                c = self.children[vid] = self._agent(vid)
                c.start(self.env)
        if self.opts.remote:
            self.log(f"waiting for {len(self.opts.remote)} vehicles started elsewhere "
                     f"({', '.join(self.opts.remote)}); start each on its host, connecting to an endpoint of "
                     f"this router it can reach ({', '.join(self.router.listen)}):")
            for vid in self.opts.remote:
                self.log(f"    {self.remote_command(vid)}")
        missing = self._wait_alive(ids, self.opts.ready_timeout)
        if missing:
            raise self._fail_start(missing, self.opts.ready_timeout)
        here = f"{len(ids) - len(self.opts.remote)} here, {len(self.opts.remote)} elsewhere" if self.opts.remote else ""
        self.log(f"fleet {self.fleet!r} up: world + {len(ids)} vehicles ({self.opts.clock} clock{', ' if here else ''}"
                 f"{here}); logs in {self.logs}")
        if not self.opts.quiet:  # the links lossy by design, before the events stamped later
            with self.cond:
                lines = self._console.opening()
            for line in lines:
                self.log(line)

    def supervise(self) -> int:
        """Until the world exits: progress, restarts. Returns the world's exit status."""
        world = self.children["world"]
        duration = self.opts.duration or self.scenario.duration
        progress = Progress(self.scenario.name, quiet=self.opts.quiet)
        while True:
            code = world.poll()
            if code is not None:
                progress.done()
                self._print_events(final=True)
                return code
            self._print_events()
            with self.cond:
                requests, self.requests = self.requests, []
            for fault in requests:
                self._carry_out(fault)
            self._watch_agents()
            with self.cond:
                if not self.requests:
                    self.cond.wait(timeout=self._wait_s())
                st = self.status
            if st is not None and st.t > 0:  # checked where it came in (_on_status)
                progress(st.t, duration)

    def _watch_agents(self) -> None:
        """Notice agents that exited and restart those whose back-off is over (never blocks)."""
        if self.stopping or self.finished:
            return
        for name, c in self.children.items():
            if name not in (keys.WORLD, ROS2_ROLE) and c.exit_code is None and c.poll() is not None:
                self._on_agent_exit(c, c.exit_code)
        bridge = self.children.get(ROS2_ROLE)
        if bridge is not None and bridge.exit_code is None and bridge.poll() not in (None, 0):
            rc = bridge.exit_code  # 0: it saw the world go (the run's end); else killed or failed mid-run
            how = f"exited with status {rc}" if rc > 0 else f"was killed by signal {-rc}"
            self.log(f"  the ROS 2 bridge {how}: the ROS 2 topics stop, the run goes on; its log: {bridge.log_path}")
        now = self.clock()
        for c in self.children.values():
            if c.restart_at is not None and now >= c.restart_at:
                c.restart_at = None
                c.restarts += 1
                c.supervised_restarts += 1
                self.log(f"  restarting vehicle {c.name} (restart {c.supervised_restarts} of at most "
                         f"{self.supervision.max_restarts})")
                c.start(self.env)

    def _wait_s(self) -> float:
        """How long the watch loop may sleep: until the next restart is due, at most 0.2 s; 0.02 s
        once the world's token went (its process is exiting, and the loop looks for its exit
        status: in 0.2 s steps that was a tenth of a second of every run's end, on average)."""
        due = [c.restart_at for c in self.children.values() if c.restart_at is not None]
        step = 0.02 if keys.WORLD in self.ever_alive and keys.WORLD not in self.alive else 0.2
        return max(0.0, min([step, *(t - self.clock() for t in due)]))

    def _on_agent_exit(self, c: Child, rc: int) -> None:
        """An agent exited during the run: by the restart policy, restart it after its back-off,
        or give up on it once its restarts are used up."""
        if c.intended_exit:  # a scheduled kill: the experiment, not a failure
            return
        how = f"exited with status {rc}" if rc >= 0 else f"was killed by signal {-rc}"
        sv = self.supervision
        if not (sv.restart == "always" or (sv.restart == "on-failure" and rc != 0)):
            self.log(f"  vehicle {c.name} {how} (restart policy {sv.restart}: it stays down)")
            return
        if c.supervised_restarts >= sv.max_restarts:
            c.given_up = True
            self._give_up(c, how)
            return
        wait = sv.backoff(c.supervised_restarts)
        c.restart_at = self.clock() + wait
        self.log(f"  vehicle {c.name} {how}; restarting it in {wait:g} s")

    def _give_up(self, c: Child, how: str) -> None:
        sv = self.supervision
        t = self.status.t if self.status is not None else 0.0
        event = FleetEvent.of(t, "gave_up", f"vehicle {c.name} {how} after {c.supervised_restarts} restarts; "
                              f"the launcher gives up on it (supervision.max_restarts = {sv.max_restarts}); "
                              f"its log: {c.log_path}", vehicle=c.name)
        self.log(f"  {event.text}")
        if self.session is not None:
            try:
                self.session.put(keys.world_events(self.fleet), encode_event(event),  # not to our own _on_event
                                 allowed_destination=zenoh.Locality.REMOTE)
            except zenoh.ZError as e:
                self.log(f"  could not publish that: {e}")

    def stop(self) -> None:
        """The shutdown ladder: ask, wait, SIGTERM, wait, SIGKILL. Idempotent."""
        self.stopping = True
        world = self.children.get("world")
        # the world's stop reaches the processes that came up (declared their token); one that never
        # did (waiting for a neighbour's link that never came, or still starting) does not hear it and
        # would only run out the grace: it gets its SIGTERM below at once
        if world is not None and world.running() and keys.WORLD not in self.ever_alive:  # a Ctrl-C as it starts:
            self._wait_alive([keys.WORLD], self.opts.grace)  # its stop, put before it listens, was lost (5 s)
        told = {n for n in self.children if n in self.ever_alive}
        if self.session is not None and world is not None and world.running() and keys.WORLD in told:
            try:
                self.session.put(keys.world_cmd(self.fleet, keys.LAUNCHER), encode_control("stop"))
                self._wait_exit(self.opts.grace, told)  # the world stops the agents
            except zenoh.ZError as e:
                self.log(f"  could not ask the world to stop ({e}); stopping the processes")
        elif self.finished:  # the world ended the run and told the agents to stop
            self._wait_exit(self.opts.grace, told)
        # else the world died: nobody tells the agents to stop but the signals below
        for c in self.children.values():
            if c.running():
                c.signal_group(signal.SIGTERM)
                c.signal_group(signal.SIGCONT)  # a vehicle paused by a fault acts on its SIGTERM only once resumed
        self._wait_exit(self.opts.grace)
        for c in self.children.values():
            if c.running():
                self.log(f"  {c.name} did not stop; killing it")
                c.signal_group(signal.SIGKILL)
                c.proc.wait()
            c.poll()
        self.close_router()

    def close_router(self) -> None:
        """Close the router's session (its threads would keep the interpreter from exiting)."""
        if self.session is not None:
            try:
                self.session.close()
            except zenoh.ZError as e:
                self.log(f"  while closing the router: {e}")
            self.session = None
        if self.sockets is not None:
            shutil.rmtree(self.sockets, ignore_errors=True)

    def _wait_exit(self, seconds: float, names: set[str] | None = None) -> None:
        """Wait up to ``seconds`` for the children (those named in ``names``, else all) to exit."""
        deadline = time.monotonic() + seconds
        for n, c in self.children.items():
            if c.proc is None or (names is not None and n not in names):
                continue
            try:
                c.proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass


def launch(scenario: Scenario, run_dir: Path, router: Transport, opts: LaunchOptions,
           log: Callable[[str], None] | None = None) -> tuple[int, Launcher]:
    """Bring the fleet up, run it, bring it down. Returns (exit status, launcher).

    Exit status: 0 the run completed, 1 it failed (the message names who), 130 interrupted.
    """
    try:
        la = Launcher(scenario, run_dir, router, opts, **({"log": log} if log else {}))
    except OSError as e:  # scenario.json, logs/: a full disk, a read-only directory
        raise RunDirError(f"cannot write into the run directory {run_dir}: {e.strerror or e} ({e.filename}); "
                          f"nothing was started; make room or give another --logs") from None
    interrupted = False
    phase = {"stopping": False, "in_stop": False}

    def _term(signum, frame):
        # The first SIGINT/SIGTERM stops the fleet. While it stops, a SIGTERM changes nothing
        # (`timeout` and `pkill` each send one) and a second Ctrl-C kills at once, but only once
        # the stop is under way (never between the first signal and the stop).
        if not phase["stopping"]:
            phase["stopping"] = True
            raise KeyboardInterrupt
        if signum == signal.SIGINT and phase["in_stop"]:
            raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, _term)
    # A shell starting us in the background (`cdus launch ... &` in a script) ignores SIGINT
    # for us, and Python keeps it ignored: Ctrl-C / kill -INT must still stop the fleet cleanly.
    old_int = signal.signal(signal.SIGINT, _term)
    marks = {la.metrics_out: la.metrics_mark()}
    t0 = time.perf_counter()
    try:
        la.start()
        marks.update((p, la.metrics_mark(p)) for p in la.world_fallbacks())
        code = la.supervise()
        status = 0 if code == 0 else 1
        la.metrics_at = la.find_world_metrics(marks)
        if code == METRICS_ELSEWHERE_EXIT:  # the run ended; its files are not where asked: not a lost world
            where = (f"the metrics are in {la.metrics_at}" if la.metrics_at is not None
                     else "no file could take the metrics (they are printed in the world's log, if it could be written)")
            la.log(f"the world ended the run but could not write all its files where asked (its log says which and "
                   f"why); {where}. Its log ends with:\n{la.children['world'].tail()}")
        elif code != 0:
            la.log(f"world exited with status {code}; its log ends with:\n{la.children['world'].tail()}")
            if la.metrics_at is None:  # it wrote nothing: the launcher writes what it knows
                la.write_world_lost(code, time.perf_counter() - t0)
                if la.metrics_at is not None:
                    la.log(f"the world wrote no metrics: {la.metrics_at} written by the launcher "
                           f"(completed: false, completion: {WORLD_LOST!r}); stopping the fleet")
    except LaunchError as e:
        la.log(f"error: the fleet did not come up:\n{e}")
        status = 1
    except KeyboardInterrupt:
        interrupted = True
        status = 130
        la.log("\ninterrupted: stopping the fleet (the world writes what it has)")
    finally:
        phase["stopping"] = phase["in_stop"] = True
        try:
            la.stop()
            la._print_events(final=True)  # any heard while it stopped
        except KeyboardInterrupt:  # a second Ctrl-C: go straight to the kill
            for c in la.children.values():
                c.signal_group(signal.SIGKILL)
                c.poll()
            la.close_router()
        signal.signal(signal.SIGTERM, old)
        signal.signal(signal.SIGINT, old_int)
    if interrupted:
        status = 130
    if la.metrics_at is None:  # interrupted, or a world that exited 0: what it wrote while stopping
        la.metrics_at = la.find_world_metrics(marks) or (
            la.metrics_out if status == 0 and la.metrics_out.exists() else None)  # e.g. a pipe: no mark changes
    world = la.children.get(keys.WORLD)
    if (la.metrics_at is None and world is not None and world.exit_code is not None
            and world.exit_code not in (0, METRICS_ELSEWHERE_EXIT)):
        # a world that died before it could write anything (while the fleet came up, or killed
        # while it stopped): the launcher says so in the metrics, as for a world lost mid-run
        la.write_world_lost(world.exit_code, time.perf_counter() - t0)
    if la.rejected:
        la.log(f"  the launcher dropped {sum(la.rejected.values())} messages: "
               + ", ".join(f"{n} {r}" for r, n in sorted(la.rejected.items())))
    return status, la

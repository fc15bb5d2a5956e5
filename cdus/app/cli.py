"""What does the ``cdus`` command do with its command line? One entry point, a subcommand per job.

    cdus sim CONFIG      the whole fleet in one process (fast, deterministic)

Exit status: 0 done, 1 the run failed, 2 the configuration or the command line is
wrong (nothing was started), 130 interrupted (partial results were still written).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

import zenoh

from cdus.app.preflight import LINKS, ListenError, RunDirError, RunDirInUse, RunDirLock, check_listen
from cdus.app.executors import CONNECT_TIMEOUT_S, EXECUTORS
from cdus.app.sweepplan import RUNNERS
from cdus.app.sweepstore import PLOT_FORMATS, ROWS
from cdus.core.vehicle import DivergedError
from cdus.scenario.config import ConfigError, load_scenario, parse_overrides
from cdus.scenario.robot import clock_problem, robots
from cdus.core.linkspec import POLICIES
from cdus.scenario.model import RESTART_POLICIES, Scenario
from cdus.wire import keys
from cdus.wire.access import GROUND_ROLE, ROS2_CLIENT_ROLE, robot_role
from cdus.wire.transport import Transport, client_of, endpoint, exposed_endpoints, router_listen
from cdus.wire.transport import router as fleet_router
from ground_station.__main__ import main as gs_main
from world_sim.recording import parse_spec, recording_line
from cdus.app.report import Progress, run_dir, summary_table
from cdus.sim.reports import late_event_lines, limit_lines, obstacle_lines
from cdus.sim.runmetrics import Metrics
from cdus.files import keep_json, metrics_fallbacks

if TYPE_CHECKING:
    from cdus.app.launcher import LaunchOptions

# Each subcommand imports its own machinery where it runs (tests/test_layers.py, LAZY): `cdus gs`
# starts without the in-process API, the sweep, the launcher or the MCAP export
# (tests/test_startup.py).

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _overrides(args: argparse.Namespace) -> dict[str, Any]:
    """--duration, --seed and every --set KEY=VALUE as dotted config keys."""
    out = parse_overrides(getattr(args, "set", None) or [])
    if getattr(args, "duration", None) is not None:
        out["scenario.duration"] = args.duration
    if getattr(args, "seed", None) is not None:
        out["scenario.seed"] = args.seed
    if getattr(args, "ros2", False):
        out["ros2.enabled"] = True
    return out


def _add_run_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("config", help="scenario file (TOML), e.g. configs/lake_circle.toml")
    p.add_argument("--duration", type=float, metavar="S", help="simulated seconds (overrides scenario.duration)")
    p.add_argument("--seed", type=int, metavar="N", help="random seed (overrides scenario.seed)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override any config key, e.g. --set rates.control=20 --set vehicle.usv1.gains.k=2")
    p.add_argument("--metrics-out", metavar="PATH", help="metrics JSON (default: <run dir>/metrics.json)")
    p.add_argument("--trace-out", metavar="PATH", help="write the time series as .npz (numpy.load reads it)")
    p.add_argument("--runs-dir", default="runs", metavar="DIR", help="where run directories go (default: runs)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    p.add_argument("--rerun", default="auto", metavar="SINK",
                   help="where the Rerun stream goes: auto (default: a viewer if there is a display, else "
                        "<run dir>/recording.rrd) | off | spawn | save:PATH | connect[:URL]; comma-separated "
                        "for several, e.g. spawn,save:run.rrd")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="cdus", allow_abbrev=False,  # --seed must not pass for sweep's --seeds
                                     description="Cross-domain unmanned fleet emulator (DGVF over Zenoh)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p = sub.add_parser("sim", allow_abbrev=False, help="run a scenario with every vehicle in this one process",
                       description="Run the whole fleet in one process over an in-memory link.")
    _add_run_args(p)
    p.add_argument("--policy", choices=POLICIES, default=None,
                   help="stale-neighbour policy (default: the scenario's link.policy, else hold)")
    p.set_defaults(func=cmd_sim)

    p = sub.add_parser("launch", allow_abbrev=False, help="run a scenario as one OS process per vehicle over Zenoh",
                       description="Start world_sim and one vehicle_agent per vehicle, run, stop them all.")
    _add_run_args(p)
    p.add_argument("--fleet", metavar="NAME", help="fleet name, the key prefix cdus/<NAME>/ (default: the scenario name)")
    p.add_argument("--clock", choices=("realtime", "lockstep"), default="lockstep",
                   help="lockstep: deterministic, as fast as the machine allows (default); realtime: wall clock")
    p.add_argument("--restart", choices=RESTART_POLICIES, default=None,
                   help="restart policy for vehicle processes that exit during the run "
                        "(default: the scenario's supervision.restart, else never)")
    p.add_argument("--logs", metavar="DIR", help="run directory for logs, metrics, trace (default: runs/<name>-<time>)")
    p.add_argument("--policy", choices=POLICIES, default=None,
                   help="stale-neighbour policy (default: the scenario's link.policy, else hold)")
    p.add_argument("--ready-timeout", type=float, default=30.0, metavar="S",
                   help="how long each process may take to come up")
    p.add_argument("-l", "--listen", action="append", default=[], metavar="ENDPOINT", type=endpoint,
                   help="router endpoint(s) (default: tcp/127.0.0.1:<free port>); e.g. tcp/0.0.0.0:7447 "
                        "for agents on other hosts")
    p.add_argument("--zenoh-config", metavar="FILE", help="zenoh json5 config for the router (multicast forced off)")
    p.add_argument("--links", choices=LINKS, default=None,
                   help="router (default, and the only choice with --remote or a secured fleet): everything "
                        "through the router; direct: neighbours exchange ω over their own unix-socket links, "
                        "the rest through the router (measured slower on 2 cores; docs/architecture.md); direct "
                        "links skip the router's access control, so they need --insecure")
    p.add_argument("--remote", action="append", default=[], metavar="ID",
                   help="a vehicle started on another host (repeat, or ID,ID,...): not started here; the launcher "
                        "prints its command line and waits for it (docs/multihost.md)")
    p.add_argument("--secure", action="store_true",
                   help="the default, kept for old command lines: generate credentials for this run in "
                        "<run dir>/secure/ and require them: a Zenoh user and password per process, and an "
                        "access-control list on the router that lets each process publish only its own keys (a "
                        "ground station attaches with --zenoh-config <run dir>/secure/ground.json5)")
    p.add_argument("--tls", action="store_true",
                   help="the secured fleet over TLS: a private CA for the run, a certificate per process (mutual "
                        "TLS), the router's endpoints tls/...; the list also checks each certificate's name")
    p.add_argument("--insecure", action="store_true",
                   help="run the fleet open, without credentials or access control: anyone who reaches the "
                        "router (on loopback: any process of this host) can then stop, retune, kill and steer "
                        "the fleet (docs/security.md); needed for --links direct and for outside tools that "
                        "attach without credentials")
    p.add_argument("--ros2", action="store_true",
                   help="publish the fleet as ROS 2 topics in rmw_zenoh's format on the fleet's router (the "
                        "scenario's [ros2] table: domain, namespace, distro; docs/ros2.md)")
    p.set_defaults(func=cmd_launch)

    p = sub.add_parser("sweep", allow_abbrev=False,
                       help="run a grid of config values x seeds; a table, a summary and a plot",
                       description="Run a grid of overrides x seeds on local processes or a Dask cluster; each "
                                   "finished run is appended to --out/results.jsonl at once, and the same command "
                                   "again resumes (runs only what is missing). At the end: results.csv, "
                                   "results.parquet, summary.md (mean, sd, 95 % bootstrap CI per cell) and "
                                   "sweep.png (--plot-format pdf or svg: a vector sweep.pdf or sweep.svg).")
    p.add_argument("config", help="scenario file (TOML)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="a grid axis: a dotted config key and its values, e.g. --set link.loss=0,0.2,0.4")
    p.add_argument("--seeds", type=int, default=3, metavar="N", help="seeds per cell: the scenario's seed and the next N-1")
    p.add_argument("--clock", choices=RUNNERS, default="inproc",
                   help="inproc: one process per run (fast, parallel); lockstep: a launched fleet per run")
    p.add_argument("--duration", type=float, metavar="S", help="simulated seconds per run")
    p.add_argument("--jobs", type=int, metavar="J",
                   help="runs in parallel on this machine (default: the number of cores for inproc, 1 for "
                        "lockstep); with --executor dask, the LocalCluster's worker processes")
    p.add_argument("--executor", choices=EXECUTORS, default="local",
                   help="local: processes of this machine (default); dask: a Dask LocalCluster on 127.0.0.1")
    p.add_argument("--cluster", metavar="ADDRESS",
                   help="run on the running Dask scheduler at ADDRESS, e.g. tcp://127.0.0.1:8786 (its workers need "
                        "only the cdus package installed)")
    p.add_argument("--connect-timeout", type=float, default=CONNECT_TIMEOUT_S, metavar="S",
                   help=f"how long to try to reach --cluster (default {CONNECT_TIMEOUT_S:g} s)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="where the results go; the same DIR again resumes the same sweep")
    p.add_argument("--plot-format", choices=PLOT_FORMATS, default="png",
                   help="the plot's format: sweep.png (default), or a vector sweep.pdf or sweep.svg for a paper")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("export", allow_abbrev=False, help="a run's trace as ROS 2 messages in an MCAP file",
                       description="Write a run (its trace and scenario) as the ROS 2 topics `cdus launch --ros2` "
                                   "publishes, in an MCAP file Foxglove opens and `ros2 bag play` replays "
                                   "(docs/ros2.md).")
    p.add_argument("run_dir", metavar="RUN_DIR", help="the run's directory (cdus launch --logs)")
    p.add_argument("--mcap", required=True, metavar="FILE", help="the MCAP file to write")
    p.add_argument("--trace", metavar="PATH", help="the run's trace (default: RUN_DIR/trace.npz, what "
                                                   "--trace-out RUN_DIR/trace.npz wrote)")
    p.add_argument("--config", metavar="FILE", help="the run's scenario (default: RUN_DIR/scenario.json, which "
                                                    "cdus launch writes); its [ros2] table sets the topics")
    p.set_defaults(func=cmd_export)

    # `cdus gs ...` is handed to ground_station whole (see main); listed here for --help
    sub.add_parser("gs", help="ground station: watch and command a running fleet (cdus gs --help)", add_help=False)
    return parser


def _note_late_events(scenario: Scenario) -> None:
    """Say (not fail: --duration often shortens a run on purpose) which [[event]]s the run ends
    before (cdus.sim.reports.late_event_lines), once, where the run starts: `cdus sim` and
    `cdus launch` alike; the [[obstacle]] notes (the filter off, a vehicle starting inside one) and
    the vehicles on a plant with preset limits given none (unbounded actuators)."""
    for line in late_event_lines(scenario) + obstacle_lines(scenario) + limit_lines(scenario):
        print(line, file=sys.stderr)


def cmd_sim(args: argparse.Namespace) -> int:
    """`cdus sim`: cdus.api.run in process, its metrics (and trace) written, a summary printed."""
    from cdus import api

    scenario = api.load(args.config, _overrides(args))
    if (why := clock_problem(scenario, "inproc")) is not None:  # plant = "ros2": said as cdus sim's, not cdus.run's
        raise ConfigError("command line", [("cdus sim", why)])
    _note_late_events(scenario)
    out_dir = None
    metrics_out = args.metrics_out
    if metrics_out is None:
        out_dir = run_dir(args.runs_dir, scenario.name)
        metrics_out = out_dir / "metrics.json"
    try:
        parse_spec(args.rerun, Path(metrics_out).parent)  # the flag's own wording for a bad --rerun
    except ValueError as e:
        raise ConfigError("command line", [("--rerun", str(e))]) from None
    progress = Progress(f"{scenario.name}", quiet=args.quiet)
    status = EXIT_OK
    try:  # progress on stderr, the fleet's events on stdout, as `cdus launch` prints them
        result = api.run(scenario, policy=args.policy, rerun=args.rerun, run_dir=Path(metrics_out).parent,
                         progress=progress, events=not args.quiet)
    except api.RunInterrupted as e:
        status = EXIT_INTERRUPTED
        result = e.result
    progress.done()
    metrics = result.metrics.to_dict()
    say = lambda line: print(line, file=sys.stderr)  # noqa: E731
    kept = keep_json(metrics_out, metrics, metrics_fallbacks(metrics_out, None, f"sim-{os.getpid()}"), say)
    trace = args.trace_out
    if trace:
        try:
            result.trace.save(trace)
        except OSError as e:  # a full disk: said (no half a trace left); the metrics are kept
            say(f"error: could not write the trace to {trace}: {e.strerror or e}")
            if Path(trace).is_file():
                Path(trace).unlink(missing_ok=True)
            trace, status = None, status or EXIT_FAIL
    print(summary_table(result.metrics, scenario.vehicles))
    if kept is None:  # no file takes them: here they are
        print(f"  metrics (no file could take them):\n{json.dumps(metrics)}")
    else:
        print(f"  metrics: {kept}" + (f" (not {metrics_out}: it could not be written)" if kept != Path(metrics_out) else ""))
    if trace:
        print(f"  trace: {trace}")
    return status if kept == Path(metrics_out) else status or EXIT_FAIL


def _read_metrics(path: Path) -> Metrics | str:
    """The run's metrics file, typed (checked once, here); what is wrong with it, naming the file and the field."""
    try:
        return Metrics.read(path)
    except (OSError, ValueError) as e:
        return f"the run's metrics cannot be read: {e}"


def launch_options(args: argparse.Namespace, scenario: Scenario) -> LaunchOptions:
    """The launcher's options: the flags, and where a flag is not given, the scenario's
    (``--restart`` over ``[supervision] restart``)."""
    from cdus.app.launcher import LaunchOptions

    return LaunchOptions(
        fleet=args.fleet or scenario.name.replace(".", "_"), clock=args.clock, duration=args.duration,
        restart=args.restart or scenario.supervision.restart,
        metrics_out=Path(args.metrics_out) if args.metrics_out else None,
        trace_out=Path(args.trace_out) if args.trace_out else None, policy=args.policy,
        ready_timeout=args.ready_timeout, quiet=args.quiet, rerun=args.rerun, links=links_of_run(args),
        remote=remote_ids(args.remote, scenario))


def links_of_run(args: argparse.Namespace) -> str:
    """--links, by default router (measured faster on 2 cores, docs/architecture.md); router with vehicles on other hosts (unix sockets do not
    reach them) or a secured fleet, the default (direct links would bypass the router's access control):
    direct needs --insecure."""
    if args.links == "direct" and args.remote:
        raise ConfigError("command line", [("--links", "direct links are unix sockets between the vehicles on this "
                                                       "host and skip the router; with --remote use --links router")])
    if args.links == "direct" and not args.insecure:
        raise ConfigError("command line", [("--links", "direct links skip the router and its access control, so a "
                                                       "fleet is secured only with --links router (the default); add "
                                                       "--insecure to run an open fleet with direct links")])
    return args.links or "router"


def remote_ids(values: list[str], scenario: Scenario) -> tuple[str, ...]:
    """--remote ID (repeated or comma-separated), checked against the scenario's ids."""
    out = tuple(dict.fromkeys(v for value in values for v in value.split(",") if v))
    unknown = [v for v in out if v not in scenario.ids]
    if unknown:
        raise ConfigError("command line", [("--remote", f"no vehicle {', '.join(map(repr, unknown))} in "
                                                        f"{scenario.name}; ids are {', '.join(scenario.ids)}")])
    return out


#: completions of a run that ended early through no one's asking (an operator's stop is asked for):
#: `cdus launch` exits 1 for them, as for a world that failed, not 0 beside "completed: false"
NOT_COMPLETED_FAILS = ("vehicles_lost", "router_lost")


def cmd_launch(args: argparse.Namespace) -> int:
    scenario = load_scenario(args.config, _overrides(args))
    try:
        parse_spec(args.rerun, Path(args.logs or "."))  # a bad --rerun starts nothing
    except ValueError as e:
        raise ConfigError("command line", [("--rerun", str(e))]) from None
    opts = launch_options(args, scenario)
    if (why := clock_problem(scenario, args.clock)) is not None:  # plant = "ros2": realtime only
        raise ConfigError("command line", [("--clock", why)])
    try:
        keys.check_fleet(opts.fleet)
    except ValueError as e:
        raise ConfigError("command line", [("--fleet", str(e))]) from None
    if not args.insecure and args.zenoh_config and not args.listen:
        raise ConfigError("command line", [("--zenoh-config", "a secured fleet (the default) needs the router's "
                                                              "endpoints on the command line: give --listen too "
                                                              "(the credentials name them), or add --insecure to "
                                                              "run an open fleet")])
    router = fleet_router(args.listen, args.zenoh_config)
    exposed = check_exposure(args, router)
    try:  # a busy port is a usage error, found before any directory, credential or process
        check_listen(router_listen(router))
    except ListenError as e:
        raise ConfigError("command line", [("--listen" if args.listen else "--zenoh-config", str(e))]) from None
    made = not args.logs or not Path(args.logs).exists()
    run = Path(args.logs) if args.logs else run_dir(args.runs_dir, scenario.name)
    try:  # before anything is written into it (credentials, logs): one fleet per run directory
        lock = RunDirLock(run)
    except RunDirInUse as e:
        raise ConfigError("command line", [("--logs", str(e))]) from None
    except RunDirError as e:  # a read-only directory, a lock file that is a symlink or a directory
        print(f"error: {e}", file=sys.stderr)
        return EXIT_FAIL
    with lock:
        return _launch_into(args, scenario, opts, router, exposed, run, made)


def _launch_into(args: argparse.Namespace, scenario: Scenario, opts: LaunchOptions, router: Transport,
                 exposed: tuple[str, ...], run: Path, made: bool) -> int:
    """cmd_launch once the run directory is held: credentials, the fleet, the summary."""
    from cdus.app.fleet_run import secure_router
    from cdus.app.launcher import launch

    cred = None
    try:
        if not args.insecure:
            router, cred = secure_router(router, opts, scenario, run / "secure", "tls" if args.tls else "password")
    except OSError as e:  # a full disk, a read-only directory
        print(f"error: cannot write the run's credentials into {run / 'secure'}: {e.strerror or e}; nothing was "
              f"started; make room or give another --logs", file=sys.stderr)
        return EXIT_FAIL
    print(f"{scenario.name}: launching {len(scenario.vehicles) - len(opts.remote)} vehicle processes + world "
          f"({args.clock} clock), router {', '.join(router.listen) or args.zenoh_config}")
    _note_late_events(scenario)  # after the line that says the run starts, as `cdus sim` before its run
    if args.insecure:
        where = ", ".join(exposed) or f"this router ({', '.join(router.listen) or args.zenoh_config}: any " \
                                      f"process of this host)"
        print("  WARNING: --insecure: " + INSECURE_ALLOWS.format(eps=where), file=sys.stderr)
    if cred is not None:
        print(f"  secured ({cred.mode}): credentials in {cred.directory}; only the fleet's own processes and "
              f"ground stations holding {cred.file(GROUND_ROLE).name} may publish under cdus/{opts.fleet}/")
    gs_config = f" --zenoh-config {cred.file(GROUND_ROLE)}" if cred is not None else ""
    print(f"  attach a ground station: cdus gs --fleet {opts.fleet} -e "
          f"{(client_of(router).connect or ('ENDPOINT',))[0]}{gs_config} status")
    if scenario.ros2.enabled:
        r2 = scenario.ros2
        r2_config = f"ZENOH_SESSION_CONFIG_URI={cred.file(ROS2_CLIENT_ROLE)} " if cred is not None else ""
        print(f"  ROS 2 ({r2.distro}): /clock, /tf and {r2.namespace}/<vehicle>/... in domain {r2.domain_id}; from a ROS "
              f"2 machine: {r2_config}RMW_IMPLEMENTATION=rmw_zenoh_cpp ROS_DOMAIN_ID={r2.domain_id} ros2 topic list, "
              f"its Zenoh connected to {(client_of(router).connect or ('ENDPOINT',))[0]} (docs/ros2.md)")
    for vid, r in robots(scenario).items():  # where each robot connects, and as whom (docs/ros2.md)
        r_config = f"ZENOH_SESSION_CONFIG_URI={cred.file(robot_role(vid))} " if cred is not None else ""
        print(f"  robot {vid}: odometry on {r.odom}, commands on {r.cmd_vel}; on the robot: {r_config}"
              f"RMW_IMPLEMENTATION=rmw_zenoh_cpp ROS_DOMAIN_ID={scenario.ros2.domain_id}, its Zenoh connected to "
              f"{(client_of(router).connect or ('ENDPOINT',))[0]}")
    try:
        status, la = launch(scenario, run, router, opts)
    except RunDirError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_FAIL
    except ListenError as e:  # taken between the check and the router's start: still nothing was started
        if made:  # only the directory this command made (credentials, an empty logs/), never the user's
            shutil.rmtree(run, ignore_errors=True)
        raise ConfigError("command line", [("--listen" if args.listen else "--zenoh-config", str(e))]) from None
    metrics = _read_metrics(la.metrics_at) if la.metrics_at is not None else None
    if isinstance(metrics, Metrics):
        print(summary_table(metrics, scenario.vehicles))
        elsewhere = f" (not {la.metrics_out}: it could not be written)" if la.metrics_at != la.metrics_out else ""
        print(f"  metrics: {la.metrics_at}{elsewhere}\n  logs: {la.logs}")
        if status == 0 and metrics.completion in NOT_COMPLETED_FAILS:  # the run failed, honestly said
            print(f"error: the run did not complete: {metrics.completion} (the lines above say which vehicles "
                  f"were lost); exit 1", file=sys.stderr)
            status = EXIT_FAIL
    elif metrics is not None:  # a metrics file that is not one (cut short, from another version)
        print(f"error: {metrics}; logs: {la.logs}", file=sys.stderr)
        status = status or EXIT_FAIL
    else:
        print(f"no metrics file was written (the lines above say why); logs: {la.logs}", file=sys.stderr)
        status = status or EXIT_FAIL
    for target in parse_spec(args.rerun, run):  # what exists, also after a disk that filled or a killed world
        if target.kind == "save":
            print(recording_line(Path(target.where)))
    return status


INSECURE_ALLOWS = ("anyone who reaches {eps} can, without any credential: stop, pause or resume the fleet; change "
                   "its gains, link faults, formation and paths; have the launcher kill, pause or restart any "
                   "vehicle; publish any vehicle's ω and telemetry (steering the formation, forging results); forge the world's clock "
                   "and roster (a lockstep run can be made to stop or hang); flood any key (docs/security.md)")


def check_exposure(args: argparse.Namespace, router: Transport) -> tuple[str, ...]:
    """The rule of a safe default: every fleet is secured (credentials and the router's
    access-control list; --tls for TLS) unless --insecure says the user means it open. Checks
    the flags agree and the router's config parses; returns the endpoints other hosts can
    reach (anything but loopback, 127.0.0.0/8 and ::1, or a unix socket), for the warning."""
    if args.insecure and (args.secure or args.tls):
        raise ConfigError("command line", [("--insecure", "contradicts --secure/--tls; give one of them")])
    try:
        return exposed_endpoints(router)
    except zenoh.ZError as e:
        raise ConfigError("command line", [("--zenoh-config", str(e).split(" at /")[0])]) from None


def cmd_export(args: argparse.Namespace) -> int:
    """`cdus export RUN_DIR --mcap FILE`."""
    from cdus.ros2.export import ExportError, export_mcap

    run = Path(args.run_dir)
    scenario = load_scenario(args.config) if args.config else None
    try:
        counts = export_mcap(run, Path(args.mcap), Path(args.trace) if args.trace else None, scenario)
    except ExportError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    print(f"{args.mcap}: {sum(counts.values())} messages on {len(counts)} topics "
          f"(open it in Foxglove, or ros2 bag play {args.mcap})")
    return EXIT_OK


def cmd_sweep(args: argparse.Namespace) -> int:
    from cdus.app.sweep import SweepInterrupted, check_grid, parse_grid, sweep

    grid = parse_grid(args.set)
    over = {"scenario.duration": args.duration} if args.duration is not None else None
    check_grid(args.config, grid, over)
    def stop(signum: int, frame: Any) -> None:  # SIGTERM (a batch system's stop) ends the sweep as Ctrl-C does
        raise KeyboardInterrupt

    before = signal.signal(signal.SIGTERM, stop)
    try:
        res = sweep(args.config, grid, args.seeds, Path(args.out), clock=args.clock, executor=args.executor,
                    cluster=args.cluster, jobs=args.jobs, duration=args.duration, quiet=args.quiet,
                    connect_timeout=args.connect_timeout, plot_format=args.plot_format)
    except SweepInterrupted as e:
        print(f"\n{e.message}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except KeyboardInterrupt:  # a second Ctrl-C while the first one's tables were written or the workers stopped
        print(f"\ninterrupted again: the runs done are kept in {Path(args.out) / ROWS} (the tables may be those of "
              f"an earlier run, or missing). Run the same command again (same --out) to run the others and write "
              f"the tables.", file=sys.stderr)
        return EXIT_INTERRUPTED
    except OSError as e:  # the disk filled up or went read-only mid-sweep: whole rows are kept, a torn one cut
        print(f"error: writing the results into {args.out} failed: {e}. The runs done are kept in "
              f"{Path(args.out) / ROWS}; make room and run the same command again (same --out) to run the others.",
              file=sys.stderr)
        return EXIT_FAIL
    finally:
        signal.signal(signal.SIGTERM, before)
    print(res.summary.read_text())
    print(f"results: {res.csv} (and {res.parquet.name}, {ROWS})\nplot: {res.plot}"
          + (f"\n{res.failed} of {res.done} runs failed (see summary.md)" if res.failed else ""))
    if res.lost:
        print(f"{res.lost} runs were lost by the executor and not recorded: run the same command again to retry "
              f"them", file=sys.stderr)
        return EXIT_FAIL
    return EXIT_OK


def set_without_equals(argv: Sequence[str]) -> str | None:
    """``--set KEY VALUE`` (a space for the ``=``): what the user meant, ``--set KEY=VALUE``; None
    if every ``--set`` has its ``=``. argparse would take VALUE for an unknown argument and print
    the top-level usage ("unrecognized arguments: 0.2"), which says nothing of the slip. A VALUE
    that is an existing file is the config, not a forgotten value: left to argparse."""
    for i, a in enumerate(argv):
        if a == "--set":
            key, j = (argv[i + 1] if i + 1 < len(argv) else ""), i + 2
        elif a.startswith("--set="):
            key, j = a[len("--set="):], i + 1
        else:
            continue
        value = argv[j] if j < len(argv) else ""
        if not key or "=" in key or key.startswith("-") or not value or Path(value).is_file():
            continue
        if not value.startswith("-") or _is_number(value):
            return f"--set {key}={value}"
    return None


def _is_number(text: str) -> bool:
    try:
        float(text.split(",")[0])
    except ValueError:
        return False
    return True


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "gs":
        return gs_main(argv[1:], "cdus gs")
    meant = set_without_equals(argv[1:])
    if meant is not None:
        print(f"error: --set takes KEY=VALUE in one word: did you mean {meant}?", file=sys.stderr)
        print("nothing was started.", file=sys.stderr)
        return EXIT_USAGE
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        print("nothing was started.", file=sys.stderr)
        return EXIT_USAGE
    except DivergedError as e:  # the simulation itself cannot go on: say who and when, not a traceback
        print(f"error: {e}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())

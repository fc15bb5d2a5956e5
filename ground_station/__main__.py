"""How does an operator watch and command a running fleet? ``python -m ground_station`` (or `cdus gs`).

    cdus gs --fleet lake_circle -e tcp/127.0.0.1:7447 --zenoh-config RUN/secure/ground.json5 status
                                                                       # live table (Ctrl-C; ends with the run)
    cdus gs ... status --once                                          # one table, for scripts
    cdus gs ... status --json                                          # one JSON snapshot
    cdus gs ... watch --jsonl                                          # a JSON line per status and event
    cdus gs ... snapshot FILE                                          # the fleet's state to FILE (JSON)
    cdus gs ... console                                                # the live console (docs/console.md)
    cdus gs ... pause | resume | stop                                  # the whole fleet
    cdus gs ... link loss=0.3 delay.base=0.1 [--at 120]                # link faults from sim time t
    cdus gs ... gains k=2 c=1 [--vehicle usv1]                         # guidance gains
    cdus gs ... radio tx_power=20 station=[0,-60,0] [--at 120]         # [radio]: power (dBm), station x, y, mast base z (m)
    cdus gs ... kill usv2 | restart usv2 | pause-vehicle usv2 | resume-vehicle usv2
    cdus gs ... formation phases.usv2=3.1416 phases.uav2=3.1416      # new phases (ω units), others kept
    cdus gs ... formation offsets.usv2.usv1=3.141592653589793 offsets.usv3.usv2=1.0471975511965976
                                # or offsets on edges (usv2 listens to usv1), closing every cycle to 1e-9
    cdus gs ... path --vehicle uav1 family=circle center=[0,0,20] radius=15 speed=1.5

Every command is answered by the fleet's world: "applied from tick N (t = ... s)" or
"rejected: <reason>". Exit codes: 0 applied (or, for status/watch/snapshot, done),
1 rejected by the world, 2 usage error (nothing sent), 3 no answer (no fleet, no world,
or no reply within --timeout), 4 denied (the router refused: on a secured fleet, use the
run's --zenoh-config RUN/secure/ground.json5). `cdus launch` prints the router endpoint,
the fleet name and the credentials to attach with. docs/ground_station.md has the JSON fields.
"""

from __future__ import annotations

import argparse
import difflib
import json
import os
import sys
import threading
import time
from dataclasses import replace

import zenoh

from cdus.commands.base import Rejected
from cdus.commands.changes import Formation, Path
from cdus.commands.fleet import Pause, Resume, Stop
from cdus.commands.gains import Gains
from cdus.commands.link import Link
from cdus.commands.parse import BY_CLI, Command, parse_cli, wire_of
from cdus.commands.radio import Radio
from cdus.commands.vehicle import VEHICLE_FAULTS
from cdus.scenario.config import ConfigError
from cdus.scenario.link import validate_link
from cdus.wire.transport import add_transport_args, transport_from_args, with_default_endpoint
from cdus.files import write_json
from ground_station.console import (
    COMMAND_TIMEOUT, EXIT_DENIED, EXIT_NO_ANSWER, EXIT_USAGE, Answer, GroundStation, config_endpoints, credentials_fleet, credentials_user, default_name, listening, num,
    status_table,
)

#: a vehicle's faults by their CLI word (cdus.commands.vehicle): kill, pause-vehicle, resume-vehicle, restart
VEHICLE_ACTIONS = {f.NAMES.cli: f for f in VEHICLE_FAULTS}


GS_CONNECT_TIMEOUT_MS = 5000  # a ground station is interactive: say soon that nobody is there
STATUS_WAIT_S = 3.0  # the world publishes its status every second


#: the longest wait a --timeout or --interval may name (s, ~31 years): Zenoh's query refused
#: --timeout 1e20 ("negative timeout", a traceback), time.sleep an --interval past ~9.2e9
MAX_WAIT_S = 1e9


def _number(text: str) -> float:
    """A float, or nan for text that is none: the callers' range checks refuse it with their own
    message (argparse's own for a ValueError names the function: "invalid _positive value")."""
    try:
        return float(text)
    except ValueError:
        return float("nan")


def _positive(text: str) -> float:
    x = _number(text)
    if not 0 < x <= MAX_WAIT_S:
        raise argparse.ArgumentTypeError(f"must be a number of seconds > 0 and at most {MAX_WAIT_S:g}, got {text}")
    return x


def _sim_time(text: str) -> float:
    x = _number(text)
    if not 0 <= x < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a simulated time >= 0 s, got {text}")
    return x


def build_parser(prog: str = "cdus gs") -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=prog, allow_abbrev=False, description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fleet", required=True, help="the fleet's name (cdus launch prints it)")
    p.add_argument("--timeout", type=_positive, default=COMMAND_TIMEOUT,
                   help=f"seconds to wait for the world's answer to a command (default {COMMAND_TIMEOUT:g}); "
                        "none in time: exit 3")
    p.add_argument("--name", default=None,
                   help="this ground station's name in the fleet's event log (gs:NAME; default: host-pid)")
    add_transport_args(p, default_mode="client")
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    st = sub.add_parser("status", help="a live table of the fleet (one table when stdout is no terminal)")
    st.add_argument("--once", action="store_true", help="print one table and exit (the default in a pipe)")
    st.add_argument("--json", action="store_true", help="print one JSON snapshot (versioned) and exit")
    st.add_argument("--interval", type=_positive, default=1.0, help="seconds between refreshes")
    wa = sub.add_parser("watch", help="a stream: one JSON line per status (every --interval s) and per event")
    wa.add_argument("--jsonl", action="store_true", required=True, help="JSON lines on stdout (the only format)")
    wa.add_argument("--interval", type=_positive, default=1.0, help="seconds between status lines")
    sn = sub.add_parser("snapshot", help="save the fleet's state (the status --json object) to FILE, atomically")
    sn.add_argument("file", metavar="FILE")
    sub.add_parser("console", help="the live console: vehicles, edges, links, alarms; keys to pause, resume, "
                                   "kill and restart a vehicle or pause and resume the fleet (docs/console.md)")
    for cmd in (Pause, Resume, Stop):
        sub.add_parser(cmd.NAMES.cli, help=f"{cmd.NAMES.cli} the whole fleet")
    ln = sub.add_parser(Link.NAMES.cli, help="change link faults at run time: KEY=VALUE of the [link] table")
    ln.add_argument("settings", nargs="+", metavar="KEY=VALUE", help="e.g. loss=0.3 delay.base=0.1 policy=extrapolate")
    ln.add_argument("--at", type=_sim_time,
                    help="simulated time from which they apply (default and a past time: the first tick every vehicle "
                         "can take: past the grant in lockstep, 0.5 s ahead in realtime)")
    rd = sub.add_parser(Radio.NAMES.cli, help="change the radio at run time ([radio] scenarios): tx_power=DBM station=[x,y,z]")
    rd.add_argument("settings", nargs="+", metavar="KEY=VALUE", help="e.g. tx_power=20 (dBm) station=[0,-60,0] (x, y and the mast's base z above the water, m; the antenna is radio.antenna.station above it)")
    rd.add_argument("--at", type=_sim_time,
                    help="simulated time from which it applies (default and a past time: the first tick every vehicle "
                         "can take: past the grant in lockstep, 0.5 s ahead in realtime)")
    gn = sub.add_parser(Gains.NAMES.cli, help="change guidance gains: k=... c=...")
    gn.add_argument("settings", nargs="+", metavar="KEY=VALUE")
    gn.add_argument("--vehicle", help="one vehicle (default: all)")
    _change_parsers(sub)
    for name, fault in VEHICLE_ACTIONS.items():
        v = sub.add_parser(name, help=f"{fault.NAMES.event} one vehicle's process (via the launcher)")
        v.add_argument("vehicle")
    for action in sub.choices.values():  # also after the action (`kill usv2 --timeout 60`), as people type it
        action.allow_abbrev = False  # as the top level: `--time 5` is not taken for --timeout
        action.add_argument("--timeout", type=_positive, default=argparse.SUPPRESS,
                            help="as before the action: seconds to wait for the world's answer")
        action.add_argument("--name", default=argparse.SUPPRESS, help="as before the action: this ground station's name")
    return p


def parsed(args: argparse.Namespace) -> Command:
    """The command the arguments name (cdus.commands.parse.parse_cli), checked before anything is
    sent; a ConfigError (exit 2) naming the argument at fault."""
    got = parse_cli(args.action, getattr(args, "settings", ()), vehicle=getattr(args, "vehicle", None),
                    at=getattr(args, "at", None))
    if isinstance(got, Rejected):
        raise ConfigError("command line", [(got.field or args.action, got.reason)])
    return got


def _change_parsers(sub) -> None:
    """``formation`` and ``path``: a formation or path change at run time (docs/config.md, [[event]])."""
    fm = sub.add_parser(Formation.NAMES.cli, help="new formation: phases.ID=θ (ω units) or offsets.I.K=Δ (I listens to K)")
    fm.add_argument("settings", nargs="+", metavar="KEY=VALUE", help="e.g. phases.usv2=10.47 or offsets.usv2.usv1=2.09")
    pa = sub.add_parser(Path.NAMES.cli, help="a new path for one vehicle: family=... and its parameters")
    pa.add_argument("settings", nargs="+", metavar="KEY=VALUE", help="e.g. family=circle center=[0,0,20] radius=15")
    pa.add_argument("--vehicle", required=True, help="the vehicle that follows it")


def _check_vehicle(vid: str, ids: list, field: str = "vehicle") -> None:
    if ids and vid not in ids:
        raise ConfigError("command line", [(field, f"no vehicle {vid!r} in this fleet; its vehicles are "
                                                   f"{', '.join(ids)}")])


def check_formation_vehicles(change: Formation, ids: list) -> None:
    """Every id a formation change names is one of the fleet's; the error names the argument
    that held it (``phases.usv9``, ``offsets.usv2.usv9``), not a ``vehicle`` the user never typed."""
    for vid, _ in change.phases:
        _check_vehicle(vid, ids, f"phases.{vid}")
    for i, k, _ in change.offsets:
        for vid in (i, k):
            _check_vehicle(vid, ids, f"offsets.{i}.{k}")


def what_of(command: Command, fleet: str) -> str:
    """How a reply names a command: ``gains {'k': 2.0} for every vehicle``, ``kill usv2``."""
    if isinstance(command, (Pause, Resume, Stop)):
        return f"{command.NAMES.cli} of fleet {fleet!r}"
    if isinstance(command, Link):
        return f"link faults {command.link_table()}"
    if isinstance(command, Radio):
        return f"radio {command.change()}"
    if isinstance(command, Gains):
        return f"gains {command.fields()['gains']} for {command.vehicle or 'every vehicle'}"
    if isinstance(command, Formation):
        return f"formation {command.fields()['phases'] or command.fields()['offsets']}"
    if isinstance(command, Path):
        return f"path {command.path_table()} for {command.vehicle}"
    return f"{command.NAMES.cli} {command.vehicle}"


def _command(gs: GroundStation, command: Command, ids: list, timeout: float) -> int:
    """Check ``command``'s ids against the fleet's, send it, print what became of it: the exit code."""
    if isinstance(command, Link):
        validate_link(command.link_table(), ids, "command line")
    elif isinstance(command, Formation):
        check_formation_vehicles(command, ids)
    elif getattr(command, "vehicle", None) is not None:
        _check_vehicle(command.vehicle, ids, "vehicle" if type(command) in VEHICLE_FAULTS else "--vehicle")
    op, fields = wire_of(command)
    return _report(gs.command(op, timeout=timeout, **fields), what_of(command, gs.fleet))


def _report(answer: Answer, what: str) -> int:
    """Print what became of a command; its exit code."""
    r = answer.reply
    if answer.outcome == "applied":
        note = f" ({r.reason})" if r.reason else ""
        print(f"{what}: applied from tick {r.tick} (t = {num(r.t, '.2f')} s){note}" + (f", by {r.by}" if r.by else ""))
    elif answer.outcome == "rejected":
        print(f"error: {what}: rejected by the fleet: {r.reason or 'no reason given'}", file=sys.stderr)
    else:
        print(f"error: {what}: {answer.detail}", file=sys.stderr)
    return answer.code


def _leave(gs: GroundStation, code: int = 0) -> None:
    """The console's exit after `q`: close the session within 3 s, then leave even if a command's
    worker thread or Zenoh's close is still waiting (a router that has gone can hold a close;
    os._exit skips waiting for non-daemon threads)."""
    closer = threading.Thread(target=gs.close, daemon=True)
    closer.start()
    closer.join(3.0)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


STATUS_LOST_S = 10.0  # the live table ends when the world has sent no status for this long


def _run_ended(gs: GroundStation) -> str | None:
    """Why the live table stops (the world left: the run is over; or no status for
    STATUS_LOST_S s: the run ended with its router, or the link is down), None while it runs."""
    if gs.world_gone():
        return "the fleet's world has left: the run is over (the table above is its last status)"
    with gs.view.lock:
        at = gs.view.status_at
    if at is not None and time.monotonic() - at > STATUS_LOST_S:
        return (f"no status from the fleet for {STATUS_LOST_S:g} s: its run has ended or the link to its router is "
                "down (the table above is the last status heard)")
    return None


def _watch(gs: GroundStation, interval: float) -> int:
    """JSON lines until Ctrl-C or the end of the run: a status line every ``interval`` s, a line
    per event as it is heard, then an ``end`` line."""
    seen = 0
    last = 0.0
    while True:
        events, seen = gs.events_since(seen)
        for e in events:
            print(json.dumps({"v": 1, "kind": "event", "fleet": gs.fleet, "event": e.as_dict()}), flush=True)
        now = time.monotonic()
        if now - last >= interval:
            last = now
            print(json.dumps(gs.snapshot()), flush=True)
        if gs.world_gone():
            with gs.view.lock:
                completion = gs.view.world.completion if gs.view.world is not None else None
            print(json.dumps({"v": 1, "kind": "end", "fleet": gs.fleet, "reason": "the world left: the run is over",
                              "completion": completion}), flush=True)
            return 0
        time.sleep(0.05)


def _other_fleets(fleets: list[str], asked: str, of_credentials: str | None = None,
                  config_file: str | None = None) -> str:
    """What to add to "no status from fleet X": the fleet the credentials given are for (a
    secured router lets a ground station see no other), else the fleets running at the router."""
    if of_credentials is not None and of_credentials != asked:
        return (f"; the credentials in {config_file} are for fleet {of_credentials!r} "
                f"(did you mean --fleet {of_credentials}?)")
    others = [f for f in fleets if f != asked]
    if not others:
        return ""
    close = difflib.get_close_matches(asked, others, n=1, cutoff=0.6)
    shown = ", ".join(others[:10]) + (f" and {len(others) - 10} more" if len(others) > 10 else "")
    return f"; fleets running there: {shown}" + (f" (did you mean --fleet {close[0]}?)" if close else "")


def _unreachable(transport, e: Exception) -> int:
    """The session could not be opened: say whether a router is there at all."""
    eps = list(transport.connect) or config_endpoints(transport.config_file)
    endpoints = ", ".join(eps) or "the configured endpoint"
    up = [listening(ep) for ep in eps]
    why = str(e).split(" at /")[0]  # not the Rust source path
    if any(x is True for x in up):
        user = credentials_user(transport.config_file)
        held = (f"the credentials of {user!r} from {transport.config_file}" if user else
                f"the settings of {transport.config_file}" if transport.config_file else "no credentials")
        print(f"error: the fleet's router at {endpoints} is up but refused or closed this session, which "
              f"had {held}", file=sys.stderr)
        if transport.config_file:  # a file was given: not this run's ground credentials
            print("  each run makes its own credentials, and a fleet started without --insecure takes only "
                  "its own: use the ground.json5 of this run (the launcher prints the whole line: "
                  "--zenoh-config RUN/secure/ground.json5)", file=sys.stderr)
        else:
            print("  a fleet started without --insecure takes only its own credentials: add "
                  "--zenoh-config RUN/secure/ground.json5 (the launcher prints the whole line)", file=sys.stderr)
        return EXIT_DENIED
    print(f"error: could not reach the fleet's router at {endpoints} within "
          f"{GS_CONNECT_TIMEOUT_MS / 1000:g} s: {why}", file=sys.stderr)
    if all(x is False for x in up) and up:
        print("  nothing listens there: is the fleet running? (cdus launch prints the endpoint)", file=sys.stderr)
    if not transport.config_file:  # fleets are secured by default: the router refuses a session without them
        print("  a fleet started without --insecure takes only its own credentials: add "
              "--zenoh-config RUN/secure/ground.json5 (the launcher prints the whole line)", file=sys.stderr)
    return EXIT_NO_ANSWER


def _config_problem(path: str | None) -> str | None:
    """Why the ``--zenoh-config`` file cannot be used (missing, unreadable, not json5), else None:
    a usage error said as such, not a router that "refused this session"."""
    if not path:
        return None
    try:
        zenoh.Config.from_file(path)
    except (zenoh.ZError, OSError) as e:
        why = " ".join(str(e).split(" at /")[0].split())  # one line, not the Rust source path
        return (f"--zenoh-config {path}: cannot be read as a Zenoh config: {why}; use the credentials file "
                "cdus launch printed (RUN/secure/ground.json5)")
    return None


def _file_sets_connect_timeout(path: str | None) -> bool:
    """Does a Zenoh config file (JSON, as cdus writes them) set ``connect.timeout_ms`` itself?"""
    if not path:
        return False
    try:
        with open(path) as fh:
            return "timeout_ms" in json.load(fh)["connect"]
    except (OSError, ValueError, KeyError, TypeError):
        return False


def gs_transport(args: argparse.Namespace):
    """The ground station's transport: GS_CONNECT_TIMEOUT_MS to reach the router, unless the
    ``--zenoh-config`` file sets its own and no ``-e`` overrides it. It was given only without a
    file, so the documented line (``-e ... --zenoh-config RUN/secure/ground.json5``) waited the
    agents' 30 s (CONNECT_TIMEOUT_S, set with every ``-e``) for a fleet that had ended, then said
    "within 5 s"."""
    transport = with_default_endpoint(transport_from_args(args))
    if transport.connect or not _file_sets_connect_timeout(transport.config_file):
        transport = replace(transport, extra=(*transport.extra, ("connect/timeout_ms", str(GS_CONNECT_TIMEOUT_MS))))
    return transport


def main(argv=None, prog: str = "python -m ground_station") -> int:
    args = build_parser(prog).parse_args(argv)
    problem = _config_problem(args.zenoh_config)
    if problem:
        print(f"error: {problem}\nnothing was sent.", file=sys.stderr)
        return EXIT_USAGE
    transport = gs_transport(args)
    try:
        gs = GroundStation(args.fleet, transport, name=args.name or default_name())
    except ValueError as e:  # the fleet name, the ground station's
        print(f"error: {'--fleet' if 'fleet' in str(e) else '--name'}: {e}", file=sys.stderr)
        return EXIT_USAGE
    try:
        # what can be checked before connecting
        command = parsed(args) if args.action in BY_CLI else None
        if args.action == "snapshot" and args.file in ("", "-"):  # wrote a file named '-', or said 'Is a directory (.)'
            raise ConfigError("command line", [("FILE", f"{args.file!r} names no file: give a file name (status --json "
                                                        "prints the same object on stdout)")])
        elif args.action == "snapshot" and os.path.isdir(args.file):
            raise ConfigError("command line", [("FILE", f"{args.file} is a directory: name the file to write, "
                                                        f"e.g. {os.path.join(args.file, 'state.json')}")])
        gs.open(watch=True)
        if not gs.wait_for_status(STATUS_WAIT_S):
            print(f"error: no status from fleet {args.fleet!r} within {STATUS_WAIT_S:g} s at "
                  f"{', '.join(transport.connect) or 'the configured endpoint'}: is it running? "
                  "(cdus launch prints the fleet name and the endpoint to attach to)"
                  + _other_fleets(gs.fleets_here(), args.fleet, credentials_fleet(transport.config_file),
                                  transport.config_file), file=sys.stderr)
            return EXIT_NO_ANSWER
        # the world's ids: names of the key space (letters, digits, _ and -), as decode_status checked them
        ids = list(gs.view.world.ids) if gs.view.world is not None else []
        if args.action == "console":
            from ground_station.tui import ConsoleApp  # Textual only for the console

            ConsoleApp(gs).run()
            _leave(gs)  # never returns
        if args.action in ("status", "watch", "snapshot"):
            gs.fetch_last()  # a paused fleet sends no telemetry: the world says where each vehicle is
        if args.action == "status":
            if args.json:
                print(json.dumps(gs.snapshot(settings=True), indent=2))
                return 0
            if args.once or not sys.stdout.isatty():  # a pipe or a file gets one table, no screen clears
                print(status_table(gs.view))
                return 0
            while True:
                print("\033[2J\033[H" + status_table(gs.view), flush=True)
                ended = _run_ended(gs)
                if ended:
                    print(ended, flush=True)
                    return 0
                time.sleep(args.interval)
        elif args.action == "watch":
            return _watch(gs, args.interval)
        elif args.action == "snapshot":
            try:
                write_json(args.file, gs.snapshot(settings=True))
            except OSError as e:  # a directory that cannot be made or written, a read-only file system
                print(f"error: could not write the snapshot to {args.file}: {e.strerror or e}"
                      + (f" ({e.filename})" if e.filename and str(e.filename) != args.file else ""), file=sys.stderr)
                return EXIT_USAGE
            print(f"fleet {args.fleet!r} saved to {args.file}")
            return 0
        else:
            return _command(gs, command, ids, args.timeout)
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except zenoh.ZError as e:  # no router at the endpoint, or one that refused this session
        return _unreachable(transport, e)
    except KeyboardInterrupt:
        return 0
    except BrokenPipeError:  # `watch --jsonl | head -n 5`: the reader has what it wanted (was a traceback)
        _stdout_gone()
        return 0
    finally:
        gs.close()


def _stdout_gone() -> None:
    """stdout's reader left: point stdout at /dev/null (by dup2, nothing renamed) so the exit's
    flush of what is still buffered does not raise again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError):
        pass


if __name__ == "__main__":
    sys.exit(main())

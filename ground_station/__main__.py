"""python -m ground_station (or `cdus gs`): watch and command a running fleet.

    cdus gs --fleet lake_circle -e tcp/127.0.0.1:7447 status          # live table (Ctrl-C to leave)
    cdus gs --fleet lake_circle -e tcp/127.0.0.1:7447 status --once   # one table, for scripts
    cdus gs --fleet lake_circle -e tcp/127.0.0.1:7447 console         # the live console (docs/console.md)
    cdus gs ... pause | resume | stop                                  # the whole fleet
    cdus gs ... link loss=0.3 delay.base=0.1 [--at 120]                # link faults from sim time t
    cdus gs ... gains k=2 c=1 [--vehicle usv1]                         # guidance gains
    cdus gs ... kill usv2 | restart usv2 | pause-vehicle usv2 | resume-vehicle usv2

`cdus launch` prints the router endpoint and the fleet name to attach to.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace

import zenoh

from cdus.scenario.config import ConfigError, parse_value
from cdus.scenario.link import validate_link
from cdus.wire.keys import FLEET_RE
from cdus.wire.transport import add_transport_args, transport_from_args, with_default_endpoint
from ground_station.console import GroundStation, num, status_table

VEHICLE_ACTIONS = {"kill": "kill", "restart": "restart", "pause-vehicle": "pause", "resume-vehicle": "resume"}


GS_CONNECT_TIMEOUT_MS = 5000  # a ground station is interactive: say soon that nobody is there
STATUS_WAIT_S = 3.0  # the world publishes its status every second


def _positive(text: str) -> float:
    x = float(text)
    if not x > 0 or x == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a number of seconds > 0, got {text}")
    return x


def _sim_time(text: str) -> float:
    x = float(text)
    if not 0 <= x < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a simulated time >= 0 s, got {text}")
    return x


def build_parser(prog: str = "cdus gs") -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=prog, allow_abbrev=False, description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fleet", required=True, help="the fleet's name (cdus launch prints it)")
    add_transport_args(p, default_mode="client")
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    st = sub.add_parser("status", help="a live table of the fleet")
    st.add_argument("--once", action="store_true", help="print one table and exit")
    st.add_argument("--interval", type=_positive, default=1.0, help="seconds between refreshes")
    sub.add_parser("console", help="the live console: vehicles, edges, links, alarms; keys to pause, resume, "
                                   "kill and restart a vehicle or pause and resume the fleet (docs/console.md)")
    for op in ("pause", "resume", "stop"):
        sub.add_parser(op, help=f"{op} the whole fleet")
    ln = sub.add_parser("link", help="change link faults at run time: KEY=VALUE of the [link] table")
    ln.add_argument("settings", nargs="+", metavar="KEY=VALUE", help="e.g. loss=0.3 delay.base=0.1 policy=extrapolate")
    ln.add_argument("--at", type=_sim_time,
                    help="simulated time from which they apply (default: now + 0.5 s; a past time means now)")
    gn = sub.add_parser("gains", help="change guidance gains: k=... c=...")
    gn.add_argument("settings", nargs="+", metavar="KEY=VALUE")
    gn.add_argument("--vehicle", help="one vehicle (default: all)")
    for name in VEHICLE_ACTIONS:
        v = sub.add_parser(name, help=f"{name.replace('-vehicle', '')} one vehicle's process (via the launcher)")
        v.add_argument("vehicle")
    return p


def nested(settings: list[str]) -> dict:
    """["loss=0.3", "delay.base=0.1"] -> {"loss": 0.3, "delay": {"base": 0.1}}."""
    out: dict = {}
    for item in settings:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError("command line", [(item, "expected KEY=VALUE, e.g. loss=0.3")])
        node = out
        parts = key.split(".")
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = parse_value(value)
    return out


def _positive_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and 0 < x < float("inf")


def check_gains(gains: dict, vehicle: str | None) -> None:
    """k: a number > 0 (every axis) or, for one vehicle (--vehicle), one per axis; c: a number > 0."""
    bad = sorted(set(gains) - {"k", "c"})
    if bad:
        raise ConfigError("command line", [(bad[0], "gains are k (a number or, with --vehicle, one per axis) and c")])
    if not gains:
        raise ConfigError("command line", [("gains", "give k=... and/or c=...")])
    k = gains.get("k", 1.0)
    if isinstance(k, list):
        if vehicle is None:
            raise ConfigError("command line", [("k", "one value per axis needs --vehicle (boats have 2 axes, "
                                                     "drones 3); a single number sets every axis")])
        if not k or not all(_positive_number(x) for x in k):
            raise ConfigError("command line", [("k", f"must be numbers > 0, got {k}")])
    elif not _positive_number(k):
        raise ConfigError("command line", [("k", f"must be a number > 0, got {k!r}")])
    if "c" in gains and not _positive_number(gains["c"]):
        raise ConfigError("command line", [("c", f"must be a number > 0, got {gains['c']!r}")])


def _check_vehicle(vid: str, ids: list) -> None:
    if ids and vid not in ids:
        raise ConfigError("command line", [("vehicle", f"no vehicle {vid!r} in this fleet; its vehicles are "
                                                       f"{', '.join(ids)}")])


def main(argv=None, prog: str = "python -m ground_station") -> int:
    args = build_parser(prog).parse_args(argv)
    transport = with_default_endpoint(transport_from_args(args))
    if transport.connect and not transport.config_file:
        transport = replace(transport, extra=(*transport.extra, ("connect/timeout_ms", str(GS_CONNECT_TIMEOUT_MS))))
    try:
        gs = GroundStation(args.fleet, transport)
    except ValueError as e:  # the fleet name
        print(f"error: --fleet: {e}", file=sys.stderr)
        return 2
    try:
        # what can be checked before connecting
        if args.action == "gains":
            gains = nested(args.settings)
            check_gains(gains, args.vehicle)
        elif args.action == "link":
            table = nested(args.settings)
            validate_link(table, None, "command line")
        gs.open(watch=True)
        if not gs.wait_for_status(STATUS_WAIT_S):
            print(f"error: no status from fleet {args.fleet!r} within {STATUS_WAIT_S:g} s at "
                  f"{', '.join(transport.connect) or 'the configured endpoint'}: is it running? "
                  "(cdus launch prints the fleet name and the endpoint to attach to)", file=sys.stderr)
            return 1
        # the world's ids: names of the key space (letters, digits, _ and -), nothing else is trusted
        ids = [i for i in (gs.view.world or {}).get("ids") or [] if isinstance(i, str) and FLEET_RE.match(i)]
        if args.action == "console":
            from ground_station.tui import ConsoleApp  # Textual only for the console

            ConsoleApp(gs).run()
            return 0
        if args.action == "status":
            if args.once:
                print(status_table(gs.view))
                return 0
            while True:
                print("\033[2J\033[H" + status_table(gs.view), flush=True)
                time.sleep(args.interval)
        elif args.action in ("pause", "resume", "stop"):
            gs.fleet_command(args.action)
            print(f"{args.action} sent to fleet {args.fleet!r}")
        elif args.action == "link":
            validate_link(table, ids, "command line")
            gs.set_link(table, args.at)
            t_now = gs.sim_time() or 0.0
            when = ("as soon as the world can" if args.at is None else f"from t = {args.at:.2f} s"
                    if args.at > t_now else f"now (t = {args.at:.2f} s is past; the world is at {num(t_now, '.1f')} s)")
            print(f"link faults {table} {when}: sent to fleet {args.fleet!r}")
        elif args.action == "gains":
            if args.vehicle is not None:
                _check_vehicle(args.vehicle, ids)
            gs.set_gains(gains, args.vehicle)
            print(f"gains {gains} sent to {args.vehicle or 'every vehicle'}")
        else:
            _check_vehicle(args.vehicle, ids)
            gs.vehicle_fault(VEHICLE_ACTIONS[args.action], args.vehicle)
            print(f"{args.action} {args.vehicle} sent to fleet {args.fleet!r}")
        time.sleep(0.2)  # let the put leave before the session closes
        return 0
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except zenoh.ZError as e:  # no router at the endpoint
        why = str(e).split(" at /")[0]  # not the Rust source path
        print(f"error: could not reach the fleet's router at {', '.join(transport.connect)} within "
              f"{GS_CONNECT_TIMEOUT_MS / 1000:g} s: {why}", file=sys.stderr)
        if not transport.config_file:  # fleets are secured by default: the router refuses a session without them
            print("  a fleet started without --insecure takes only its own credentials: add "
                  "--zenoh-config RUN/secure/ground.json5 (the launcher prints the whole line)", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 0
    finally:
        gs.close()


if __name__ == "__main__":
    sys.exit(main())

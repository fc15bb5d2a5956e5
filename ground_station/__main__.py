"""python -m ground_station (or `cdus gs`): watch and command a running fleet.

    cdus gs --fleet lake_circle -e tcp/127.0.0.1:7447 status          # live table (Ctrl-C to leave)
    cdus gs --fleet lake_circle -e tcp/127.0.0.1:7447 status --once   # one table, for scripts
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

import zenoh

from cdus.scenario.config import ConfigError, parse_value
from cdus.scenario.link import validate_link
from cdus.wire.transport import add_transport_args, transport_from_args, with_default_endpoint
from ground_station.console import GroundStation, status_table

VEHICLE_ACTIONS = {"kill": "kill", "restart": "restart", "pause-vehicle": "pause", "resume-vehicle": "resume"}


def build_parser(prog: str = "cdus gs") -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=prog, allow_abbrev=False, description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fleet", required=True, help="the fleet's name (cdus launch prints it)")
    add_transport_args(p, default_mode="client")
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    st = sub.add_parser("status", help="a live table of the fleet")
    st.add_argument("--once", action="store_true", help="print one table and exit")
    st.add_argument("--interval", type=float, default=1.0, help="seconds between refreshes")
    for op in ("pause", "resume", "stop"):
        sub.add_parser(op, help=f"{op} the whole fleet")
    ln = sub.add_parser("link", help="change link faults at run time: KEY=VALUE of the [link] table")
    ln.add_argument("settings", nargs="+", metavar="KEY=VALUE", help="e.g. loss=0.3 delay.base=0.1 policy=extrapolate")
    ln.add_argument("--at", type=float, help="simulated time from which they apply (default: now + 0.5 s)")
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


def main(argv=None, prog: str = "python -m ground_station") -> int:
    args = build_parser(prog).parse_args(argv)
    transport = with_default_endpoint(transport_from_args(args))
    gs = GroundStation(args.fleet, transport)
    try:
        gs.open(watch=True)
        if args.action == "status":
            gs.wait_for_status(3.0)
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
            table = nested(args.settings)
            if not gs.wait_for_status(3.0):
                print(f"error: no status from fleet {args.fleet!r} within 3 s: is it running?", file=sys.stderr)
                return 1
            validate_link(table, (gs.view.world or {}).get("ids") or [], "command line")
            gs.set_link(table, args.at)
            when = "as soon as the world can" if args.at is None else f"from t = {args.at:.2f} s"
            print(f"link faults {table} {when}: sent to fleet {args.fleet!r}")
        elif args.action == "gains":
            gains = nested(args.settings)
            bad = sorted(set(gains) - {"k", "c"})
            if bad:
                raise ConfigError("command line", [(bad[0], "gains are k (a number or per-axis list) and c")])
            gs.set_gains(gains, args.vehicle)
            print(f"gains {gains} sent to {args.vehicle or 'every vehicle'}")
        else:
            gs.vehicle_fault(VEHICLE_ACTIONS[args.action], args.vehicle)
            print(f"{args.action} {args.vehicle} sent to fleet {args.fleet!r}")
        time.sleep(0.2)  # let the put leave before the session closes
        return 0
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except zenoh.ZError as e:  # no router at the endpoint
        print(f"error: could not reach the fleet's router at {', '.join(transport.connect)}: {e}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 0
    finally:
        gs.close()


if __name__ == "__main__":
    sys.exit(main())

"""What does ``python -m cdus.ros2 --config FILE --fleet NAME [transport flags]`` run? The ROS 2 bridge.

Started by `cdus launch --ros2` (docs/ros2.md); it publishes the fleet named --fleet, on the
Zenoh it connects to, as ROS 2 topics in rmw_zenoh's format, as the scenario's [ros2] says.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

from cdus.ros2.bridge import run_bridge
from cdus.scenario.config import ConfigError, load_scenario, parse_overrides
from cdus.wire.transport import add_transport_args, open_session, transport_from_args, with_default_endpoint


#: a transient-local topic is an advanced publisher with a cache, as rmw_zenoh's: Zenoh needs timestamps for it
TIMESTAMPS = ("timestamping/enabled", "{router: true, peer: true, client: true}")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m cdus.ros2", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", required=True, help="scenario file (.toml, or the .json a launcher resolved)")
    p.add_argument("--fleet", default="default", help="fleet name: the key-space prefix cdus/<fleet>/")
    p.add_argument("--clock", help="(ignored: the launcher passes every child the same flags)")
    p.add_argument("--duration", type=float, help="simulated seconds (default: the scenario's): telemetry of a later "
                                                  "tick is forged")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a config key")
    add_transport_args(p)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        scenario = load_scenario(args.config, parse_overrides(args.set))
    except ConfigError as e:
        parser.error(str(e))  # exits 2
    t = with_default_endpoint(transport_from_args(args))
    session = open_session(replace(t, extra=(*t.extra, TIMESTAMPS)))
    try:
        return run_bridge(scenario, args.fleet, session, args.duration)
    finally:
        session.close()


if __name__ == "__main__":
    sys.exit(main())

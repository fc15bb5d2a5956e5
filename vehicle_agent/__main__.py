"""How is one vehicle started as its own process? ``python -m vehicle_agent --config FILE --id ID [...]``.

Usually started by `cdus launch`; start it by hand to put a vehicle on another host:

    python -m vehicle_agent --config configs/lake_circle.toml --id usv1 --fleet lake \\
        --connect tcp/192.168.1.10:7447
"""

from __future__ import annotations

import argparse
import sys

from cdus.scenario.config import ConfigError, load_scenario, parse_overrides
from cdus.core.linkspec import POLICIES
from cdus.core.schedule import CLOCKS
from cdus.wire.transport import add_transport_args, transport_from_args, with_default_endpoint
from vehicle_agent.agent import Agent, run_agent
from vehicle_agent.robot import RobotAgent


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m vehicle_agent", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", required=True, help="scenario file (.toml, or the .json a launcher resolved)")
    p.add_argument("--id", required=True, help="this vehicle's id in the scenario")
    p.add_argument("--fleet", default="default", help="fleet name: the key-space prefix cdus/<fleet>/")
    p.add_argument("--clock", choices=CLOCKS, default="realtime")
    p.add_argument("--duration", type=float, help="simulated seconds (default: the scenario's)")
    p.add_argument("--policy", choices=POLICIES, help="stale-neighbour policy (default: the scenario's link.policy)")
    p.add_argument("--rejoin", action="store_true",
                   help="join a run under way (a restart): do not wait for listeners that are not alive")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a config key")
    add_transport_args(p, default_mode="client")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        scenario = load_scenario(args.config, parse_overrides(args.set))
        if args.id not in scenario.ids:
            print(f"error: {args.config}: no vehicle with id {args.id!r}; ids are {', '.join(scenario.ids)}",
                  file=sys.stderr)
            return 2
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    transport = with_default_endpoint(transport_from_args(args))
    make = RobotAgent if scenario.vehicle(args.id).robot is not None else Agent  # plant = "ros2": a real robot
    agent = make(scenario, args.id, args.fleet, transport, clock=args.clock, policy=args.policy,
                  duration=args.duration, rejoin=args.rejoin)
    return run_agent(agent)


if __name__ == "__main__":
    sys.exit(main())

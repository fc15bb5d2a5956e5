"""How is the world process started? ``python -m world_sim --config FILE [...]``.

Usually started by `cdus launch`. By hand, e.g. as the router of a multi-host fleet:

    python -m world_sim --config configs/lake_circle.toml --fleet lake --listen tcp/0.0.0.0:7447
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cdus.scenario.config import ConfigError, load_scenario, parse_overrides
from cdus.core.linkspec import POLICIES
from cdus.core.schedule import CLOCKS
from cdus.wire.transport import add_transport_args, transport_from_args, with_default_endpoint
from world_sim.sinks import make_sink  # imports Rerun only for a recording
from world_sim.world import World, run_world


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m world_sim", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--config", required=True, help="scenario file (.toml, or the .json a launcher resolved)")
    p.add_argument("--fleet", default="default", help="fleet name: the key-space prefix cdus/<fleet>/")
    p.add_argument("--clock", choices=CLOCKS, default="lockstep")
    p.add_argument("--duration", type=float, help="simulated seconds (default: the scenario's)")
    p.add_argument("--metrics-out", metavar="PATH", default="metrics.json")
    p.add_argument("--trace-out", metavar="PATH")
    p.add_argument("--start-timeout", type=float, default=60.0, metavar="S",
                   help="how long to wait for every vehicle to come up")
    p.add_argument("--rerun", default="off", metavar="SINK",
                   help="off | spawn | save:PATH | connect:URL (comma-separated for several)")
    p.add_argument("--run-dir", metavar="DIR", help="where a default recording goes")
    p.add_argument("--policy", choices=POLICIES, help="the stale-neighbour policy the agents use (for the metrics)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a config key")
    add_transport_args(p, default_mode="router")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        scenario = load_scenario(args.config, parse_overrides(args.set))
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    transport = with_default_endpoint(transport_from_args(args))
    try:
        sink = make_sink(args.rerun, Path(args.run_dir) if args.run_dir else None)
    except ValueError as e:
        print(f"error: --rerun: {e}", file=sys.stderr)
        return 2
    world = World(scenario, args.fleet, transport, clock=args.clock, duration=args.duration,
                  metrics_out=args.metrics_out, trace_out=args.trace_out, start_timeout=args.start_timeout,
                  sink=sink, policy=args.policy, run_dir=args.run_dir)
    return run_world(world)


if __name__ == "__main__":
    sys.exit(main())

"""The ``cdus`` command: one entry point, a subcommand per job.

    cdus sim CONFIG      the whole fleet in one process (fast, deterministic)

Exit status: 0 done, 1 the run failed, 2 the configuration or the command line is
wrong (nothing was started), 130 interrupted (partial results were still written).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Sequence

from cdus.config import ConfigError, load_scenario, parse_value
from cdus.report import Progress, run_dir, summary_table, write_json

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


def _overrides(args: argparse.Namespace) -> dict[str, Any]:
    """--duration, --seed and every --set KEY=VALUE as dotted config keys."""
    out: dict[str, Any] = {}
    for item in getattr(args, "set", None) or []:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ConfigError("command line", [("--set", f"expected KEY=VALUE (e.g. rates.control=20), got {item!r}")])
        out[key.strip()] = parse_value(value.strip())
    if getattr(args, "duration", None) is not None:
        out["scenario.duration"] = args.duration
    if getattr(args, "seed", None) is not None:
        out["scenario.seed"] = args.seed
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="cdus", description="Cross-domain unmanned fleet emulator (DGVF over Zenoh)")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    p = sub.add_parser("sim", help="run a scenario with every vehicle in this one process",
                       description="Run the whole fleet in one process over an in-memory link.")
    _add_run_args(p)
    p.add_argument("--policy", choices=("hold", "timeout", "extrapolate"), default=None,
                   help="stale-neighbour policy (default: the scenario's link.policy, else hold)")
    p.set_defaults(func=cmd_sim)
    return parser


def cmd_sim(args: argparse.Namespace) -> int:
    from world_sim.fleet import InProcessFleet

    scenario = load_scenario(args.config, _overrides(args))
    out_dir = None
    metrics_out = args.metrics_out
    if metrics_out is None:
        out_dir = run_dir(args.runs_dir, scenario.name)
        metrics_out = out_dir / "metrics.json"
    policy = args.policy or scenario.link.get("policy", "hold")
    fleet = InProcessFleet(scenario, policy=policy, timeout=float(scenario.link.get("timeout", 1.5)))
    progress = Progress(f"{scenario.name}", quiet=args.quiet)
    status = EXIT_OK
    try:
        result = fleet.run(progress=progress)
        metrics = result.metrics
    except KeyboardInterrupt:
        status = EXIT_INTERRUPTED
        metrics = fleet.partial_metrics()
        metrics["interrupted"] = True
    progress.done()
    write_json(metrics_out, metrics)
    if args.trace_out:
        fleet.recorder.save_trace(args.trace_out)
    print(summary_table(metrics, fleet.vehicles))
    print(f"  metrics: {metrics_out}" + (f"\n  trace: {args.trace_out}" if args.trace_out else ""))
    return status


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        print("nothing was started.", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())

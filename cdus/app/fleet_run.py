"""How does the Python API run a lockstep fleet of processes (cdus.api.run(clock="lockstep"))?
With the launcher, and the credentials step `cdus launch` shares with it.

Kept apart from cdus.api because it brings in Zenoh (the router, the credentials): the API
imports this module only when a lockstep run is asked for, so ``import cdus`` stays light.
The fleet is `cdus launch --clock lockstep`'s: the launcher (cdus.app.launcher) with its own
router on a fresh loopback port (multicast scouting off, cdus.wire.transport), secured by
default, every process stopped at the end, on Ctrl-C or SIGTERM, and when the caller dies.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Callable

from cdus.app.credentials import Credentials, CredentialsError, make_credentials
from cdus.app.launcher import LaunchOptions, RunDirError, RunDirInUse, RunDirLock, launch
from cdus.scenario.config import ConfigError
from cdus.scenario.model import Scenario
from cdus.sim.build import listeners_of
from cdus.ros2.fleet import grant, robot_grants
from cdus.wire.access import ROS2_ROLE, WORLD_ROLE, vehicle_role
from cdus.wire.transport import Transport
from cdus.wire.transport import router as fleet_router


def secure_router(router: Transport, opts: LaunchOptions, scenario: Scenario, directory: Path,
                  mode: str) -> tuple[Transport, Credentials]:
    """Credentials for this run; the router requires them, every child gets its own file."""
    ids = scenario.ids
    ros2 = grant(scenario.ros2, ids) if scenario.ros2.enabled else None  # only a fleet that asked for it
    try:
        cred = make_credentials(directory, opts.fleet, {v: listeners_of(scenario, v) for v in ids}, router.listen,
                                mode, ros2=ros2, robots=robot_grants(scenario))
    except CredentialsError as e:
        raise ConfigError("command line", [("--tls" if mode == "tls" else "--secure", str(e))]) from None
    opts.zenoh_configs = {"world": str(cred.file(WORLD_ROLE)), **{v: str(cred.file(vehicle_role(v))) for v in ids}}
    if ros2 is not None:
        opts.zenoh_configs[ROS2_ROLE] = str(cred.file(ROS2_ROLE))
    return replace(router, listen=cred.listen, extra=router.extra + cred.router_extra()), cred


def run_lockstep(scenario: Scenario, run: Path, *, fleet: str, policy: str | None = None, rerun: str = "off",
                 secure: bool = True, tls: bool = False, ready_timeout: float = 30.0, quiet: bool = True,
                 log: Callable[[str], None] | None = None) -> tuple[int, Path, Path]:
    """Run ``scenario`` (its duration, its supervision policy) as a lockstep fleet in ``run``
    (logs/, secure/, metrics.json, trace.npz). Returns (the launcher's exit status: 0 completed,
    1 failed, 130 interrupted; the metrics path; the trace path), either file possibly absent.
    Arguments are the caller's to check (cdus.api.run); a run directory another fleet runs into now is a
    ConfigError naming run_dir."""
    try:
        lock = RunDirLock(run)
    except (RunDirInUse, RunDirError) as e:  # another fleet runs into it now, or it cannot be held: nothing is started
        raise ConfigError("run", [("run_dir", str(e))]) from None
    with lock:
        return _run_held(scenario, run, fleet, policy, rerun, secure, tls, ready_timeout, quiet, log)


def _run_held(scenario: Scenario, run: Path, fleet: str, policy: str | None, rerun: str, secure: bool, tls: bool,
              ready_timeout: float, quiet: bool, log: Callable[[str], None] | None) -> tuple[int, Path, Path]:
    for stale in ("metrics.json", "trace.npz"):  # an earlier run's in the same directory is not this run's
        (run / stale).unlink(missing_ok=True)
    opts = LaunchOptions(fleet=fleet, clock="lockstep", restart=scenario.supervision.restart,
                         metrics_out=run / "metrics.json", trace_out=run / "trace.npz", policy=policy,
                         ready_timeout=ready_timeout, quiet=quiet, rerun=rerun, links="router")
    router = fleet_router()  # a fresh port on 127.0.0.1
    if secure:
        router, _ = secure_router(router, opts, scenario, run / "secure", "tls" if tls else "password")
    status, la = launch(scenario, run, router, opts, log=log)
    return status, la.metrics_at or la.metrics_out, run / "trace.npz"

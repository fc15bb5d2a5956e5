"""How does a user run a scenario from Python? The Python API: load a scenario, run it, read its
metrics and trace, run a sweep.

This module: its checks of every argument and its
runs; the typed results they return are in :mod:`cdus.results`.

    import cdus
    sc = cdus.load("configs/lake_circle.toml", {"scenario.duration": 60, "link.loss": 0.2})
    res = cdus.run(sc)                       # in process (`cdus sim`); clock="lockstep": `cdus launch`
    res.metrics.coord_settle_s               # a typed Metrics (docs/metrics.md), .to_dict() is the JSON
    res.trace.to_dataframe()                 # the time series (numpy arrays; pandas, xarray helpers)
    table = cdus.sweep("configs/lake_circle.toml", {"link.loss": [0, 0.2]}, seeds=3, out="runs/sw")
    table.rows[0].coord_settle_s, table.cells, table.to_dataframe(), table.to_xarray()

docs/api.md is the reference. Every argument is checked here, where it enters: a bad path,
override, or option raises :class:`ConfigError` naming the field and what would be valid,
before anything runs. The command line (cdus.app.cli) is a thin layer over these functions.

``import cdus`` imports nothing heavy: this module is loaded on first use of a name, and
Zenoh (lockstep runs) and Rerun (``rerun=`` other than ``off``) only when a run asks for them.
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from cdus.app import sweep as app_sweep
from cdus.app.report import Progress
from cdus.app.sweep import RUNNERS  # how run() runs a scenario: `cdus sim`, `cdus launch --clock lockstep`
from cdus.app.sweeptable import CellStats, SweepTable, cell_statistics
from cdus.app.sweepstore import SweepRow
from cdus.core.linkspec import POLICIES
from cdus.core.metrics import TRACE_ARRAYS, Recorder  # noqa: F401  (TRACE_ARRAYS: a name users read from here)
from cdus.core.vehicle import DivergedError
from cdus.scenario.config import MAX_NESTING, ConfigError, load_scenario, nesting_problem, parse_scenario
from cdus.scenario.model import Scenario
from cdus.scenario.robot import clock_problem
from cdus.results import (ClosestPair, DroppedBy, Event, FaultCounters, Integrity, LinkFaults, LinkMetrics,
                          LinkStateChange, Metrics, RadioMetrics, RejectedByReason, Result, SafetyInfo, Trace,
                          Utilisation, WorldLost)
from cdus.sim.fleet import InProcessFleet
from cdus.sim.reports import ConsoleQuota
from cdus.wire.bounds import finite
from cdus.sim.sink import NullSink
from cdus.wire import keys
from world_sim.recording import parse_spec
from world_sim.sinks import make_sink

__all__ = [  # the names of ``import cdus`` (cdus/__init__.py, docs/api.md; tests/api/test_public.py: one list)
    "RUNNERS", "ClosestPair", "ConfigError", "DivergedError", "DroppedBy", "Event", "FaultCounters", "Integrity",
    "LinkFaults", "LinkMetrics", "LinkStateChange", "Metrics", "RadioMetrics", "RejectedByReason", "Result",
    "RunError", "RunInterrupted", "SafetyInfo", "Scenario", "SweepRow", "SweepTable", "CellStats", "Trace",
    "Utilisation", "WorldLost", "cell_statistics", "load", "override", "run", "sweep",
]



# --------------------------------------------------------------------------- errors


class RunError(RuntimeError):
    """A lockstep fleet that could not run: it did not come up, or wrote no metrics. The
    message names who failed and ends with the launcher's log (``log`` holds its lines)."""

    def __init__(self, message: str, log: Sequence[str] = ()):
        self.log = tuple(log)
        self.message = message
        super().__init__(message + ("\nthe launcher's log:\n" + "\n".join(self.log[-40:]) if self.log else ""))

    def __reduce__(self):  # picklable (a worker process's error) with its log
        return (type(self), (self.message, self.log))


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by Ctrl-C (SIGINT; SIGTERM for a lockstep fleet), every process it started
    already stopped. A KeyboardInterrupt, so it stops a script or a notebook cell as Ctrl-C
    does; ``result`` is what ran (metrics with ``completed`` false), None if nothing was written."""

    def __init__(self, result: "Result | None"):
        self.result = result
        super().__init__("interrupted" + ("" if result is None else
                                          f" at t = {result.metrics.duration_s:g} s of {result.scenario.name}"))

    def __reduce__(self):
        return (type(self), (self.result,))


# --------------------------------------------------------------------------- loading


def _arg_error(where: str, fld: str, message: str) -> ConfigError:
    return ConfigError(where, [(fld, message)])


def _plain(value: Any, where: str, key: str) -> Any:
    """An override value as TOML holds it (numpy scalars and arrays turned into Python's)."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, (list, tuple)):
        return [_plain(v, where, key) for v in value]
    if isinstance(value, Mapping):
        return {str(k) if isinstance(k, str) else _bad_key(where, key, k): _plain(v, where, key)
                for k, v in value.items()}
    raise _arg_error(where, f"override {key}", f"a {type(value).__name__} is not a config value; give a number, "
                                               f"a bool, a string, a list or a table of them")


def _bad_key(where: str, key: str, k: Any) -> str:
    raise _arg_error(where, f"override {key}", f"table keys are strings, got {k!r}")


def _overrides(overrides: Any, where: str) -> dict[str, Any]:
    if overrides is None:
        return {}
    if not isinstance(overrides, Mapping):
        raise _arg_error(where, "overrides", f"expected a mapping of dotted keys to values, e.g. {{'link.loss': "
                                             f"0.2, 'scenario.seed': 3}}, got {type(overrides).__name__}")
    out = {}
    for key, value in overrides.items():
        if not isinstance(key, str):
            raise _arg_error(where, "overrides", f"keys are dotted config keys (strings) such as 'rates.control', "
                                                 f"got {key!r}")
        if nesting_problem(value, MAX_NESTING - 1):  # iteratively, before _plain recurses into it
            raise _arg_error(where, f"override {key}", f"lists and tables nested deeper than {MAX_NESTING} levels "
                                                       f"are not a config value")
        out[key] = _plain(value, where, key)
    return out


def load(path: str | os.PathLike, overrides: Mapping[str, Any] | None = None) -> Scenario:
    """Read, override and validate a scenario file (TOML; or the JSON of a resolved one).

    ``overrides``: dotted keys as ``cdus sim --set`` takes them, e.g. ``{"link.loss": 0.2,
    "vehicle.usv1.gains.k": 2}``. Raises :class:`ConfigError` listing every problem."""
    if not isinstance(path, (str, os.PathLike)):
        raise _arg_error("cdus.load", "path", f"expected the path of a scenario .toml file (str or Path), got "
                                              f"{type(path).__name__}")
    return load_scenario(path, _overrides(overrides, os.fspath(path)))


def override(scenario: Scenario, overrides: Mapping[str, Any]) -> Scenario:
    """A new scenario: ``scenario`` with more keys overridden (as :func:`load`'s ``overrides``),
    validated again as a whole; the random starts are drawn again from the (new) seed."""
    _check_scenario(scenario, "cdus.override")
    return parse_scenario(scenario.raw, scenario.source, _overrides(overrides, scenario.source))


def _check_scenario(scenario: Any, where: str) -> Scenario:
    if isinstance(scenario, (str, os.PathLike)):
        return load(scenario)
    if not isinstance(scenario, Scenario):
        raise _arg_error(where, "scenario", f"expected a Scenario (cdus.load) or the path of a scenario file, got "
                                            f"{type(scenario).__name__}")
    return scenario


# --------------------------------------------------------------------------- running


def run(scenario: Scenario | str | os.PathLike, *, clock: str = "inproc", policy: str | None = None,
        rerun: str = "off", run_dir: str | os.PathLike | None = None,
        progress: bool | Callable[[float, float], None] = False, secure: bool = True, tls: bool = False,
        fleet: str | None = None, ready_timeout: float = 30.0, events: bool = False) -> Result:
    """Run a scenario to its end and return its :class:`Result`.

    ``clock``: ``inproc`` (``cdus sim``: every vehicle in this process, deterministic) or
    ``lockstep`` (``cdus launch --clock lockstep``: one OS process per vehicle over a Zenoh
    router on loopback, no multicast; the same numbers as inproc; must be called from the
    main thread). ``policy``: the stale-neighbour policy (default: the scenario's).
    ``rerun``: where the Rerun stream goes, as ``--rerun`` (default ``off``). ``run_dir``:
    where a lockstep run keeps its logs, credentials, metrics.json and trace.npz (default: a
    temporary directory, removed after), and where ``rerun="auto"`` saves without a display.
    ``progress``: True for progress lines on stderr (and the launcher's lines, the fleet's
    events among them; inproc: the events too, as ``events``), or a callable ``(t, duration)``.
    ``events`` (inproc): True to print the fleet's events on stdout as they happen, as ``cdus
    launch`` prints them (``cdus sim`` does; cdus.sim.reports.ConsoleQuota). Lockstep only: ``secure`` (default True: credentials and the router's
    access control, docs/security.md), ``tls``, ``fleet`` (the key prefix's name, default the
    scenario's), ``ready_timeout`` (s each process may take to come up).

    Ctrl-C raises :class:`RunInterrupted` (a KeyboardInterrupt) carrying what ran, once every
    process the run started is stopped. A diverged fleet raises ``DivergedError`` (inproc);
    a lockstep fleet that did not come up raises :class:`RunError`."""
    where = "cdus.run"
    scenario = _check_scenario(scenario, where)
    if clock not in RUNNERS:
        raise _arg_error(where, "clock", f"{clock!r} is not one of {', '.join(RUNNERS)}")
    if (why := clock_problem(scenario, clock)) is not None:  # plant = "ros2": cdus launch --clock realtime only
        raise _arg_error(where, "clock", why)
    if policy is not None and policy not in POLICIES:
        raise _arg_error(where, "policy", f"{policy!r} is not one of {', '.join(POLICIES)} (or None: the scenario's)")
    base = Path(run_dir) if run_dir is not None else None
    try:
        parse_spec(rerun, base)
    except (ValueError, AttributeError) as e:
        raise _arg_error(where, "rerun", str(e) if isinstance(e, ValueError) else
                         f"expected a string such as 'off', 'spawn' or 'save:run.rrd', got {type(rerun).__name__}"
                         ) from None
    if not (isinstance(progress, bool) or callable(progress)):
        raise _arg_error(where, "progress", f"expected True, False or a callable (t, duration), got {progress!r}")
    if not isinstance(events, bool):
        raise _arg_error(where, "events", f"expected True or False, got {events!r}")
    if clock == "inproc":
        return _run_inproc(scenario, policy, rerun, base, progress, events or progress is True)
    if events:
        raise _arg_error(where, "events", "a lockstep run prints the launcher's lines, the events among them, with "
                                          "progress=True")
    if base is None and any(item.strip().lower() == "auto" for item in rerun.split(",")):
        raise _arg_error(where, "rerun", "'auto' may save the recording into the run directory, and a lockstep "
                                         "run's default one is temporary: give run_dir=..., or rerun='save:PATH'")
    if not isinstance(progress, bool):
        raise _arg_error(where, "progress", "a lockstep run shows the launcher's own progress: give True or False "
                                            "(a callable is for clock='inproc')")
    for name, value in (("secure", secure), ("tls", tls)):
        if not isinstance(value, bool):
            raise _arg_error(where, name, f"expected True or False, got {value!r}")
    if tls and not secure:
        raise _arg_error(where, "tls", "TLS is a mode of the secured fleet: give secure=True with tls=True")
    if not (finite(ready_timeout) and ready_timeout > 0):
        raise _arg_error(where, "ready_timeout", f"expected seconds > 0, got {ready_timeout!r}")
    name = scenario.name.replace(".", "_") if fleet is None else fleet
    try:
        keys.check_fleet(name if isinstance(name, str) else repr(name))
    except ValueError as e:
        raise _arg_error(where, "fleet", f"{e}" + ("; give fleet=NAME" if fleet is None else "")) from None
    if threading.current_thread() is not threading.main_thread():
        raise _arg_error(where, "clock", "a lockstep run starts processes and stops them on Ctrl-C, which Python "
                                         "allows only in the main thread: call it from the main thread, or use "
                                         "clock='inproc'")
    return _run_lockstep(scenario, name, policy, rerun, base, progress, secure, tls, float(ready_timeout))


class _PrintingSink:
    """A sink that prints each event's console lines on stdout as the launcher does (held
    ``ConsoleQuota.HOLD_S`` of simulated time, then in time order, a change of many links as one
    line: ``ConsoleQuota.hold``) and hands everything on to ``inner``."""

    def __init__(self, inner: Any, console: ConsoleQuota):
        self.inner, self.console = inner, console

    def start(self, scenario: Scenario) -> None:
        self.inner.start(scenario)

    def update(self, recorder: Recorder) -> None:
        if len(recorder):
            self._print(self.console.due(float(recorder.view("t")[-1])))
        self.inner.update(recorder)

    def event(self, event: Any) -> None:
        self.console.hold(event, event.t)
        self._print(self.console.due(event.t))
        self.inner.event(event)

    @staticmethod
    def _print(lines: list[str]) -> None:
        for line in lines:
            print(line, flush=True)

    def link_state(self, t: float, src: str, dst: str, state: str) -> None:
        self.inner.link_state(t, src, dst, state)

    def radio(self, t: float, watch: Any) -> None:
        """[radio]: each geometry sample to ``inner`` (the Rerun sink draws them)."""
        self.inner.radio(t, watch)

    def close(self) -> None:
        self._print(self.console.flush())  # the run is over: what is held, at once
        self.inner.close()


def _run_inproc(scenario: Scenario, policy: str | None, rerun: str, base: Path | None,
                progress: bool | Callable[[float, float], None], events: bool = False) -> Result:
    sink = None
    if parse_spec(rerun, base):
        sink = make_sink(rerun, base)
    if events:  # the fleet's events as they happen, in the launcher's words (cdus.sim.reports)
        sink = _PrintingSink(sink or NullSink(), ConsoleQuota(scenario=scenario))
    fleet = InProcessFleet(scenario, policy=policy, sink=sink, clock=time.perf_counter)
    shown = Progress(scenario.name) if progress is True else None
    interrupted = False
    try:
        metrics = fleet.run(progress=shown or (progress or None)).metrics
    except KeyboardInterrupt:
        interrupted = True
        metrics = replace(fleet.partial_metrics(), interrupted=True)
    finally:
        fleet.sink.close()
        if shown is not None:
            shown.done()
    result = Result(scenario, metrics, Trace.from_recorder(fleet.recorder))
    if interrupted:
        raise RunInterrupted(result)
    return result


def _run_lockstep(scenario: Scenario, fleet: str, policy: str | None, rerun: str, base: Path | None,
                  progress: bool | Callable[[float, float], None], secure: bool, tls: bool,
                  ready_timeout: float) -> Result:
    from cdus.app.fleet_run import run_lockstep  # Zenoh and the launcher: only for lockstep runs

    lines: list[str] = []

    def log(line: str) -> None:
        lines.append(line)
        if progress is True:
            print(line, flush=True)

    def go(where: Path) -> Result | None:
        status, metrics_path, trace_path = run_lockstep(
            scenario, where, fleet=fleet, policy=policy, rerun=rerun, secure=secure, tls=tls,
            ready_timeout=ready_timeout, quiet=progress is not True, log=log)
        if not metrics_path.exists():
            if status == 130:
                raise RunInterrupted(None)
            raise RunError(f"the lockstep fleet of {scenario.name} wrote no metrics (exit status {status})", lines)
        metrics = Metrics.read(metrics_path)
        if metrics.completion == "not_started":
            raise RunError(f"the lockstep fleet of {scenario.name} did not come up", lines)
        trace = Trace.from_npz(trace_path) if trace_path.exists() else None
        result = Result(scenario, metrics, trace, run_dir=base, log=tuple(lines))
        if status == 130:
            raise RunInterrupted(result)
        return result

    if base is not None:
        base.mkdir(parents=True, exist_ok=True)
        return go(base)
    with tempfile.TemporaryDirectory(prefix="cdus-run-") as tmp:
        return go(Path(tmp))


# --------------------------------------------------------------------------- sweeps


def sweep(config: str | os.PathLike | Scenario, grid: Mapping[str, Sequence[Any]], *, out: str | os.PathLike,
          seeds: int | Sequence[int] = 3, clock: str = "inproc", executor: str = "local", cluster: str | None = None,
          jobs: int | None = None, duration: float | None = None, overrides: Mapping[str, Any] | None = None,
          quiet: bool = True, plot_format: str = "png") -> SweepTable:
    """Run every combination of ``grid``'s values x ``seeds`` (``cdus sweep``'s engine,
    cdus.app.sweep.sweep) and return its :class:`SweepTable`, whatever is installed: ``rows``
    (typed, one per (cell, seed) in plan order), ``cells`` (the per-cell statistics),
    ``to_dataframe()`` and ``to_xarray()`` (grid x seed) (docs/api.md).

    ``config``: a scenario file or a loaded Scenario (the workers get it resolved).
    ``grid``: dotted key -> list of values, e.g. ``{"link.loss": [0, 0.2], "rates.control":
    [20, 50]}`` ({} runs the scenario alone). ``seeds``: how many (the scenario's seed and the
    next ones) or which. ``out``: where results.jsonl (streamed, one row per run), results.csv,
    results.parquet, summary.md and sweep.png go; a second call with the same ``out`` runs
    only the (cell, seed) pairs not done yet (resume). ``clock``: ``inproc`` or ``lockstep``;
    ``executor``: ``local`` (processes of this machine) or ``dask`` (a LocalCluster on
    127.0.0.1); ``cluster``: a running Dask scheduler's address; ``jobs``: runs in parallel;
    ``duration``: simulated seconds per run; ``overrides``: fixed config values of every run.
    ``plot_format``: ``png`` (sweep.png), ``pdf`` or ``svg`` (a vector sweep.pdf or sweep.svg).
    Every cell is validated before any run (ConfigError). Ctrl-C raises
    cdus.app.sweep.SweepInterrupted (a KeyboardInterrupt) with the rows done kept on disk."""
    where = "cdus.sweep"
    if out is None or not isinstance(out, (str, os.PathLike)):
        raise _arg_error(where, "out", f"expected a directory path for the results, got {type(out).__name__}")
    if clock not in RUNNERS:
        raise _arg_error(where, "clock", f"{clock!r} is not one of {', '.join(RUNNERS)}")
    if plot_format not in app_sweep.PLOT_FORMATS:
        raise _arg_error(where, "plot_format", f"{plot_format!r} is not one of {', '.join(app_sweep.PLOT_FORMATS)}")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise _arg_error(where, "jobs", f"expected a number of parallel runs >= 1 (or None), got {jobs!r}")
    if duration is not None and not (finite(duration) and duration > 0):
        raise _arg_error(where, "duration", f"expected simulated seconds > 0 (or None), got {duration!r}")
    if not isinstance(grid, Mapping):
        raise _arg_error(where, "grid", f"expected a mapping of dotted keys to lists of values, e.g. "
                                        f"{{'link.loss': [0, 0.2]}}, got {type(grid).__name__}")
    axes: list[tuple[str, list[Any]]] = []
    for key, values in _overrides(grid, where).items():
        if not isinstance(values, list) or not values:
            raise _arg_error(where, f"grid {key}", f"expected a non-empty list of values, e.g. [0, 0.2], got "
                                                   f"{values!r}")
        axes.append((key, values))
    if not isinstance(config, (Scenario, str, os.PathLike)):
        raise _arg_error(where, "config", f"expected a scenario file or a Scenario, got {type(config).__name__}")
    if isinstance(seeds, bool) or not (isinstance(seeds, int) and seeds >= 1 or isinstance(seeds, (list, tuple, range))
                                       and seeds and all(isinstance(s, int) and not isinstance(s, bool)
                                                         for s in seeds)):
        raise _arg_error(where, "seeds", f"expected how many seeds (>= 1) or a list of integer seeds, got {seeds!r}")
    fixed = _overrides(overrides, where) if overrides else None
    result = app_sweep.sweep(config if isinstance(config, Scenario) else os.fspath(config), axes,
                             seeds if isinstance(seeds, int) else list(seeds), Path(out), overrides=fixed,
                             clock=clock, executor=executor, cluster=cluster, jobs=jobs,
                             duration=None if duration is None else float(duration), quiet=quiet,
                             plot_format=plot_format)
    if result.done < result.planned:  # runs lost by the executor (a worker died): say so, the table is short
        warnings.warn(f"{result.planned - result.done} of {result.planned} runs are not in the table: the executor "
                      f"lost them ({result.lost} lost, a worker process died?); the same call again runs only those",
                      RuntimeWarning, stacklevel=2)
    return SweepTable.of(result)


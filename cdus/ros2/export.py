"""How is a run written as ROS 2 messages in an MCAP file? ``cdus export RUN_DIR --mcap FILE`` (docs/ros2.md).

The same topics and messages the bridge publishes live (:mod:`cdus.ros2.fleet`), from the
run's trace (``--trace-out``, default ``RUN_DIR/trace.npz``) and its resolved scenario
(``RUN_DIR/scenario.json``, which ``cdus launch`` writes): per vehicle its pose, odometry, ω and ω̇
and a /tf transform at ``[ros2] rate`` while it was live, /clock at every recorded control tick,
each vehicle's path once at the start, and the events the metrics list. Schemas are the
``.msg`` definitions (encoding ``ros2msg``), messages CDR, log and publish times the simulated
time in ns (a run starts at 0, 1 January 1970 to a viewer): the file opens in Foxglove and
replays with ``ros2 bag play``.

The trace has no speed: the odometry's linear twist is the speed between this row and the
next, ``|q[k+1] - q[k]| / Δt`` (the last row repeats the one before); the live bridge publishes
the vehicle's own. The yaw rate is the heading's change since the row before, as the bridge's. Needs the ``mcap`` package (``pip install 'cdus[ros2]'``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from cdus.core.metrics import read_trace
from cdus.ros2 import cdr, fleet as rf
from cdus.ros2.types import definition
from cdus.scenario.config import load_scenario
from cdus.scenario.model import Scenario
from cdus.sim.polyline import path_polyline

TRACE_NAME, SCENARIO_NAME, METRICS_NAME = "trace.npz", "scenario.json", "metrics.json"
MAX_STAMP_S = 2 ** 31  # builtin_interfaces/Time.sec is an int32


class ExportError(Exception):
    """The run cannot be exported as asked; the message says what to give."""


def _ns(t: float) -> int:
    return max(0, round(float(t) * 1e9))


def speeds(q: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Per row and vehicle, |q[k+1] - q[k]| / (t[k+1] - t[k]); the last row repeats the one before."""
    if len(t) < 2:
        return np.zeros(q.shape[:2])
    v = np.linalg.norm(np.diff(q, axis=0), axis=2) / np.diff(t)[:, None]
    return np.concatenate([v, v[-1:]], axis=0)


def export_mcap(run_dir: Path, out: Path, trace: Path | None = None, scenario: Scenario | None = None) -> dict:
    """Write ``out`` from the run in ``run_dir``; returns {topic: messages written}."""
    try:
        from mcap.writer import Writer  # an optional extra: only this command needs it
    except ImportError:
        raise ExportError("--mcap needs the mcap package: pip install 'cdus[ros2]' (or pip install mcap)") from None
    trace = trace or run_dir / TRACE_NAME
    if not trace.exists():
        if _completion(run_dir) == "world_lost":  # it was asked for: the world died before the run's end
            raise ExportError(f"no trace at {trace}: the world process was lost before the run's end "
                              f"({run_dir / METRICS_NAME}: world_lost), and a trace is written at the end only; "
                              f"run it again (or give --trace PATH)")
        raise ExportError(f"no trace at {trace}: run the fleet with --trace-out {run_dir / TRACE_NAME} "
                          f"(or give --trace PATH)")
    if scenario is None:
        if not (run_dir / SCENARIO_NAME).exists():
            raise ExportError(f"no {SCENARIO_NAME} in {run_dir} (cdus launch writes it): give --config FILE")
        scenario = load_scenario(run_dir / SCENARIO_NAME)
    try:  # a truncated, empty or foreign file, times not finite: said, naming the file
        data = read_trace(trace)
    except (OSError, ValueError) as e:
        raise ExportError(f"{e}; give the run's own --trace" if isinstance(e, ValueError) else
                          f"cannot read the trace {trace}: {e.strerror or e}") from None
    if len(data["t"]) and not (0 <= data["t"].min() and data["t"].max() < MAX_STAMP_S):
        raise ExportError(f"{trace}: not a cdus trace: a time outside [0, {MAX_STAMP_S}) s (a ROS 2 stamp's "
                          f"seconds are an int32); give the run's own --trace")
    ids = list(data["ids"])
    if ids != list(scenario.ids):
        raise ExportError(f"the trace's vehicles ({', '.join(ids)}) are not the scenario's "
                          f"({', '.join(scenario.ids)}): give the run's own --config")
    try:
        f = open(out, "wb")
    except OSError as e:  # a directory, a read-only disk
        raise ExportError(f"cannot write {out}: {e.strerror or e}; give another --mcap") from None
    try:
        with f:
            return _write(Writer(f), scenario, run_dir, ids, data)
    except OSError as e:  # a full disk: no half file left
        out.unlink(missing_ok=True)
        raise ExportError(f"cannot write {out}: {e.strerror or e}; give another --mcap") from None


def _write(w: Any, scenario: Scenario, run_dir: Path, ids: list[str], data: dict) -> dict:
    spec, frame = scenario.ros2, scenario.ros2.world_frame
    t, q, heading = data["t"], data["q"], data["heading"]
    omega, omega_rate, live = data["omega"], data["omega_rate"], data["live"]
    speed = speeds(q, t)
    period = 1.0 / scenario.rates.control
    every = rf.every(spec, scenario.rates.control)
    topics = {(tp.vehicle, tp.field): tp for tp in rf.topics(spec, ids)}
    counts: dict[str, int] = {tp.name: 0 for tp in topics.values()}
    w.start(profile="ros2", library="cdus")
    schemas = {name: w.register_schema(name=name, encoding="ros2msg", data=definition(name).encode())
               for name in sorted({tp.type_name for tp in topics.values()})}
    channels = {which: w.register_channel(topic=tp.name, message_encoding="cdr",
                                          schema_id=schemas[tp.type_name])
                for which, tp in topics.items()}

    def write(which: Any, value: dict, at: float) -> None:
        tp = topics[which]
        ns = _ns(at)
        w.add_message(channels[which], log_time=ns, publish_time=ns, data=cdr.encode(tp.type_name, value),
                      sequence=counts[tp.name])
        counts[tp.name] += 1

    for v in scenario.vehicles:
        write((v.id, "path"), rf.path(path_polyline(v, scenario.duration), frame), 0.0)
    events = _events(run_dir)
    for k in range(len(t)):
        tk = float(t[k])
        while events and events[0][0] <= tk:
            at, text = events.pop(0)
            write((None, "events"), {"data": text}, at)
        write((None, "clock"), rf.clock(tk), tk)
        if round(tk / period) % every:
            continue
        for j, vid in enumerate(ids):
            if not live[k, j]:
                continue
            qj = q[k, j] if scenario.vehicles[j].dim == 3 else q[k, j, :2]
            before = (float(t[k - 1]), float(heading[k - 1, j])) if k else None
            rate = rf.yaw_rate(float(heading[k, j]), tk, before)
            for which, value in rf.vehicle_messages(vid, tk, qj, float(heading[k, j]), float(speed[k, j]),
                                                    float(omega[k, j]), float(omega_rate[k, j]), frame, rate):
                write(which, value, tk)
    for at, text in events:  # after the last row
        write((None, "events"), {"data": text}, at)
    w.finish()
    return counts


def _completion(run_dir: Path) -> Any:
    """The run's metrics' ``completion`` (None when they cannot be read)."""
    try:
        return json.loads((run_dir / METRICS_NAME).read_text()).get("completion")
    except (OSError, ValueError, AttributeError, RecursionError):
        return None


def _events(run_dir: Path) -> list[tuple[float, str]]:
    """The events the run's metrics list, by time, each as the JSON the bridge publishes."""
    try:
        listed = json.loads((run_dir / METRICS_NAME).read_text()).get("events") or []
    except (OSError, ValueError, AttributeError, RecursionError):
        return []
    out = [(float(e["t"]), json.dumps(e, ensure_ascii=False)) for e in listed  # a time a stamp can carry
           if isinstance(e, dict) and isinstance(e.get("t"), (int, float)) and 0 <= e["t"] < MAX_STAMP_S]
    return sorted(out, key=lambda x: x[0])

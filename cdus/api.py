"""The Python API: load a scenario, run it, read its metrics and trace, run a sweep.

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

import json
import os
import tempfile
import threading
import time
import warnings
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from cdus.app import sweep as app_sweep
from cdus.app.report import Progress
from cdus.app.sweep import RUNNERS  # how run() runs a scenario: `cdus sim`, `cdus launch --clock lockstep`
from cdus.app.sweeptable import CellStats, SweepTable, cell_statistics
from cdus.app.sweepstore import SweepRow
from cdus.core.linkspec import POLICIES
from cdus.core.metrics import TRACE_ARRAYS, Recorder, read_trace, trace_shape_problem
from cdus.core.vehicle import DivergedError
from cdus.extras import needs
from cdus.scenario.config import MAX_NESTING, ConfigError, load_scenario, nesting_problem, parse_scenario
from cdus.scenario.model import Scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.reports import ConsoleQuota
from cdus.wire.bounds import finite
from cdus.sim.sink import NullSink
from cdus.wire import keys
from world_sim.recording import parse_spec

__all__ = [  # the names of ``import cdus`` (cdus/__init__.py, docs/api.md; tests/api/test_public.py: one list)
    "RUNNERS", "ClosestPair", "ConfigError", "DivergedError", "DroppedBy", "Event", "FaultCounters", "Integrity",
    "LinkFaults", "LinkMetrics", "LinkStateChange", "Metrics", "RadioMetrics", "RejectedByReason", "Result",
    "RunError", "RunInterrupted", "SafetyInfo", "Scenario", "SweepRow", "SweepTable", "CellStats", "Trace",
    "cell_statistics", "load", "override", "run", "sweep",
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


# --------------------------------------------------------------------------- reading a metrics JSON


def _bad(where: str, expected: str, value: Any) -> ValueError:
    shown = repr(value)
    return ValueError(f"metrics: {where}: expected {expected}, got {shown[:60] + ('...' if len(shown) > 60 else '')}")


def _num(d: Mapping, key: str, where: str, null: bool = False) -> Any:
    v = d[key] if key in d else _missing(where, key)
    if v is None and null:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise _bad(f"{where}{key}", "a number" + (" or null" if null else ""), v)
    return v


def _int(d: Mapping, key: str, where: str) -> int:
    v = d[key] if key in d else _missing(where, key)
    if isinstance(v, bool) or not isinstance(v, int):
        raise _bad(f"{where}{key}", "an integer", v)
    return v


def _str(d: Mapping, key: str, where: str, null: bool = False) -> Any:
    v = d[key] if key in d else (None if null else _missing(where, key))
    if v is None and null:
        return None
    if not isinstance(v, str):
        raise _bad(f"{where}{key}", "a string", v)
    return v


def _bool(d: Mapping, key: str, where: str) -> bool:
    v = d[key] if key in d else _missing(where, key)
    if not isinstance(v, bool):
        raise _bad(f"{where}{key}", "true or false", v)
    return v


def _table(v: Any, where: str) -> Mapping:
    if not isinstance(v, dict):
        raise _bad(where, "an object", v)
    return v


def _numbers_by_id(d: Mapping, key: str, where: str) -> dict[str, float | None]:
    table = _table(d[key] if key in d else _missing(where, key), f"{where}{key}")
    return {k: _num(table, k, f"{where}{key}.", null=True) for k in table}


def _counts(v: Any, where: str) -> dict[str, int]:
    table = _table(v, where)
    return {k: _int(table, k, f"{where}.") for k in table}


def _missing(where: str, key: str) -> Any:
    raise ValueError(f"metrics: {where}{key}: missing (docs/metrics.md lists the fields)")


def _opt(value: Any, out: dict, key: str) -> None:
    if value is not None:
        out[key] = value


@dataclass(frozen=True)
class DroppedBy:
    """Drops by cause (``link.faults`` counters' ``dropped_by``)."""

    loss: int
    burst: int
    down: int
    partition: int

    @classmethod
    def from_dict(cls, d: Any, where: str = "dropped_by.") -> "DroppedBy":
        d = _table(d, where.rstrip("."))
        return cls(*(_int(d, f.name, where) for f in fields(cls)))

    def to_dict(self) -> dict[str, int]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True)
class FaultCounters:
    """The fault emulator's counters on one directed link or in total (docs/metrics.md,
    ``link.faults``): decisions, drops (and by cause), extra copies, copies given a delay."""

    sent: int
    dropped: int
    dropped_by: DroppedBy
    duplicated: int
    delayed: int

    @classmethod
    def from_dict(cls, d: Any, where: str) -> "FaultCounters":
        d = _table(d, where.rstrip("."))
        return cls(_int(d, "sent", where), _int(d, "dropped", where),
                   DroppedBy.from_dict(d.get("dropped_by"), f"{where}dropped_by."),
                   _int(d, "duplicated", where), _int(d, "delayed", where))

    def to_dict(self) -> dict[str, Any]:
        return {"sent": self.sent, "dropped": self.dropped, "dropped_by": self.dropped_by.to_dict(),
                "duplicated": self.duplicated, "delayed": self.delayed}


@dataclass(frozen=True)
class LinkStateChange:
    """A directed link's change of state at simulated time ``t``: ``up``, ``lossy`` or ``down``."""

    t: float
    link: str  # "src->dst"
    state: str


@dataclass(frozen=True)
class LinkFaults:
    """``link.faults``: present when the scenario has link faults (or a ground station set some)."""

    total: FaultCounters
    links: dict[str, FaultCounters]  # "src->dst" -> its counters
    state_changes: tuple[LinkStateChange, ...]

    @classmethod
    def from_dict(cls, d: Any, where: str = "link.faults.") -> "LinkFaults":
        d = _table(d, where.rstrip("."))
        links = _table(d["links"] if "links" in d else _missing(where, "links"), f"{where}links")
        changes = d["state_changes"] if "state_changes" in d else _missing(where, "state_changes")
        if not isinstance(changes, list):
            raise _bad(f"{where}state_changes", "a list", changes)
        out = []
        for n, ch in enumerate(changes):
            w = f"{where}state_changes[{n}]."
            ch = _table(ch, w.rstrip("."))
            out.append(LinkStateChange(_num(ch, "t", w), _str(ch, "link", w), _str(ch, "state", w)))
        return cls(FaultCounters.from_dict(d.get("total"), f"{where}total."),
                   {k: FaultCounters.from_dict(v, f"{where}links.{k}.") for k, v in links.items()}, tuple(out))

    def to_dict(self) -> dict[str, Any]:
        return {"total": self.total.to_dict(), "links": {k: v.to_dict() for k, v in self.links.items()},
                "state_changes": [{"t": c.t, "link": c.link, "state": c.state} for c in self.state_changes]}


LINK_COUNTS = ("sent", "delivered", "dropped", "duplicated", "rejected")


@dataclass(frozen=True)
class RadioMetrics:
    """The metrics' ``radio`` block (with ``[radio]`` only; docs/metrics.md): messages decided on
    the radio path, drops by cause (``fault``: the hand-set [link] fault, which decides first;
    ``range``, ``fading``, ``collision``, ``queue``: the channel), the channel utilisation over
    the geometry samples (``mean``, ``max``, ``samples``) and the communication-graph splits."""

    sent: int
    delivered: int
    dropped: int
    dropped_by: dict[str, int]
    no_geometry: int
    utilisation: dict[str, Any]
    splits: int

    @classmethod
    def from_dict(cls, d: Any, where: str = "radio.") -> "RadioMetrics":
        d = _table(d, where.rstrip("."))
        u = _table(d["utilisation"] if "utilisation" in d else _missing(where, "utilisation"), f"{where}utilisation")
        w = f"{where}utilisation."
        return cls(_int(d, "sent", where), _int(d, "delivered", where), _int(d, "dropped", where),
                   _counts(d.get("dropped_by"), f"{where}dropped_by"), _int(d, "no_geometry", where),
                   {"mean": _num(u, "mean", w, null=True), "max": _num(u, "max", w, null=True),
                    "samples": _int(u, "samples", w)}, _int(d, "splits", where))

    def to_dict(self) -> dict[str, Any]:
        return {"sent": self.sent, "delivered": self.delivered, "dropped": self.dropped,
                "dropped_by": dict(self.dropped_by), "no_geometry": self.no_geometry,
                "utilisation": dict(self.utilisation), "splits": self.splits}


@dataclass(frozen=True)
class LinkMetrics:
    """The metrics' ``link`` block: what the links did, counted at the receivers (docs/metrics.md)."""

    sent: int
    delivered: int
    dropped: int
    duplicated: int
    rejected: int
    latency_ms_p50: float | None
    latency_ms_p99: float | None
    missed_deadlines: int | None = None  # a fleet of processes only (0 in lockstep)
    faults: LinkFaults | None = None  # only with link faults
    extra: dict[str, Any] = field(default_factory=dict)  # any other key, kept as it came

    @classmethod
    def from_dict(cls, d: Any, where: str = "link.") -> "LinkMetrics":
        d = _table(d, where.rstrip("."))
        known = (*LINK_COUNTS, "latency_ms_p50", "latency_ms_p99", "missed_deadlines", "faults")
        return cls(*(_int(d, k, where) for k in LINK_COUNTS), _num(d, "latency_ms_p50", where, null=True),
                   _num(d, "latency_ms_p99", where, null=True),
                   _int(d, "missed_deadlines", where) if "missed_deadlines" in d else None,
                   LinkFaults.from_dict(d["faults"], f"{where}faults.") if "faults" in d else None,
                   {k: v for k, v in d.items() if k not in known})

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {k: getattr(self, k) for k in (*LINK_COUNTS, "latency_ms_p50", "latency_ms_p99")}
        _opt(self.missed_deadlines, out, "missed_deadlines")
        out.update(self.extra)
        if self.faults is not None:
            out["faults"] = self.faults.to_dict()
        return out


@dataclass(frozen=True)
class Event:
    """A fleet event (``cdus.wire.schemas.FleetEvent``): programs act on ``kind`` and ``severity``."""

    t: float
    kind: str
    text: str
    severity: str
    vehicle: str | None = None
    link: str | None = None
    origin: str | None = None

    @classmethod
    def from_dict(cls, d: Any, where: str) -> "Event":
        d = _table(d, where.rstrip("."))
        # vehicle, link, origin: absent when they do not apply (as FleetEvent.as_dict writes them), never null
        return cls(_num(d, "t", where), _str(d, "kind", where), _str(d, "text", where), _str(d, "severity", where),
                   *(_str(d, k, where) if k in d else None for k in ("vehicle", "link", "origin")))

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self) if getattr(self, f.name) is not None}


@dataclass(frozen=True)
class SafetyInfo:
    """The metrics' ``safety``: whether the safety filter was on, and its radius R (m)."""

    enabled: bool
    radius_m: float | None


@dataclass(frozen=True)
class ClosestPair:
    """One entry of the metrics' ``closest_pairs`` (and ``closest_pair``): vehicles ``a`` and
    ``b`` (scenario order) of ``domain`` (``usv``, ``uav`` or ``uav-usv``) came
    ``distance_m`` apart at ``t_s`` simulated s; whether each was live (stepping) then."""

    domain: str
    a: str
    b: str
    distance_m: float
    t_s: float
    a_live: bool
    b_live: bool
    both_live: bool

    @classmethod
    def from_dict(cls, d: Any, where: str) -> "ClosestPair":
        d = _table(d, where.rstrip("."))
        return cls(_str(d, "domain", where), _str(d, "a", where), _str(d, "b", where), _num(d, "distance_m", where),
                   _num(d, "t_s", where), _bool(d, "a_live", where), _bool(d, "b_live", where),
                   _bool(d, "both_live", where))

    def to_dict(self) -> dict[str, Any]:
        return {"domain": self.domain, "a": self.a, "b": self.b, "distance_m": self.distance_m, "t_s": self.t_s,
                "a_live": self.a_live, "b_live": self.b_live, "both_live": self.both_live}


@dataclass(frozen=True)
class RejectedByReason:
    """``rejected_by_reason`` (a fleet of processes): what the world and the vehicles dropped, by reason."""

    world: dict[str, int]
    vehicles: dict[str, int]


@dataclass(frozen=True)
class Integrity:
    """``integrity``: whether something was seen that may have altered the run (a liveliness
    token that is no process's, a second one of a process), the counts by reason and a
    sentence for the first of each (docs/metrics.md, docs/security.md)."""

    tampered: bool
    reasons: dict[str, int]
    notes: tuple[str, ...]

    @classmethod
    def from_dict(cls, d: Any) -> "Integrity":
        t = _table(d, "integrity")
        notes = t["notes"] if "notes" in t else _missing("integrity.", "notes")
        if not isinstance(notes, list) or not all(isinstance(x, str) for x in notes):
            raise _bad("integrity.notes", "a list of strings", notes)
        return cls(_bool(t, "tampered", "integrity."), _counts(t.get("reasons"), "integrity.reasons"), tuple(notes))

    def to_dict(self) -> dict[str, Any]:
        return {"tampered": self.tampered, "reasons": dict(self.reasons), "notes": list(self.notes)}


@dataclass(frozen=True)
class Metrics:
    """One run's metrics JSON, typed: the fields and their meaning are docs/metrics.md's.

    ``from_dict`` checks every field's type (ValueError naming it); ``to_dict()`` gives the
    JSON back, equal to what was read, in the same key order. Keys the JSON may lack are None
    here when absent (``rejected_by_reason``, ``interrupted``); keys this class does not know
    are kept in ``extra``. ``link`` is None only in the metrics the launcher writes when the
    world process died (its JSON ``link`` is ``{}``)."""

    scenario: str
    mode: str
    seed: int
    duration_s: float
    path_tol: float
    coord_tol: float
    path_settle_s: float | None
    coord_settle_s: float | None
    final_path_error_max: float | None
    final_coord_error_max: float | None
    omega_rate_final: dict[str, float | None]
    final_path_error: dict[str, float | None]
    live_final: tuple[str, ...]
    link: LinkMetrics | None
    wall_s: float
    realtime_factor: float | None
    policy: str
    events: tuple[Event, ...]
    completed: bool
    completion: str
    min_separation_m: float | None
    # None only in the metrics the launcher writes when the world process died
    closest_pairs: dict[str, ClosestPair] | None
    closest_pair: ClosestPair | None
    near_collision: bool | None
    interventions: int
    safety: SafetyInfo
    integrity: Integrity | None = None  # None only in metrics written before it was (and the launcher's world_lost)
    rejected_by_reason: RejectedByReason | None = None
    radio: RadioMetrics | None = None  # with [radio] only
    interrupted: bool | None = None
    never_up: tuple[str, ...] | None = None  # only in a run that never began (completion not_started)
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: Any) -> "Metrics":
        """A metrics JSON (as ``json.load`` gives it); ValueError naming the first bad field."""
        d = _table(d, "metrics")
        w = ""
        live = d["live_final"] if "live_final" in d else _missing(w, "live_final")
        if not isinstance(live, list) or not all(isinstance(v, str) for v in live):
            raise _bad("live_final", "a list of vehicle ids", live)
        events = d["events"] if "events" in d else _missing(w, "events")
        if not isinstance(events, list):
            raise _bad("events", "a list", events)
        link = _table(d["link"] if "link" in d else _missing(w, "link"), "link")
        safety = _table(d["safety"] if "safety" in d else _missing(w, "safety"), "safety")
        rej = None
        if "rejected_by_reason" in d:
            r = _table(d["rejected_by_reason"], "rejected_by_reason")
            rej = RejectedByReason(_counts(r.get("world"), "rejected_by_reason.world"),
                                   _counts(r.get("vehicles"), "rejected_by_reason.vehicles"))
        pairs = None
        trio = ("closest_pairs", "closest_pair", "near_collision")  # written together, or none (a dead world)
        if any(k in d for k in trio):
            for k in trio:
                if k not in d:
                    _missing(w, k)
            pairs = {str(k): ClosestPair.from_dict(v, f"closest_pairs.{k}.")
                     for k, v in _table(d["closest_pairs"], "closest_pairs").items()}
        closest = d.get("closest_pair")
        never_up = d.get("never_up")
        if never_up is not None and (not isinstance(never_up, list) or not all(isinstance(v, str) for v in never_up)):
            raise _bad("never_up", "a list of vehicle ids", never_up)
        known = {f.name for f in fields(cls)} - {"extra"}
        return cls(
            scenario=_str(d, "scenario", w), mode=_str(d, "mode", w), seed=_int(d, "seed", w),
            duration_s=_num(d, "duration_s", w), path_tol=_num(d, "path_tol", w), coord_tol=_num(d, "coord_tol", w),
            path_settle_s=_num(d, "path_settle_s", w, null=True),
            coord_settle_s=_num(d, "coord_settle_s", w, null=True),
            final_path_error_max=_num(d, "final_path_error_max", w, null=True),
            final_coord_error_max=_num(d, "final_coord_error_max", w, null=True),
            omega_rate_final=_numbers_by_id(d, "omega_rate_final", w),
            final_path_error=_numbers_by_id(d, "final_path_error", w), live_final=tuple(live),
            link=LinkMetrics.from_dict(link) if link else None,
            wall_s=_num(d, "wall_s", w), realtime_factor=_num(d, "realtime_factor", w, null=True),
            policy=_str(d, "policy", w),
            events=tuple(Event.from_dict(e, f"events[{n}].") for n, e in enumerate(events)),
            completed=_bool(d, "completed", w), completion=_str(d, "completion", w),
            min_separation_m=_num(d, "min_separation_m", w, null=True), closest_pairs=pairs,
            closest_pair=None if closest is None else ClosestPair.from_dict(closest, "closest_pair."),
            near_collision=_bool(d, "near_collision", w) if "near_collision" in d else None,
            interventions=_int(d, "interventions", w),
            safety=SafetyInfo(_bool(safety, "enabled", "safety."), _num(safety, "radius_m", "safety.", null=True)),
            integrity=Integrity.from_dict(d["integrity"]) if "integrity" in d else None,
            rejected_by_reason=rej,
            radio=RadioMetrics.from_dict(d["radio"]) if "radio" in d else None,
            interrupted=_bool(d, "interrupted", w) if "interrupted" in d else None,
            never_up=None if never_up is None else tuple(never_up),
            extra={k: v for k, v in d.items() if k not in known},
        )

    @classmethod
    def from_json(cls, path: str | os.PathLike) -> "Metrics":
        """Read a metrics JSON file (``metrics.json`` of a run, ``--metrics-out``)."""
        with open(path, encoding="utf-8") as fh:
            return cls.from_dict(json.load(fh))

    def to_dict(self) -> dict[str, Any]:
        """The metrics JSON: equal to the dict this was read from (and in its key order)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "extra":
                out.update(v)
            elif f.name == "link":
                out["link"] = {} if v is None else v.to_dict()
            elif f.name == "live_final":
                out[f.name] = list(v)
            elif f.name in ("omega_rate_final", "final_path_error"):
                out[f.name] = dict(v)
            elif f.name == "events":
                out[f.name] = [e.to_dict() for e in v]
            elif f.name == "safety":
                out[f.name] = {"enabled": v.enabled, "radius_m": v.radius_m}
            elif f.name == "integrity":
                if v is not None:
                    out[f.name] = v.to_dict()
            elif f.name == "rejected_by_reason":
                if v is not None:
                    out[f.name] = {"world": dict(v.world), "vehicles": dict(v.vehicles)}
            elif f.name == "closest_pairs":
                if v is not None:
                    out[f.name] = {k: p.to_dict() for k, p in v.items()}
            elif f.name == "closest_pair":
                if "closest_pairs" in out:
                    out[f.name] = None if v is None else v.to_dict()
            elif f.name in ("interrupted", "near_collision"):
                _opt(v, out, f.name)
            elif f.name == "never_up":
                if v is not None:
                    out[f.name] = list(v)
            elif f.name == "radio":
                if v is not None:
                    out[f.name] = v.to_dict()
            else:
                out[f.name] = v
        return out


# --------------------------------------------------------------------------- the trace




@dataclass(frozen=True, eq=False)
class Trace:
    """A run's time series, one row per control tick (sampled after the controller's update;
    docs/metrics.md), as numpy arrays: T ticks, N vehicles (``ids``), E metric edges
    (``edge_names``, "<id_i>__<id_k>"). A vehicle not live at a tick (killed, paused) repeats
    its last row there; ``live`` says who stepped."""

    t: np.ndarray  # (T,) simulated s
    ids: tuple[str, ...]  # (N,) in scenario order
    q: np.ndarray  # (T, N, 3) position, m (a boat's z is 0)
    heading: np.ndarray  # (T, N) rad
    omega: np.ndarray  # (T, N) the path parameter ω, rad
    omega_rate: np.ndarray  # (T, N) ω̇, rad/s
    path_error: np.ndarray  # (T, N) |Φ_i|, m
    edge_names: tuple[str, ...]  # (E,)
    edge_error: np.ndarray  # (T, E) |ω_i - ω_k - Δ_ik|, rad
    live: np.ndarray  # (T, N) bool: stepping at that tick
    # (T, N) int: each vehicle's safety-filter interventions so far (None: a trace written before it was kept)
    interventions: np.ndarray | None = None

    def __post_init__(self) -> None:
        why = trace_shape_problem({k: getattr(self, k) for k in (*TRACE_ARRAYS, "interventions")},
                                  len(self.ids), len(self.edge_names))
        if why is not None:
            raise ValueError(f"trace: {why}")

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def from_recorder(cls, rec: Recorder) -> "Trace":
        """A copy of a Recorder's series (cdus.core.metrics)."""
        return cls(t=rec.view("t").copy(), ids=tuple(rec.ids), q=rec.view("q").copy(),
                   heading=rec.view("heading").copy(), omega=rec.view("omega").copy(),
                   omega_rate=rec.view("omega_rate").copy(), path_error=rec.view("path_error").copy(),
                   edge_names=tuple(e.name for e in rec.edges), edge_error=rec.edge_error(),
                   live=rec.view("live").copy(), interventions=rec.view("interventions").copy())

    @classmethod
    def from_npz(cls, path: str | os.PathLike) -> "Trace":
        """Read a ``--trace-out`` file (``.npz``)."""
        arrays = read_trace(os.fspath(path))
        return cls(**arrays)

    def save(self, path: str | os.PathLike) -> None:
        """Write as ``--trace-out`` does (a compressed ``.npz``; :meth:`from_npz` reads it)."""
        np.savez_compressed(path, t=self.t, ids=np.array(self.ids), q=self.q, heading=self.heading,
                            omega=self.omega, omega_rate=self.omega_rate, path_error=self.path_error,
                            edge_error=self.edge_error, edge_names=np.array(self.edge_names), live=self.live,
                            **({} if self.interventions is None else {"interventions": self.interventions}))

    def to_dataframe(self):
        """A pandas DataFrame, one row per (tick, vehicle): ``t, vehicle, x, y, z, heading,
        omega, omega_rate, path_error, live`` and ``interventions`` when the trace has them
        (needs pandas: the ``api`` extra)."""
        pd = needs("pandas", "Trace.to_dataframe")
        T, N = len(self.t), len(self.ids)
        return pd.DataFrame({
            "t": np.repeat(self.t, N), "vehicle": pd.Categorical(np.tile(np.array(self.ids, dtype=object), T),
                                                                 categories=list(self.ids)),
            "x": self.q[:, :, 0].ravel(), "y": self.q[:, :, 1].ravel(), "z": self.q[:, :, 2].ravel(),
            "heading": self.heading.ravel(), "omega": self.omega.ravel(), "omega_rate": self.omega_rate.ravel(),
            "path_error": self.path_error.ravel(), "live": self.live.ravel(),
            **({} if self.interventions is None else {"interventions": self.interventions.ravel()}),
        })

    def edges_dataframe(self):
        """A pandas DataFrame, one row per (tick, metric edge): ``t, edge, error`` (rad)."""
        pd = needs("pandas", "Trace.edges_dataframe")
        T, E = len(self.t), len(self.edge_names)
        return pd.DataFrame({"t": np.repeat(self.t, E),
                             "edge": pd.Categorical(np.tile(np.array(self.edge_names, dtype=object), T),
                                                    categories=list(self.edge_names)),
                             "error": self.edge_error.ravel()})

    def to_xarray(self):
        """An xarray Dataset over dims ``t``, ``vehicle``, ``axis`` (x, y, z) and ``edge``, with
        units in each variable's attrs (needs xarray: the ``api`` extra)."""
        xr = needs("xarray", "Trace.to_xarray")
        tv = ("t", "vehicle")
        data = {
            "q": (("t", "vehicle", "axis"), self.q, {"units": "m", "long_name": "position"}),
            "heading": (tv, self.heading, {"units": "rad"}),
            "omega": (tv, self.omega, {"units": "rad", "long_name": "path parameter ω"}),
            "omega_rate": (tv, self.omega_rate, {"units": "rad/s", "long_name": "ω̇"}),
            "path_error": (tv, self.path_error, {"units": "m", "long_name": "|Φ_i|"}),
            "live": (tv, self.live, {"long_name": "stepping at that tick"}),
            "edge_error": (("t", "edge"), self.edge_error, {"units": "rad", "long_name": "|ω_i - ω_k - Δ_ik|"}),
        }
        if self.interventions is not None:
            data["interventions"] = (tv, self.interventions, {"long_name": "safety-filter interventions so far"})
        return xr.Dataset(data, coords={"t": ("t", self.t, {"units": "s"}), "vehicle": list(self.ids),
                                        "axis": ["x", "y", "z"], "edge": list(self.edge_names)})


@dataclass(frozen=True, eq=False)
class Result:
    """What :func:`run` returns: the scenario that ran, its metrics and its trace."""

    scenario: Scenario
    metrics: Metrics
    trace: Trace | None  # None only when a lockstep fleet's world died before writing it
    run_dir: Path | None = None  # a lockstep run's directory (logs, metrics.json, trace.npz) if one was given
    log: tuple[str, ...] = ()  # a lockstep run's launcher lines


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
        """[radio]: each geometry sample to ``inner`` if it draws them (the Rerun sink does)."""
        view = getattr(self.inner, "radio", None)
        if view is not None:
            view(t, watch)

    def close(self) -> None:
        self._print(self.console.flush())  # the run is over: what is held, at once
        self.inner.close()


def _run_inproc(scenario: Scenario, policy: str | None, rerun: str, base: Path | None,
                progress: bool | Callable[[float, float], None], events: bool = False) -> Result:
    sink = None
    if parse_spec(rerun, base):
        from world_sim.rerun_sink import make_sink  # Rerun costs ~1 s and 55 MB to import: only when asked for

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
        metrics = fleet.partial_metrics()
        metrics["interrupted"] = True
    finally:
        fleet.sink.close()
        if shown is not None:
            shown.done()
    result = Result(scenario, Metrics.from_dict(metrics), Trace.from_recorder(fleet.recorder))
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
        metrics = Metrics.from_json(metrics_path)
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


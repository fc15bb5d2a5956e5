"""What did a run measure? The typed metrics record, built by the run and decoded from a file.

:class:`Metrics` (and its parts, one per concern: :class:`LinkMetrics` with its
:class:`LinkFaults`, :class:`RadioMetrics`, :class:`ClosestPair`, :class:`SafetyInfo`,
:class:`Integrity`, :class:`RejectedByReason`, :class:`WorldLost`, :class:`Event`) is a run's
metrics JSON (docs/metrics.md) in types. A run builds it (cdus.sim.summary.run_metrics: the
in-process fleet, the world process, the launcher for a lost world) and writes its
``to_dict()``; a file is read back with :meth:`Metrics.read` / :meth:`Metrics.from_json`, which
validate a JSON object once (a ``metrics.json`` on disk may be corrupt, or from an older
version) and return the record or ``Rejected(reason, field)`` naming the first bad field,
never raising. Everything that reads metrics (``cdus.run``, the summary table of
cdus.app.report, the sweep's rows) reads this type and checks no field again. It is the pure
layer's (cdus.sim) so that the builder below the app can make it; :mod:`cdus.results` and
:mod:`cdus.api` give it to users. A new block is a new part here, a field of :class:`Metrics`
(its place in the class is its place in the JSON) and its line in docs/metrics.md.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, fields, is_dataclass
from typing import Any

from cdus.sim.metricfields import (_Bad, _bad, _bool, _counts, _ids, _int, _missing, _num, _numbers_by_id, _opt,
                                   _str, _table)
from cdus.wire.bounds import finite
from cdus.wire.rejected import Rejected


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
class Utilisation:
    """``radio.utilisation``: the channel utilisation's mean and max over the geometry samples
    (null without a sample), and how many samples there were."""

    mean: float | None
    max: float | None
    samples: int

    @classmethod
    def from_dict(cls, d: Any, where: str = "radio.utilisation.") -> "Utilisation":
        d = _table(d, where.rstrip("."))
        return cls(_num(d, "mean", where, null=True), _num(d, "max", where, null=True), _int(d, "samples", where))

    def to_dict(self) -> dict[str, Any]:
        return {"mean": self.mean, "max": self.max, "samples": self.samples}


@dataclass(frozen=True)
class RadioMetrics:
    """The metrics' ``radio`` block (with ``[radio]`` only; docs/metrics.md): messages decided on
    the radio path, drops by cause (``fault``: the hand-set [link] fault, which decides first;
    ``range``, ``fading``, ``collision``, ``queue``: the channel), the channel utilisation over
    the geometry samples and the communication-graph splits."""

    sent: int
    delivered: int
    dropped: int
    dropped_by: dict[str, int]
    no_geometry: int
    utilisation: Utilisation
    splits: int

    @classmethod
    def from_dict(cls, d: Any, where: str = "radio.") -> "RadioMetrics":
        d = _table(d, where.rstrip("."))
        u = d["utilisation"] if "utilisation" in d else _missing(where, "utilisation")
        return cls(_int(d, "sent", where), _int(d, "delivered", where), _int(d, "dropped", where),
                   _counts(d.get("dropped_by"), f"{where}dropped_by"), _int(d, "no_geometry", where),
                   Utilisation.from_dict(u, f"{where}utilisation."), _int(d, "splits", where))

    def to_dict(self) -> dict[str, Any]:
        return {"sent": self.sent, "delivered": self.delivered, "dropped": self.dropped,
                "dropped_by": dict(self.dropped_by), "no_geometry": self.no_geometry,
                "utilisation": self.utilisation.to_dict(), "splits": self.splits}


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

    @classmethod
    def from_dict(cls, d: Any) -> "SafetyInfo":
        d = _table(d, "safety")
        return cls(_bool(d, "enabled", "safety."), _num(d, "radius_m", "safety.", null=True))

    def to_dict(self) -> dict[str, Any]:
        return {"enabled": self.enabled, "radius_m": self.radius_m}


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
class ObstacleMetrics:
    """The metrics' ``obstacles`` block (with [[obstacle]] only; docs/metrics.md): ``count``, the
    fleet's smallest clearance, the vehicles ``below_margin`` and per vehicle its
    ``min_clearance_m``, ``obstacle``, ``t``, ``margin_m``, ``deflected_s`` (cdus.core.obstacle_metrics)."""

    count: int
    min_clearance_m: float | None
    below_margin: tuple[str, ...]
    vehicles: dict[str, dict[str, Any]]

    @classmethod
    def from_dict(cls, d: Any, where: str = "obstacles.") -> "ObstacleMetrics":
        d = _table(d, where.rstrip("."))
        below = d.get("below_margin")
        if not isinstance(below, list) or not all(isinstance(v, str) for v in below):
            raise _bad(f"{where}below_margin", "a list of vehicle ids", below)
        rows = {}
        for vid, r in _table(d.get("vehicles"), f"{where}vehicles").items():
            w = f"{where}vehicles.{vid}."
            r = _table(r, w.rstrip("."))
            rows[str(vid)] = {"min_clearance_m": _num(r, "min_clearance_m", w, null=True),
                              "obstacle": _str(r, "obstacle", w, null=True), "t": _num(r, "t", w, null=True),
                              "margin_m": _num(r, "margin_m", w, null=True),
                              "deflected_s": _num(r, "deflected_s", w, null=True)}
        return cls(_int(d, "count", where), _num(d, "min_clearance_m", where, null=True), tuple(below), rows)

    def to_dict(self) -> dict[str, Any]:
        return {"count": self.count, "min_clearance_m": self.min_clearance_m, "below_margin": list(self.below_margin),
                "vehicles": {k: dict(v) for k, v in self.vehicles.items()}}


@dataclass(frozen=True)
class RejectedByReason:
    """``rejected_by_reason`` (a fleet of processes): what the world and the vehicles dropped, by reason."""

    world: dict[str, int]
    vehicles: dict[str, int]

    @classmethod
    def from_dict(cls, d: Any) -> "RejectedByReason":
        r = _table(d, "rejected_by_reason")
        return cls(_counts(r.get("world"), "rejected_by_reason.world"),
                   _counts(r.get("vehicles"), "rejected_by_reason.vehicles"))

    def to_dict(self) -> dict[str, Any]:
        return {"world": dict(self.world), "vehicles": dict(self.vehicles)}


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
class WorldLost:
    """``world_lost`` (only in the metrics the launcher writes when the world process died,
    ``completion`` ``world_lost``): how the world ended (``world_exit``: its exit status, or
    minus the signal), the time and the fields of its last status (null: it gave none), the
    vehicles whose liveliness token was up, the restarts per vehicle and what the launcher
    rejected, by reason."""

    world_exit: int
    last_status_t: float | None
    last_status: dict[str, Any] | None  # {alive, path_error_max, coord_error_max, paused}, as the world said them
    alive_tokens: tuple[str, ...]
    restarts: dict[str, int]
    rejected_by_launcher: dict[str, int]

    @classmethod
    def from_dict(cls, d: Any, where: str = "world_lost.") -> "WorldLost":
        d = _table(d, where.rstrip("."))
        last = d["last_status"] if "last_status" in d else _missing(where, "last_status")
        if last is not None:
            last = dict(_table(last, f"{where}last_status"))
        t = _num(d, "last_status_t", where, null=True)
        if t is not None and not finite(t):
            raise _bad(f"{where}last_status_t", "a finite number or null", t)
        return cls(_int(d, "world_exit", where), t, last,
                   _ids(d, "alive_tokens", where), _counts(d.get("restarts"), f"{where}restarts"),
                   _counts(d.get("rejected_by_launcher"), f"{where}rejected_by_launcher"))

    def to_dict(self) -> dict[str, Any]:
        return {"world_exit": self.world_exit, "last_status_t": self.last_status_t, "last_status": self.last_status,
                "alive_tokens": list(self.alive_tokens), "restarts": dict(self.restarts),
                "rejected_by_launcher": dict(self.rejected_by_launcher)}


@dataclass(frozen=True)
class Metrics:
    """One run's metrics JSON, typed: the fields and their meaning are docs/metrics.md's.

    The builder (:func:`cdus.sim.summary.run_metrics`, for the in-process fleet, the world and
    the launcher's ``world_lost`` record) makes this record; ``to_dict()`` is the JSON every run
    writes, its fields in this class's order. ``from_json`` reads one back, checking every
    field's type once (a Rejected naming the first bad one; ``from_dict``: the same as a
    ValueError), and ``Metrics.from_json(m.to_dict()) == m``. A key the JSON may lack is None
    here when absent (``rejected_by_reason``, ``radio``, ``interrupted``, ...); keys this class
    does not know are kept in ``extra``. ``link`` is None only in the launcher's ``world_lost``
    record (its JSON ``link`` is ``{}``)."""

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
    # None only in metrics written without them (a lost world's, before they were kept)
    closest_pairs: dict[str, ClosestPair] | None
    closest_pair: ClosestPair | None
    near_collision: bool | None
    interventions: int
    safety: SafetyInfo
    obstacles: ObstacleMetrics | None = None  # with [[obstacle]] only
    integrity: Integrity | None = None  # None only in metrics written before it was
    rejected_by_reason: RejectedByReason | None = None  # a fleet of processes only
    never_up: tuple[str, ...] | None = None  # only in a run that never began (completion not_started)
    radio: RadioMetrics | None = None  # with [radio] only
    interrupted: bool | None = None  # only after a Ctrl-C of cdus sim
    written_by: str | None = None  # "launcher": the world_lost record
    world_lost: WorldLost | None = None  # ... and what the launcher knew
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_json(cls, d: Any) -> "Metrics | Rejected":
        """A metrics JSON object (as ``json.load`` gives it) into the record, or
        ``Rejected(reason, field)`` naming the first field that is not what docs/metrics.md says
        (``seed``, ``link.faults.total.sent``, ``events[3].t``). Never raises."""
        if isinstance(d, (str, bytes, os.PathLike)):
            return Rejected(f"expected the JSON object, got a {type(d).__name__}: Metrics.read(path) reads a file",
                            "metrics")
        try:
            return cls._decode(d)
        except _Bad as e:
            return e.rejected

    @classmethod
    def from_dict(cls, d: Any) -> "Metrics":
        """As :meth:`from_json`, but a ValueError (``metrics: <field>: <why>``) for a bad field."""
        m = cls.from_json(d)
        if isinstance(m, Rejected):
            raise ValueError(f"metrics: {m}")
        return m

    @classmethod
    def read(cls, path: str | os.PathLike) -> "Metrics":
        """Read a metrics JSON file (``metrics.json`` of a run, ``--metrics-out``); ValueError
        naming the file and the bad field (OSError: the file cannot be read)."""
        with open(path, encoding="utf-8") as fh:
            try:
                d = json.load(fh)
            except ValueError as e:  # not JSON at all (a file cut short by a full disk, not UTF-8)
                raise ValueError(f"{os.fspath(path)}: not a metrics JSON ({e})") from None
        m = cls.from_json(d)
        if isinstance(m, Rejected):
            raise ValueError(f"{os.fspath(path)}: metrics: {m}")
        return m

    @classmethod
    def _decode(cls, d: Any) -> "Metrics":
        d = _table(d, "metrics")
        w = ""
        events = d["events"] if "events" in d else _missing(w, "events")
        if not isinstance(events, list):
            raise _bad("events", "a list", events)
        link = _table(d["link"] if "link" in d else _missing(w, "link"), "link")
        pairs = None
        trio = ("closest_pairs", "closest_pair", "near_collision")  # written together, or none
        if any(k in d for k in trio):
            for k in trio:
                if k not in d:
                    _missing(w, k)
            pairs = {str(k): ClosestPair.from_dict(v, f"closest_pairs.{k}.")
                     for k, v in _table(d["closest_pairs"], "closest_pairs").items()}
        closest = d.get("closest_pair")
        known = {f.name for f in fields(cls)} - {"extra"}
        return cls(
            scenario=_str(d, "scenario", w), mode=_str(d, "mode", w), seed=_int(d, "seed", w),
            duration_s=_num(d, "duration_s", w), path_tol=_num(d, "path_tol", w), coord_tol=_num(d, "coord_tol", w),
            path_settle_s=_num(d, "path_settle_s", w, null=True),
            coord_settle_s=_num(d, "coord_settle_s", w, null=True),
            final_path_error_max=_num(d, "final_path_error_max", w, null=True),
            final_coord_error_max=_num(d, "final_coord_error_max", w, null=True),
            omega_rate_final=_numbers_by_id(d, "omega_rate_final", w),
            final_path_error=_numbers_by_id(d, "final_path_error", w), live_final=_ids(d, "live_final", w),
            link=LinkMetrics.from_dict(link) if link else None,
            wall_s=_num(d, "wall_s", w), realtime_factor=_num(d, "realtime_factor", w, null=True),
            policy=_str(d, "policy", w),
            events=tuple(Event.from_dict(e, f"events[{n}].") for n, e in enumerate(events)),
            completed=_bool(d, "completed", w), completion=_str(d, "completion", w),
            min_separation_m=_num(d, "min_separation_m", w, null=True), closest_pairs=pairs,
            closest_pair=None if closest is None else ClosestPair.from_dict(closest, "closest_pair."),
            near_collision=_bool(d, "near_collision", w) if "near_collision" in d else None,
            interventions=_int(d, "interventions", w),
            safety=SafetyInfo.from_dict(d["safety"] if "safety" in d else _missing(w, "safety")),
            obstacles=ObstacleMetrics.from_dict(d["obstacles"]) if "obstacles" in d else None,
            integrity=Integrity.from_dict(d["integrity"]) if "integrity" in d else None,
            rejected_by_reason=RejectedByReason.from_dict(d["rejected_by_reason"]) if "rejected_by_reason" in d
            else None,
            never_up=_ids(d, "never_up", w) if "never_up" in d else None,
            radio=RadioMetrics.from_dict(d["radio"]) if "radio" in d else None,
            interrupted=_bool(d, "interrupted", w) if "interrupted" in d else None,
            written_by=_str(d, "written_by", w) if "written_by" in d else None,
            world_lost=WorldLost.from_dict(d["world_lost"]) if "world_lost" in d else None,
            extra={k: v for k, v in d.items() if k not in known},
        )

    def to_dict(self) -> dict[str, Any]:
        """The metrics JSON (docs/metrics.md): the fields in this class's order, an optional one
        absent when None (``closest_pair`` is written with ``closest_pairs``, null or not), then ``extra``."""
        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "extra":
                out.update(v)
            elif f.name == "link":
                out["link"] = {} if v is None else v.to_dict()
            elif f.name == "closest_pair":
                if "closest_pairs" in out:
                    out[f.name] = None if v is None else v.to_dict()
            elif f.name == "closest_pairs":
                if v is not None:
                    out[f.name] = {k: p.to_dict() for k, p in v.items()}
            elif f.name in _NULLABLE or v is not None:
                out[f.name] = _encode(v)
        return out


#: the fields of Metrics whose JSON is null when they are None (the others are then absent)
_NULLABLE = frozenset(("path_settle_s", "coord_settle_s", "final_path_error_max", "final_coord_error_max",
                       "realtime_factor", "min_separation_m"))


def _encode(v: Any) -> Any:
    """A field's JSON: a part's own to_dict, a tuple a list, a mapping a copy."""
    if is_dataclass(v):
        return v.to_dict()
    if isinstance(v, tuple):
        return [_encode(x) for x in v]
    if isinstance(v, dict):
        return dict(v)
    return v

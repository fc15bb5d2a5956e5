"""What did a run measure? The typed metrics record, decoded once.

:class:`Metrics` (and the records it holds: :class:`LinkMetrics`, :class:`FaultCounters`,
:class:`RadioMetrics`, :class:`Event`, :class:`SafetyInfo`, ...) is a run's metrics JSON
(docs/metrics.md) in types. :meth:`Metrics.from_json` validates a JSON object once (a
``metrics.json`` on disk may be corrupt, or from an older version) and returns the record or
``Rejected(reason, field)`` naming the first bad field, never raising; ``to_dict()`` gives the
JSON back, byte for byte as it was built (cdus.sim.summary). Everything that reads metrics
(``cdus.run``, the summary table of cdus.app.report, the sweep's rows) reads this type and
checks no field again. It is the pure layer's (cdus.sim) so that a builder of the metrics
below the app can make it; :mod:`cdus.results` and :mod:`cdus.api` give it to users.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

from cdus.wire.bounds import is_number
from cdus.wire.rejected import Rejected




class _Bad(ValueError):
    """A field that is not what docs/metrics.md says: raised inside the decoding, which
    :meth:`Metrics.from_json` turns into the Rejected naming the field."""

    def __init__(self, field: str, reason: str):
        self.rejected = Rejected(reason, field)
        super().__init__(f"metrics: {self.rejected}")


def _bad(where: str, expected: str, value: Any) -> _Bad:
    shown = repr(value)
    return _Bad(where, f"expected {expected}, got {shown[:60] + ('...' if len(shown) > 60 else '')}")


def _num(d: Mapping, key: str, where: str, null: bool = False) -> Any:
    v = d[key] if key in d else _missing(where, key)
    if v is None and null:
        return None
    if not is_number(v):
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
    raise _Bad(f"{where}{key}", "missing (docs/metrics.md lists the fields)")


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

    ``from_json`` checks every field's type once (a Rejected naming the first bad one;
    ``from_dict``: the same as a ValueError); ``to_dict()`` gives the JSON back, equal to what was read, in the same key order. Keys the JSON may lack are None
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
    obstacles: ObstacleMetrics | None = None  # with [[obstacle]] only
    integrity: Integrity | None = None  # None only in metrics written before it was (and the launcher's world_lost)
    rejected_by_reason: RejectedByReason | None = None
    radio: RadioMetrics | None = None  # with [radio] only
    interrupted: bool | None = None
    never_up: tuple[str, ...] | None = None  # only in a run that never began (completion not_started)
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
        never_up = d.get("never_up")  # absent, or a list (null would not come back from to_dict)
        if "never_up" in d and (not isinstance(never_up, list) or not all(isinstance(v, str) for v in never_up)):
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
            obstacles=ObstacleMetrics.from_dict(d["obstacles"]) if "obstacles" in d else None,
            integrity=Integrity.from_dict(d["integrity"]) if "integrity" in d else None,
            rejected_by_reason=rej,
            radio=RadioMetrics.from_dict(d["radio"]) if "radio" in d else None,
            interrupted=_bool(d, "interrupted", w) if "interrupted" in d else None,
            never_up=None if never_up is None else tuple(never_up),
            extra={k: v for k, v in d.items() if k not in known},
        )

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
            elif f.name in ("radio", "obstacles"):
                if v is not None:
                    out[f.name] = v.to_dict()
            else:
                out[f.name] = v
        return out

"""What do the realism sections of a scenario file ([safety], [disturbance], [observer]) hold? Checked values.

Each validator takes the collected :class:`Problems` and its table and returns the
section's values with the defaults filled in (docs/config.md lists them; docs/safety.md
explains them). A bad value is reported and replaced by its default.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Mapping, Sequence

from cdus.core.observer import DEFAULT_BANDWIDTH
from cdus.scenario.checks import Problems
from cdus.scenario.model import DEFAULT_SAFETY, Safety, VehicleSpec
from cdus.wire.bounds import BOUNDS

SAFETY_UNITS = {"radius": " m", "gamma": " 1/s", "range": " m", "rate": " Hz"}
#: [disturbance] sub-table -> the vehicle kind it pushes and its dimension
DISTURBANCE_KINDS = {"current": ("usv", 2), "wind": ("uav", 3)}
DISTURBANCE_FIELDS = ("constant", "gust", "gust_tau")
OBSERVER_KEYS = ("enabled", "bandwidth")


def safety_section(p: Problems, sf: Mapping[str, Any]) -> Safety:
    """[safety]: the filter on/off, R, γ, the sensor's range, rate and latency."""
    p.unknown_keys(sf, DEFAULT_SAFETY, "safety")
    out = dict(DEFAULT_SAFETY)
    for key in ("enabled", "cross_domain"):
        if key in sf:
            got = p.boolean(sf[key], f"safety.{key}", true=" (on)", false=" (off)")
            out[key] = DEFAULT_SAFETY[key] if got is None else got
    for key, unit in SAFETY_UNITS.items():
        if key in sf:
            out[key] = p.number(sf[key], f"safety.{key}", f"safety.{key}", unit=unit) or DEFAULT_SAFETY[key]
    if "latency" in sf:
        got = p.number(sf["latency"], "safety.latency", "safety.latency",
                       unit=" s (contacts are used from the next control tick at the earliest)")
        out["latency"] = DEFAULT_SAFETY["latency"] if got is None else got
    if "sidestep" in sf:
        side = BOUNDS["safety.sidestep"]
        got = p.number(sf["sidestep"], "safety.sidestep", ge=side.lo, unit=" (below 1; 0 turns the sidestep off)")
        if got is not None and not side.holds(got):
            p.add("safety.sidestep", f"must be below 1 (a fraction of |u_ref|; 0 turns the sidestep off), got {got:g}")
            got = None
        out["sidestep"] = DEFAULT_SAFETY["sidestep"] if got is None else got
    if out["range"] <= out["radius"]:
        default = "" if "range" in sf else " (the default; set safety.range above the radius)"
        p.add("safety.range", f"must be above safety.radius ({out['radius']:g} m): the sensor has to see a "
                              f"vehicle before it is too close; got {out['range']:g}{default}")
    return Safety(**out)


def disturbance_section(p: Problems, dt: Mapping[str, Any]) -> dict[str, tuple[tuple[str, Any], ...]]:
    """[disturbance]: ``current`` (on every USV) and ``wind`` (on every UAV), each a table of
    constant (m/s, one per axis), gust (std, m/s) and gust_tau (s). Returns kind -> the
    disturbance pairs a VehicleSpec carries."""
    p.unknown_keys(dt, DISTURBANCE_KINDS, "disturbance")
    out = {}
    for name, (kind, dim) in DISTURBANCE_KINDS.items():
        if name not in dt:
            continue
        field = f"disturbance.{name}"
        tbl = p.table(dt[name], field, f"{name} = {{ constant = [{', '.join(['0.3'] + ['0.0'] * (dim - 1))}], "
                                       f"gust = 0.1 }}")
        if tbl is None:
            continue
        p.unknown_keys(tbl, DISTURBANCE_FIELDS, field)
        got: dict[str, Any] = {}
        if "constant" in tbl:
            got["constant"] = p.vector(tbl["constant"], f"{field}.constant", dim,
                                       f"the {name} on every {kind} in m/s, one per axis", key="disturbance.constant")
        if "gust" in tbl:
            got["gust"] = p.number(tbl["gust"], f"{field}.gust", "disturbance.gust", unit=" m/s (std of the gusts)")
        if "gust_tau" in tbl:
            got["gust_tau"] = p.number(tbl["gust_tau"], f"{field}.gust_tau", "disturbance.gust_tau",
                                       unit=" s (correlation time of the gusts)")
        out[kind] = tuple(sorted((k, x) for k, x in got.items() if x is not None))
    return out


def observer_section(p: Problems, ob: Mapping[str, Any]) -> float | None:
    """[observer]: the disturbance observer's bandwidth (rad/s) if enabled, else None."""
    p.unknown_keys(ob, OBSERVER_KEYS, "observer")
    enabled = p.boolean(ob.get("enabled", False), "observer.enabled", true=" (compensate the disturbance)",
                        false=" (off)")
    bandwidth = DEFAULT_BANDWIDTH
    if "bandwidth" in ob:
        bandwidth = p.number(ob["bandwidth"], "observer.bandwidth", "observer.bandwidth",
                             unit=" rad/s (well above the path gain k, well below the physics rate)") \
            or DEFAULT_BANDWIDTH
    return bandwidth if enabled else None


def apply_fleet(specs: Sequence[VehicleSpec | None], raw_vehicles: Any, defaults: Mapping,
                disturbance: Mapping[str, tuple], observer: float | None) -> list[VehicleSpec | None]:
    """The fleet-wide [disturbance] on every vehicle of its kind that sets no disturbance of
    its own (in [[vehicle]] or [defaults]), and the [observer] on every vehicle."""
    own = [isinstance(t, dict) and "disturbance" in t for t in (raw_vehicles or [])] if isinstance(raw_vehicles, list) \
        else []
    out = []
    for j, spec in enumerate(specs):
        if spec is None or spec.plant == "ros2":  # a real robot: its disturbance is real, no model to observe
            out.append(spec)
            continue
        changes: dict[str, Any] = {}
        has_own = (j < len(own) and own[j]) or "disturbance" in defaults
        if not has_own and spec.kind in disturbance:
            changes["disturbance"] = disturbance[spec.kind]
        if observer is not None:
            changes["observer"] = observer
        out.append(replace(spec, **changes) if changes else spec)
    return out

"""What do the small sections of a scenario file hold? [scenario], [rates], [metrics], [gains], [supervision].

Each validator takes the collected :class:`Problems` and the section's table and returns
the section's values, with defaults filled in (docs/config.md lists them). A bad value is
reported and replaced by its default, so the later sections can still be checked.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterable, Mapping

from cdus.scenario.checks import Problems, is_number, num
from cdus.scenario.model import (
    DEFAULT_BACKOFF_S, DEFAULT_MAX_RESTARTS, DEFAULT_RESTART, RESTART_POLICIES, Rates, Supervision,
)

DEFAULT_DURATION = 60.0
DEFAULT_SEED = 0
DEFAULT_RATES = {"physics": 200.0, "control": 50.0, "broadcast": 50.0}
DEFAULT_METRICS = {"path_tol": 0.1, "coord_tol": 0.05}
DEFAULT_GAINS = {"k": 1.5, "c": 2.0}  # the paper's

SCENARIO_KEYS = ("name", "description", "duration", "seed")
METRIC_UNITS = {"path_tol": " m", "coord_tol": " rad"}
SUPERVISION_KEYS = ("restart", "max_restarts", "backoff_s")


def section(p: Problems, data: Mapping[str, Any], name: str) -> dict:
    """The top-level table ``[name]`` ({} if absent or not a table)."""
    return p.table(data.get(name, {}), name, f"a [{name}] section") or {}


@dataclass(frozen=True)
class Header:
    """The [scenario] table."""

    name: str
    description: str
    duration: float
    seed: int


def scenario_section(p: Problems, sc: Mapping[str, Any]) -> Header:
    p.unknown_keys(sc, SCENARIO_KEYS, "scenario")
    name = ""
    if "name" not in sc:
        p.missing("scenario.name", 'every scenario needs a name, e.g. [scenario] name = "lake_circle"')
    else:
        name = p.string(sc["name"], "scenario.name", nonempty=True, one_line=True) or ""
        if "/" in name or "\\" in name:  # runs/<name>-<time>: "../../x" or "/x" made a directory anywhere
            p.add("scenario.name", f"must not contain / or \\ (it names the run directory, runs/<name>-<time>), "
                                   f"got '{name}'; e.g. {name.replace('/', '_').replace(chr(92), '_').strip('._')!r}")
            name = ""
    description = p.string(sc.get("description", ""), "scenario.description") or ""
    duration = DEFAULT_DURATION
    if "duration" in sc:
        duration = p.number(sc["duration"], "scenario.duration", "scenario.duration", unit=" s") or DEFAULT_DURATION
    seed = p.integer(sc.get("seed", DEFAULT_SEED), "scenario.seed", ge=0)
    return Header(name, description, duration, DEFAULT_SEED if seed is None else seed)


def rates_section(p: Problems, rt: Mapping[str, Any]) -> Rates:
    """[rates] in Hz; unset rates follow the control rate: broadcast once per control step,
    physics at least that often."""
    p.unknown_keys(rt, DEFAULT_RATES, "rates")
    rates = dict(DEFAULT_RATES)
    mark = len(p)
    for key in DEFAULT_RATES:
        if key in rt:
            rates[key] = p.number(rt[key], f"rates.{key}", f"rates.{key}", unit=" Hz") or rates[key]
    if "broadcast" not in rt:
        rates["broadcast"] = rates["control"]
    if "physics" not in rt:
        rates["physics"] = max(rates["physics"], rates["control"])
    if not p.since(mark):
        control = num(rates["control"])
        if rates["physics"] < rates["control"]:
            p.add("rates.physics", f"must be >= rates.control ({control} Hz): the plant steps at least once "
                                   f"per control period; got {num(rates['physics'])}")
        if rates["broadcast"] > rates["control"]:
            p.add("rates.broadcast", f"must be <= rates.control ({control} Hz): a vehicle has a new ω at most "
                                     f"once per control step; got {num(rates['broadcast'])}")
    return Rates(**rates)


#: The default path_tol of a fleet with usv_3dof boats, by preset (a boat given its own epsilon:
#: cybership2's). The heading regulator leaves a boat a steady crab angle, and the GVF's -KΦ term
#: holds it |Φ| ≈ 1.5 v² / (R k) inside a path of radius R at v m/s (measured, lake_circle_dynamic,
#: k = 1.5, R = 10 m: 0.0997 m at 1 m/s, 0.23 at 1.5, 0.40 at 2): 0.1 m is not reached with any
#: margin at 1 m/s. 0.15 m separates "on the path" from "still approaching" at ~1 m/s; faster
#: boats or tighter turns need [metrics] path_tol set (docs/config.md, [metrics]).
USV_PATH_TOL = {"cybership2": 0.15}
USV_PATH_TOL_OTHER = USV_PATH_TOL["cybership2"]


def default_path_tol(specs: Iterable[Any]) -> float:
    """The path_tol of a scenario whose [metrics] does not give one: DEFAULT_METRICS', or that
    of its usv_3dof boats' presets (USV_PATH_TOL) if larger."""
    tol = DEFAULT_METRICS["path_tol"]
    for v in specs:
        if v is not None and v.plant == "usv_3dof":
            tol = max(tol, USV_PATH_TOL.get(v.preset, USV_PATH_TOL_OTHER))
    return tol


def metrics_section(p: Problems, mt: Mapping[str, Any]) -> tuple[float, float]:
    """[metrics]: (path_tol, coord_tol)."""
    p.unknown_keys(mt, DEFAULT_METRICS, "metrics")
    tol = dict(DEFAULT_METRICS)
    for key, unit in METRIC_UNITS.items():
        if key in mt:
            tol[key] = p.number(mt[key], f"metrics.{key}", f"metrics.{key}", unit=unit) or tol[key]
    return tol["path_tol"], tol["coord_tol"]


GUIDANCE_KEYS = ("scale_omega",)


def guidance_section(p: Problems, g: Mapping[str, Any]) -> bool:
    """[guidance]: whether a vehicle's speed limit also scales ω's path-following part."""
    p.unknown_keys(g, GUIDANCE_KEYS, "guidance")
    return bool(p.boolean(g.get("scale_omega", False), "guidance.scale_omega",
                          true=" (σ = min(1, v_max/|a|) scales ω's path-following part too)",
                          false=" (only the velocity reference is limited)"))


def gains_section(p: Problems, gains: Mapping[str, Any]) -> dict:
    """[gains], the fleet's default guidance gains; the per-axis length of k is checked per vehicle."""
    p.unknown_keys(gains, DEFAULT_GAINS, "gains")
    gain_values(p, gains, "gains")
    return dict(gains)


def gain_values(p: Problems, gains: Mapping[str, Any], prefix: str, note: str = "") -> None:
    """k (a number > 0 or a list of per-axis numbers > 0) and c (> 0) of a gains table."""
    if "k" in gains:
        k = gains["k"]
        if isinstance(k, list):
            if not k:
                p.add(f"{prefix}.k", f"must be a number > 0 or a list of per-axis numbers > 0, got []{note}")
            for j, x in enumerate(k):
                p.number(x, f"{prefix}.k[{j}]", "gains.k", note=note)
        else:
            p.number(k, f"{prefix}.k", "gains.k", unit=" (or a list of per-axis numbers)" if not is_number(k) else "",
                     note=note)
    if "c" in gains:
        p.number(gains["c"], f"{prefix}.c", "gains.c", note=note)


def supervision_section(p: Problems, sv: Mapping[str, Any]) -> Supervision:
    """[supervision]: the launcher's restart policy for vehicle processes."""
    p.unknown_keys(sv, SUPERVISION_KEYS, "supervision")
    restart = DEFAULT_RESTART
    if "restart" in sv:
        restart = p.choice(sv["restart"], "supervision.restart", RESTART_POLICIES, "restart policy") \
            or DEFAULT_RESTART
    max_restarts = p.integer(sv.get("max_restarts", DEFAULT_MAX_RESTARTS), "supervision.max_restarts", ge=0,
                             unit=" (restarts of one vehicle's process)")
    backoff = DEFAULT_BACKOFF_S
    if "backoff_s" in sv:
        backoff = p.number(sv["backoff_s"], "supervision.backoff_s", "supervision.backoff_s",
                           unit=" s (the wait before a vehicle's first restart)") or DEFAULT_BACKOFF_S
    return Supervision(restart, DEFAULT_MAX_RESTARTS if max_restarts is None else max_restarts, backoff)

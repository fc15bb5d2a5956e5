"""What is in a run's metrics JSON? One builder for the in-process fleet, the world, sweep and report.

Field names and definitions are docs/metrics.md's: the Recorder's summary (path and
coordination settle times, final errors, ω̇, wall time), the link block (messages sent
to, delivered at, dropped and rejected by the receivers, latency percentiles, and the
fault emulator's per-link counters), the stale-neighbour policy, the events, whether
the run reached its end, and the safety figures: ``min_separation_m`` (the smallest
distance between two vehicles of the same domain), ``closest_pairs`` / ``closest_pair``
(who came closest, when, and whether both were live), ``near_collision`` (a closest
pair below the safety radius, also with the filter off) and ``interventions`` (control
steps at which a safety filter changed a velocity reference, summed over the fleet).

What it builds is the JSON, byte for byte what a run writes; its readers (``cdus.run``, the
summary table, the sweep's rows) take it, or the file, into the typed record once:
:meth:`cdus.sim.runmetrics.Metrics.from_json`.
"""

from __future__ import annotations

from typing import Any, Iterable, Sequence

from cdus.core.link import LinkCounters
from cdus.core.obstacle_metrics import obstacle_block
from cdus.core.metrics import CROSS_DOMAIN, Recorder, closest_pairs, min_separation, percentile_ms
from cdus.core.vocabulary import KINDS
from cdus.scenario.model import Scenario
from cdus.wire.schemas import FleetEvent


from cdus.wire.schemas import COMPLETED, COMPLETIONS  # noqa: F401  (defined with the status that carries them)


def link_block(counters: LinkCounters, faults: dict | None = None, **extra: Any) -> dict[str, Any]:
    """``link`` of the metrics JSON from summed counters (and the emulator's summary)."""
    c = counters
    out: dict[str, Any] = {
        "sent": c.sent, "delivered": c.delivered, "dropped": c.dropped, "duplicated": c.duplicated,
        "rejected": c.rejected,
        "latency_ms_p50": percentile_ms(c.latencies, 50), "latency_ms_p99": percentile_ms(c.latencies, 99),
        **extra,
    }
    if faults is not None:
        out["faults"] = faults
    return out


def sum_counters(counters: Iterable[LinkCounters]) -> LinkCounters:
    total = LinkCounters()
    for c in counters:
        total.add(c)
    return total


def run_metrics(scenario: Scenario, recorder: Recorder, *, mode: str, link: dict[str, Any], wall_s: float,
                policy: str, events: Sequence[FleetEvent] = (), completed: bool = True,
                interventions: int = 0, completion: str | None = None, integrity: dict[str, Any] | None = None,
                deflected: Sequence[int] | None = None, **extra: Any) -> dict[str, Any]:
    """The metrics JSON (also of an empty or interrupted run). ``completion``: COMPLETED or why
    not (COMPLETIONS); by default COMPLETED or "interrupted" after ``completed``. ``integrity``:
    what may have altered the run (a launched fleet's world finds it; in process, nothing can)."""
    completion = completion or (COMPLETED if completed else "interrupted")
    if completion not in COMPLETIONS or completed != (completion == COMPLETED):
        raise ValueError(f"completed {completed} with completion {completion!r}")
    m = recorder.summary(scenario=scenario.name, mode=mode, seed=scenario.seed, path_tol=scenario.path_tol,
                         coord_tol=scenario.coord_tol, link=link, wall_s=wall_s)
    m["policy"] = policy
    m["events"] = [e.as_dict() for e in events]
    m["completed"] = completed
    m["completion"] = completion
    kinds = [v.kind for v in scenario.vehicles]
    sep = min_separation(recorder.view("q"), kinds)
    m["min_separation_m"] = None if sep is None else round(sep, 6)
    m.update(safety_figures(recorder, kinds, scenario.safety.radius))
    m["interventions"] = interventions
    m["safety"] = {"enabled": scenario.safety.enabled, "radius_m": scenario.safety.radius}
    if scenario.obstacles:  # [[obstacle]]: clearances and deflected time (cdus.core.obstacle_metrics)
        m["obstacles"] = obstacle_block(recorder.view("t"), recorder.view("q"), recorder.ids, kinds, scenario.obstacles,
                                        deflected, 1.0 / scenario.rates.control)
    m["integrity"] = integrity or {"tampered": False, "reasons": {}, "notes": []}  # nothing seen to alter it
    m.update(extra)
    return m


def safety_figures(recorder: Recorder, kinds: Sequence[str], radius: float) -> dict[str, Any]:
    """``closest_pairs`` (per domain), ``closest_pair`` (the closest of them) and
    ``near_collision`` (one of them strictly below ``radius``: the [safety] table's R, or
    its default, 2 m, when the table is absent; whether the filter is on or not)."""
    pairs = closest_pairs(recorder.view("t"), recorder.view("q"), recorder.view("live"), recorder.ids, kinds)
    closest = min(pairs.values(), key=lambda p: (p.distance, p.t), default=None)
    return {
        "closest_pairs": {d: pairs[d].as_dict() for d in (*KINDS, CROSS_DOMAIN) if d in pairs},
        "closest_pair": None if closest is None else closest.as_dict(),
        "near_collision": any(p.distance < radius for p in pairs.values()),
    }

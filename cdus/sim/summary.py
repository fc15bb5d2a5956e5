"""What is in a run's metrics? One builder for the in-process fleet, the world and the launcher.

Field names and definitions are docs/metrics.md's: the Recorder's summary (path and
coordination settle times, final errors, ω̇, wall time), the link block (messages sent
to, delivered at, dropped and rejected by the receivers, latency percentiles, and the
fault emulator's per-link counters), the stale-neighbour policy, the events, whether
the run reached its end, and the safety figures: ``min_separation_m`` (the smallest
distance between two vehicles of the same domain), ``closest_pairs`` / ``closest_pair``
(who came closest, when, and whether both were live), ``near_collision`` (a closest
pair below the safety radius, also with the filter off) and ``interventions`` (control
steps at which a safety filter changed a velocity reference, summed over the fleet).

What it builds is the typed record, :class:`cdus.sim.runmetrics.Metrics`, one part per
concern; its ``to_dict()`` is the JSON a run writes. ``cdus.run``, the summary table and the
sweep's rows take the record from here in process, and :meth:`Metrics.read` from a file.
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Sequence

from cdus.core.link import LinkCounters
from cdus.core.obstacle_metrics import obstacle_block
from cdus.core.metrics import CROSS_DOMAIN, Recorder, closest_pairs, min_separation, percentile_ms
from cdus.core.vocabulary import KINDS
from cdus.scenario.model import Scenario
from cdus.sim.runmetrics import (ClosestPair, DroppedBy, Event, FaultCounters, Integrity, LinkFaults, LinkMetrics,
                                 LinkStateChange, Metrics, ObstacleMetrics, RadioMetrics, RejectedByReason, SafetyInfo)
from cdus.wire.schemas import FleetEvent


from cdus.wire.schemas import COMPLETED, COMPLETIONS  # noqa: F401  (defined with the status that carries them)

#: what a run in which nothing could meddle saw (in process; a launched fleet's world finds its own)
UNTOUCHED = Integrity(tampered=False, reasons={}, notes=())


def link_metrics(counters: LinkCounters, faults: LinkFaults | None = None,
                 missed_deadlines: int | None = None) -> LinkMetrics:
    """``link`` of the metrics from summed counters (and the emulator's counters, ``faults``,
    only when the scenario's link has faults); ``missed_deadlines``: a fleet of processes only."""
    c = counters
    return LinkMetrics(sent=c.sent, delivered=c.delivered, dropped=c.dropped, duplicated=c.duplicated,
                       rejected=c.rejected, latency_ms_p50=percentile_ms(c.latencies, 50),
                       latency_ms_p99=percentile_ms(c.latencies, 99), missed_deadlines=missed_deadlines,
                       faults=faults)


def link_faults(summary: Mapping[str, Any]) -> LinkFaults:
    """``link.faults`` from the link emulator's ``counters_summary()`` (or several merged:
    ``merge_link_summaries``): built by the core, or checked where it came in (an agent's stats,
    cdus.wire.stats), so taken as it is."""
    def counters(c: Mapping[str, Any]) -> FaultCounters:
        return FaultCounters(sent=c["sent"], dropped=c["dropped"], dropped_by=DroppedBy(**c["dropped_by"]),
                             duplicated=c["duplicated"], delayed=c["delayed"])

    return LinkFaults(total=counters(summary["total"]), links={k: counters(v) for k, v in summary["links"].items()},
                      state_changes=tuple(LinkStateChange(t=c["t"], link=c["link"], state=c["state"])
                                          for c in summary["state_changes"]))


def sum_counters(counters: Iterable[LinkCounters]) -> LinkCounters:
    total = LinkCounters()
    for c in counters:
        total.add(c)
    return total


def run_metrics(scenario: Scenario, recorder: Recorder, *, mode: str, link: LinkMetrics | None, wall_s: float,
                policy: str, events: Sequence[FleetEvent] = (), completed: bool = True,
                interventions: int = 0, completion: str | None = None, integrity: Integrity = UNTOUCHED,
                rejected_by_reason: RejectedByReason | None = None, never_up: Sequence[str] | None = None,
                radio: RadioMetrics | None = None, deflected: Sequence[int] | None = None) -> Metrics:
    """The metrics of a run (also of an empty or interrupted one). ``completion``: COMPLETED or
    why not (COMPLETIONS); by default COMPLETED or "interrupted" after ``completed``.
    ``integrity``: what may have altered the run (a launched fleet's world finds it; in process,
    nothing can). ``link`` None: nothing is known of the links (the launcher's lost world).
    ``deflected``: per vehicle, the control steps an obstacle deflected it (None: not known)."""
    completion = completion or (COMPLETED if completed else "interrupted")
    if completion not in COMPLETIONS or completed != (completion == COMPLETED):
        raise ValueError(f"completed {completed} with completion {completion!r}")
    s = recorder.summary(scenario=scenario.name, mode=mode, seed=scenario.seed, path_tol=scenario.path_tol,
                         coord_tol=scenario.coord_tol, link={}, wall_s=wall_s)
    kinds = [v.kind for v in scenario.vehicles]
    sep = min_separation(recorder.view("q"), kinds)
    pairs, closest, near = safety_figures(recorder, kinds, scenario.safety.radius)
    return Metrics(
        **{**s, "live_final": tuple(s["live_final"]), "link": link}, policy=policy,
        events=tuple(Event(**e.as_dict()) for e in events), completed=completed, completion=completion,
        min_separation_m=None if sep is None else round(sep, 6), closest_pairs=pairs, closest_pair=closest,
        near_collision=near, interventions=interventions,
        safety=SafetyInfo(enabled=scenario.safety.enabled, radius_m=scenario.safety.radius),
        obstacles=obstacle_metrics(recorder, kinds, scenario, deflected), integrity=integrity,
        rejected_by_reason=rejected_by_reason, never_up=None if never_up is None else tuple(never_up), radio=radio)


def obstacle_metrics(recorder: Recorder, kinds: Sequence[str], scenario: Scenario,
                     deflected: Sequence[int] | None) -> ObstacleMetrics | None:
    """The ``obstacles`` part ([[obstacle]] only): each vehicle's smallest clearance and its time
    deflected (cdus.core.obstacle_metrics)."""
    if not scenario.obstacles:
        return None
    b = obstacle_block(recorder.view("t"), recorder.view("q"), recorder.ids, kinds, scenario.obstacles, deflected,
                       1.0 / scenario.rates.control)
    return ObstacleMetrics(count=b["count"], min_clearance_m=b["min_clearance_m"],
                           below_margin=tuple(b["below_margin"]), vehicles=b["vehicles"])


def safety_figures(recorder: Recorder, kinds: Sequence[str],
                   radius: float) -> tuple[dict[str, ClosestPair], ClosestPair | None, bool]:
    """``closest_pairs`` (per domain), ``closest_pair`` (the closest of them) and
    ``near_collision`` (one of them strictly below ``radius``: the [safety] table's R, or
    its default, 2 m, when the table is absent; whether the filter is on or not)."""
    pairs = closest_pairs(recorder.view("t"), recorder.view("q"), recorder.view("live"), recorder.ids, kinds)
    closest = min(pairs.values(), key=lambda p: (p.distance, p.t), default=None)
    return ({d: ClosestPair(**pairs[d].as_dict()) for d in (*KINDS, CROSS_DOMAIN) if d in pairs},
            None if closest is None else ClosestPair(**closest.as_dict()),
            any(p.distance < radius for p in pairs.values()))

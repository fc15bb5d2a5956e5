"""What a person sees: progress lines, the end-of-run summary table, the run directory."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any, Sequence, TextIO

from cdus.scenario.model import VehicleSpec
from cdus.sim.runmetrics import Event, Metrics
from cdus.wire.bounds import finite, is_number
from cdus.wire.text import printable


def run_dir(base: str | os.PathLike, scenario: str) -> Path:
    """A fresh ``runs/<scenario>-<YYYYmmdd-HHMMSS>[-n]`` directory."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    root = Path(base)
    d = root / f"{scenario}-{stamp}"
    n = 1
    while d.exists():
        n += 1
        d = root / f"{scenario}-{stamp}-{n}"
    d.mkdir(parents=True)
    return d


class Progress:
    """One updating line on a terminal, a line per ~10% otherwise."""

    def __init__(self, label: str, stream: TextIO = sys.stderr, quiet: bool = False):
        self.label = label
        self.stream = stream
        self.quiet = quiet
        self.tty = stream.isatty()
        self._last_decile = -1
        self._first: tuple[float, float] | None = None  # (simulated t, wall) of the first report

    def __call__(self, t: float, total: float) -> None:
        if self.quiet or total <= 0:
            return
        now = time.perf_counter()
        rate = None
        if self._first is None:
            # the rate is measured from the first report: a fleet's start-up (processes, sessions)
            # before it is not simulation (a realtime launch's first line said "0.3x real time")
            self._first = (t, now) if t > 0 else None
        elif now > self._first[1] and t > self._first[0]:
            rate = (t - self._first[0]) / (now - self._first[1])
        frac = min(1.0, t / total)
        line = f"{self.label}: t = {t:7.1f} / {total:.1f} s ({frac:4.0%})" + (
            f", {rate:6.1f}x real time" if rate is not None else "")
        if self.tty:
            self.stream.write("\r" + line)
            self.stream.flush()
        else:
            decile = int(frac * 10)
            if decile > self._last_decile:
                self._last_decile = decile
                self.stream.write(line + "\n")
                self.stream.flush()

    def done(self) -> None:
        if self.tty and not self.quiet:
            self.stream.write("\r" + " " * 80 + "\r")
            self.stream.flush()


def _fmt(x: Any, spec: str = ".3f", none: str = "never") -> str:
    if x is None:
        return none
    if is_number(x) and not finite(x):
        return str(x)
    return format(x, spec)


def _not_live(vid: str, m: Metrics, never_up: Sequence[str]) -> str:
    """Why a vehicle was not live at the end, as far as the metrics say."""
    if vid in never_up:
        return "  (never came up)"
    if m.completion == "not_started":
        return "  (up, waiting for the others: the run never started)"
    if m.completion == WORLD_LOST:  # live_final is the world's last status, or nothing
        t = _world_lost_t(m)
        return ("  (not known: the world was lost before its first status)" if t is None else
                f"  (not live at the world's last status, t = {t:.1f} s)")
    return "  (not live at the end: killed or paused; left out of the worst errors)"


#: the completion the launcher writes when the world process died without writing its metrics
#: (cdus.app.launcher.WORLD_LOST): the trace is lost; what is known is the world's last status
WORLD_LOST = "world_lost"


def _world_lost_t(m: Metrics) -> float | None:
    """The time of the world's last status in a world_lost record (the launcher's ``world_lost``);
    None: it gave none."""
    return None if m.world_lost is None else m.world_lost.last_status_t


def _lost_words(m: Metrics) -> str:
    t = _world_lost_t(m)
    return "the world was lost before its first status" if t is None else f"the world was lost at t = {t:.1f} s"


def boat_offset_note(m: Metrics, vehicles: Sequence[VehicleSpec]) -> list[str]:
    """A line when the path never settled because usv_3dof boats end above path_tol: they keep
    a steady offset from their path (their crab angle), which grows with speed and turn rate."""
    pe, tol = m.final_path_error, m.path_tol
    if m.path_settle_s is not None or not m.completed:
        return []
    above = [(v.id, pe[v.id]) for v in vehicles if v.plant == "usv_3dof" and pe.get(v.id) is not None
             and pe[v.id] >= tol]
    if not above:
        return []
    worst = max(x for _, x in above)
    return [f"  note: usv_3dof boats hold a steady offset from their path (crab angle; about 1.5 v²/(R k) m at v "
            f"m/s on a turn of radius R m): {', '.join(v for v, _ in above)} ended {worst:.3f} m off, above "
            f"path_tol {tol:g} m; set [metrics] path_tol above it (docs/config.md, [metrics])"]


def _settle(x: float | None, unknown: str | None = None) -> str:
    """A settle time; None is "never" for a run whose trace was judged, ``unknown`` (the words
    why) for one whose trace was lost (the world died): it may have settled."""
    if x is None:
        return unknown or "never (not within the tolerance at the end)"
    return f"{x:.2f} s"


def integrity_lines(m: Metrics) -> list[str]:
    """A line when something was seen that may have altered the run (metrics ``integrity``):
    ``completed`` says the run reached its end, not that nobody meddled with it."""
    integrity = m.integrity
    if integrity is None or not integrity.tampered:
        return []
    notes = [printable(x, 160) for x in integrity.notes]
    counts = ", ".join(f"{printable(k, 40)} {v}" for k, v in integrity.reasons.items())
    return [f"  TAMPERED: the result may have been altered ({counts}): " + "; ".join(notes[:3])
            + (f"; and {len(notes) - 3} more" if len(notes) > 3 else "") + " (metrics integrity, docs/security.md)"]


def summary_table(m: Metrics, vehicles: Sequence[VehicleSpec]) -> str:
    """The end-of-run table: per vehicle (the scenario's, in order), then per run. ``m`` is the
    typed record (cdus.sim.runmetrics, checked once where it was read): no field is checked here."""
    lines = []
    rf = m.realtime_factor
    # the world died (the launcher wrote these metrics): the trace is lost with it, so the settle
    # times are not known, and the errors are those of the world's last status, if it gave one
    lost = m.completion == WORLD_LOST
    t_lost = _world_lost_t(m) if lost else None
    if lost and t_lost is None:  # its duration_s (0) is not a time the run reached
        lines.append(f"{m.scenario} ({m.mode}, seed {m.seed}): {m.wall_s:.1f} s wall; how far the "
                     f"run got is not known")
    else:
        lines.append(
            f"{m.scenario} ({m.mode}, seed {m.seed}): {m.duration_s:.1f} s simulated in "
            f"{m.wall_s:.1f} s wall" + (f" ({rf:.0f}x real time)" if rf else ""))
    never_up = list(m.never_up or ())
    if m.completion == "not_started":
        lines.append("  NOT STARTED: " + (f"{', '.join(never_up)} never came up; " if never_up else "")
                     + "the run did not begin, nothing below was simulated")
    elif lost:
        lines.append(f"  NOT COMPLETED ({WORLD_LOST}): {_lost_words(m)} and the run's trace with it: the settle "
                     "times are not known" + ("" if t_lost is None else
                                              ", the errors below are those of the world's last status"))
    elif not m.completed:
        lines.append(f"  NOT COMPLETED ({m.completion}): the run ended at "
                     f"{m.duration_s:.1f} s; the settle times and errors below are of what ran")
    lines += integrity_lines(m)
    head = f"  {'vehicle':<10} {'kind':<4} {'plant':<22} {'|Φ| final (m)':>14} {'ω̇ final':>10}"
    lines.append(head)
    lines.append("  " + "-" * (len(head) - 2))
    pe = m.final_path_error
    for v in vehicles:
        gone = v.id not in m.live_final
        lines.append(
            f"  {v.id:<10} {v.kind:<4} {v.plant:<22} {_fmt(pe.get(v.id), '.4f', 'n/a'):>14} "
            f"{_fmt(m.omega_rate_final.get(v.id), '.4f', 'n/a'):>10}"
            + ("" if not gone else _not_live(v.id, m, never_up)))
    unknown = f"not known: {_lost_words(m)}" if lost else None
    lines.append(f"  path settle (worst |Φ| < {m.path_tol} m):             "
                 f"{_settle(m.path_settle_s, unknown)}")
    lines += boat_offset_note(m, vehicles)
    lines.append(f"  coordination settle (worst edge < {m.coord_tol} rad): "
                 f"{_settle(m.coord_settle_s, unknown)}")
    if lost and t_lost is None:
        lines.append(f"  worst |Φ| and coordination error: not known ({_lost_words(m)})")
    else:
        final, when = ("", f" at the world's last status (t = {t_lost:.1f} s)") if lost else ("final ", "")
        lines.append(f"  {final}worst |Φ| {_fmt(m.final_path_error_max, '.4f', 'n/a')} m, "
                     f"{final}worst coordination error {_fmt(m.final_coord_error_max, '.4f', 'n/a')} rad{when}")
    safety = m.safety
    if safety.enabled or m.min_separation_m is not None:
        sep = m.min_separation_m
        radius = safety.radius_m
        below = (sep is not None and radius is not None and safety.enabled and sep < radius - 1e-6)
        lines.append(f"  min separation (same domain) {_fmt(sep, '.3f', 'n/a')} m"
                     + (f", safety radius {radius:g} m, {m.interventions} filter interventions"
                        if safety.enabled else "")
                     + ("  [BELOW THE SAFETY RADIUS]" if below else ""))
    lines += closest_lines(m)
    lines += obstacle_lines(m)
    link = m.link
    if link is not None:
        lines.append(f"  link: {link.sent} sent, {link.delivered} delivered, "
                     f"{link.dropped} dropped, {link.rejected} rejected")
    lines += radio_lines(m)
    return "\n".join(lines)


def radio_lines(m: Metrics) -> list[str]:
    """With [radio]: what the radio path did (drops by cause, the hand-set fault first), the
    channel utilisation (mean, max over the geometry samples) and the communication-graph splits."""
    r = m.radio
    if r is None:
        return []
    causes = ", ".join(f"{k} {v}" for k, v in r.dropped_by.items() if v) or "none"
    u = r.utilisation
    spans = split_spans(m.events)
    return [f"  radio: {r.sent} decided, {r.delivered} delivered, {r.dropped} dropped "
            f"({causes}); channel utilisation mean {_fmt(u.mean, '.3f', 'n/a')}, "
            f"max {_fmt(u.max, '.3f', 'n/a')}; {r.splits} graph split(s)"
            + (f": {spans}" if spans else "")]


#: at most this many split intervals in the summary line (the metrics' events have them all)
MAX_SPANS = 4


def split_spans(events: Sequence[Event]) -> str:
    """When the communication graph was split, from the ``radio_split`` / ``radio_joined``
    events: ``18.8-83.8 s``, ``from 16.2 s, still split at the end``, several comma-separated; "" without."""
    spans: list[str] = []
    start = None
    for e in events:
        if e.kind == "radio_split" and start is None:
            start = e.t
        elif e.kind == "radio_joined" and start is not None:
            spans.append(f"{start:.1f}-{e.t:.1f} s")
            start = None
    if start is not None:
        spans.append(f"from {start:.1f} s, still split at the end")
    more = len(spans) - MAX_SPANS
    return ", ".join(spans[:MAX_SPANS]) + (f", and {more} more" if more > 0 else "")


#: at most this many vehicle ids named in the obstacles line's flag (the metrics have them all)
MAX_BELOW = 6


def obstacle_lines(m: Metrics) -> list[str]:
    """With [[obstacle]]: the fleet's smallest clearance to an obstacle (who, from which, when,
    that obstacle's margin), the time obstacles deflected the fleet, and a flag naming the
    vehicles that came within their margin (inside: below 0), filter on or off: the metrics'
    ``obstacles`` block at a glance (docs/metrics.md)."""
    o = m.obstacles
    if o is None:
        return []
    rows = {v: r for v, r in o.vehicles.items() if r.get("min_clearance_m") is not None}
    head = f"  obstacles ({o.count}): "
    if not rows:
        return [head + "no vehicle shares a medium with them (boats see circles and polygons, drones "
                       "cylinders and boxes)"]
    vid, r = min(rows.items(), key=lambda kv: kv[1]["min_clearance_m"])
    deflected = sum(r2.get("deflected_s") or 0.0 for r2 in o.vehicles.values())
    line = (head + f"closest {printable(vid, 64)} {_fmt(r['min_clearance_m'], '.3f')} m from "
            f"{printable(str(r.get('obstacle')), 64)} at t = {_fmt(r.get('t'), '.2f', 'n/a')} s "
            f"(margin {_fmt(r.get('margin_m'), 'g', 'n/a')} m)")
    if m.safety.enabled:
        line += f", deflected {deflected:.2f} s (summed over the vehicles)"
    below = list(o.below_margin)
    if below:
        more = len(below) - MAX_BELOW
        who = ", ".join(printable(v, 64) for v in below[:MAX_BELOW]) + (f" and {more} more" if more > 0 else "")
        inside = any(rows.get(v, {}).get("min_clearance_m", 0.0) < 0.0 for v in below)
        line += (f"  [{'INSIDE AN OBSTACLE' if inside else 'BELOW THE MARGIN'}: {who}"
                 + ("]" if m.safety.enabled else "; the filter is off: obstacles are only measured]"))
    elif m.safety.enabled:
        line += " (every vehicle kept its margin)"
    return [line]


#: how the summary names a closest pair's domain (cdus.core.metrics.closest_pairs)
DOMAIN_WORDS = {"usv": "boats", "uav": "drones", "uav-usv": "drone to boat at the surface"}


def closest_lines(m: Metrics) -> list[str]:
    """One line per domain: the closest pair, its distance, when, who was not live, and a
    NEAR COLLISION flag below the safety radius (the [safety] table's, or its default when
    the scenario has none), whether the filter was on or off."""
    radius, enabled = m.safety.radius_m, m.safety.enabled
    out = []
    for domain, p in (m.closest_pairs or {}).items():
        gone = [v for v, live in ((p.a, p.a_live), (p.b, p.b_live)) if not live]
        who = ("both live" if not gone else
               f"{' and '.join(gone)} not live then (killed or paused: counted where it stopped)")
        line = (f"  closest approach ({DOMAIN_WORDS.get(domain, domain)}): {p.a} - {p.b} "
                f"{_fmt(p.distance_m, '.3f')} m at t = {p.t_s:.2f} s, {who}")
        if radius is not None and p.distance_m < radius:
            line += (f"  [NEAR COLLISION: below the safety radius {radius:g} m]" if enabled else
                     f"  [NEAR COLLISION: below the [safety] radius {radius:g} m; the filter is off]")
        elif radius is not None and enabled:
            line += f"  (the filter kept the {radius:g} m radius)"
        out.append(line)
    return out

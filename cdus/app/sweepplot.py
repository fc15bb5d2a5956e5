"""How is a sweep drawn? sweep.png (or .pdf, .svg): the coordination settle time and the
final error over the first grid key, one series per combination of the others, the keys in
words with their units.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Sequence

from cdus.app.stats import CI_SHORT
from cdus.app.sweepcells import CellSummary
from cdus.app.sweepstore import PLOT_FORMATS, canonical, cell_label
from cdus.wire.bounds import finite

#: how a grid key reads on an axis or in a legend: (words, unit or None); a key not here is
#: worded from its own parts (axis_label)
LABELS: dict[str, tuple[str, str | None]] = {
    "scenario.duration": ("Run duration", "s"),
    "rates.control": ("Control rate", "Hz"), "rates.broadcast": ("Broadcast rate", "Hz"),
    "rates.physics": ("Physics rate", "Hz"),
    "gains.k": ("Path gain k", None), "gains.c": ("Coordination gain c", None),
    "graph.topology": ("Graph topology", None), "graph.weight": ("Edge weight", None),
    "metrics.path_tol": ("Path tolerance", "m"), "metrics.coord_tol": ("Coordination tolerance", "rad"),
    "link.loss": ("Loss probability", None), "link.duplicate": ("Duplication probability", None),
    "link.delay.base": ("Link delay", "s"), "link.delay.jitter": ("Delay jitter", "s"),
    "link.burst": ("Burst loss (Gilbert-Elliott)", None), "link.burst.p": ("Burst onset probability p", None),
    "link.burst.r": ("Burst end probability r", None), "link.policy": ("Stale-neighbour policy", None),
    "link.timeout": ("Stale-neighbour timeout", "s"),
    "safety.radius": ("Safety radius R", "m"), "safety.range": ("Proximity sensor range", "m"),
    "safety.rate": ("Proximity sensor rate", "Hz"), "safety.latency": ("Proximity sensor latency", "s"),
    "safety.gamma": ("Safety filter rate γ", "1/s"), "supervision.backoff_s": ("Restart back-off", "s"),
    "radio.tx_power": ("Transmit power", "dBm"), "radio.sample_period": ("Geometry sample period", "s"),
    "radio.shadowing_sigma": ("Shadowing σ", "dB"), "radio.shadowing_distance": ("Shadowing distance", "m"),
    "radio.shadowing_time": ("Shadowing time", "s"), "radio.frequency": ("Carrier frequency", "Hz"),
    "radio.capacity": ("Channel bit rate", "bit/s"), "radio.noise_floor": ("Noise floor", "dBm"),
    "radio.noise_figure": ("Noise figure", "dB"), "radio.bandwidth": ("Noise bandwidth", "Hz"),
    "radio.relay_delay": ("Station relay delay", "s"), "radio.queue": ("Transmit queue", "messages"),
    "radio.exponent": ("Path-loss exponent", None), "radio.fading": ("Fading", None),
    "radio.modulation": ("Modulation", None), "radio.topology": ("Radio topology", None),
}
#: the unit of a key not in LABELS, by its last part (a vehicle's or a link's own setting)
SUFFIX_UNITS = {".loss": "fraction", ".duplicate": "fraction", ".bad_loss": "fraction", ".good_loss": "fraction",
                ".burst.p": "probability", ".burst.r": "probability", ".delay.base": "s", ".delay.jitter": "s",
                ".phase": "ω units"}
UNITLESS = ("fraction", "probability", "ω units")  # not written after a value


def unit_of(key: str) -> str | None:
    """A grid key's unit where known: ``s``, ``Hz``, ``fraction``..."""
    if key in LABELS:
        return LABELS[key][1]
    if key.startswith("rates."):
        return "Hz"
    return next((u for sfx, u in SUFFIX_UNITS.items() if key.endswith(sfx) or key == sfx[1:]), None)


def words_of(key: str) -> str:
    """A grid key in words: LABELS's, else its parts (``vehicle.usv1.gains.k`` -> ``Vehicle
    usv1 gains k``)."""
    if key in LABELS:
        return LABELS[key][0]
    text = " ".join(key.replace("_", " ").split("."))
    return text[:1].upper() + text[1:]


def axis_label(key: str) -> str:
    """A grid key as an axis label, in words with its unit: ``Link delay (s)``, ``Loss
    probability``; a key not in LABELS in its own words: ``Vehicle usv1 gains k``."""
    unit = unit_of(key)
    words = words_of(key)
    return f"{words} ({unit})" if unit else words


def value_label(key: str, value: Any) -> str:
    """A grid value in a legend or a title, in words with its physical unit: ``Link delay =
    0.2 s``, ``Control rate = 20 Hz``, ``Loss probability = 0.2`` (a fraction needs none)."""
    unit = unit_of(key)
    text = f"{words_of(key)} = {cell_label(value)}"
    return f"{text} {unit}" if unit and unit not in UNITLESS else text


DODGE_STEP = 0.1  # series at one x are drawn this fraction of the x spacing apart...
DODGE_SPREAD = 0.4  # ...and all of them within this fraction


def dodge_offsets(n: int, positions: Sequence[float]) -> list[float]:
    """How far in x each of ``n`` series is moved so that points of different series at one x
    (and their error bars) do not hide each other: centred on the x, ``DODGE_STEP`` of the
    smallest spacing of ``positions`` apart (closer with many series: within
    ``DODGE_SPREAD``). One series is not moved."""
    if n < 2:
        return [0.0] * n
    xs = sorted(set(positions))
    gaps = [b - a for a, b in zip(xs, xs[1:]) if b > a]
    gap = min(gaps) if gaps else (abs(xs[0]) or 1.0) if xs else 1.0
    step = min(DODGE_STEP, DODGE_SPREAD / (n - 1)) * gap
    return [(i - (n - 1) / 2) * step for i in range(n)]


LOG_DECADES_ONLY = 3.0  # a log axis spanning this many decades or more is labelled at the decades only


def plain_log_axis(ax: Any) -> None:
    """``ax``'s log y axis as a paper has it: major ticks at the decades (at 1, 2 and 5 times
    them when the data spans fewer than LOG_DECADES_ONLY decades), labelled as plain numbers
    (``0.01``, ``0.2``; powers of ten beyond 1e-3 .. 1e4); minor ticks unlabelled (matplotlib
    labelled them ``6×10⁻²``, ``4×10⁻²``... over less than a decade or two)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    lo, hi = sorted(ax.get_ylim())
    span = math.log10(hi / lo) if lo > 0 and hi > 0 else 0.0
    axis = ax.yaxis
    axis.set_major_locator(LogLocator(base=10, subs=(1.0,) if span >= LOG_DECADES_ONLY else (1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(lambda y, _: plain_number(y)))
    axis.set_minor_formatter(NullFormatter())


def plain_number(y: float) -> str:
    """A tick value: ``0.02``, ``0.25``, ``5``, ``100``; a power of ten outside 1e-3 .. 1e4 as
    ``10^k``. Every digit the tick has (to 6), none of a float's rounding (0.1 + 0.2 is ``0.3``):
    a log axis within a decade is ticked every 0.05 by matplotlib, and one digit read 0.25 as 0.2."""
    if y <= 0 or not math.isfinite(y):
        return ""
    k = math.floor(math.log10(y) + 1e-9)
    mantissa = y / 10 ** k
    if -3 <= k <= 4:
        return f"{y:.6g}"
    return f"$10^{{{k}}}$" if abs(mantissa - 1) < 1e-6 else f"${mantissa:.6g}\\times10^{{{k}}}$"


# no creation date in a vector file (and an SVG's ids from a fixed salt): the same rows give the same file
_NO_DATE = {"pdf": {"CreationDate": None}, "svg": {"Date": None}}


def plot(keys: list[str], cells: list[CellSummary], path: Path, title: str = "") -> dict[str, Any]:
    """Coordination settle time and final coordination error over the first grid key, one
    line per combination of the other keys: the mean over the seeds with its 95 % bootstrap
    interval as error bars; a cell whose runs did not all settle gets a marker at the top
    with the count; a panel with nothing to show says so. Keys are worded (LABELS), series
    are moved apart in x (:func:`dodge_offsets`), the log axis has plain decades
    (:func:`plain_log_axis`). ``path``'s extension is the format (PLOT_FORMATS: png, or pdf
    and svg, vector). Returns what it drew besides the lines: ``{"empty": [the texts of empty
    panels], "never": [the labels of the markers], "offsets": {series: its x offset}}``."""
    from matplotlib import rc_context
    from matplotlib.figure import Figure  # no pyplot: a notebook's backend and figures are left alone
    from matplotlib.transforms import blended_transform_factory

    fig = Figure(figsize=(12, 4.6))
    axes = fig.subplots(1, 2)
    x_key, others = (keys[0], keys[1:]) if keys else (None, [])
    fixed = [k for k in others if len({canonical(dict(c.cell)[k]) for c in cells if c.runs}) == 1]
    if fixed:  # keys with one value go in the title, not in every legend entry
        first = dict(next((c for c in cells if c.runs), cells[0]).cell)
        title = ", ".join([title] * bool(title) + [value_label(k, first[k]) for k in fixed])
        others = [k for k in others if k not in fixed]
    series: dict[tuple, list[CellSummary]] = {}
    for c in cells:
        if c.runs:
            values = dict(c.cell)
            series.setdefault(tuple(value_label(k, values[k]) for k in others), []).append(c)
    xs_all = [dict(c.cell)[x_key] if x_key else "all runs" for c in cells if c.runs]
    # an inf value (radio.shadowing_distance = inf) has no place on a numeric axis: the values as categories
    numeric = all(finite(x) for x in xs_all)
    categories = list(dict.fromkeys(canonical(x) for x in xs_all))

    def pos(x: Any) -> float:
        return float(x) if numeric else float(categories.index(canonical(x)))

    panels = (("coord_settle_s", "Coordination settle time (s)", "no run settled"),
              ("final_coord_error_max", "Final coordination error, worst edge (rad)", "no run finished"))
    shown = [False, False]
    drawn: dict[str, Any] = {"empty": [], "never": [], "offsets": {}}
    labels: list[Any] = []  # the "k/n never" texts, kept apart once the layout is final
    n_series = max(1, len(series))
    offsets = dodge_offsets(len(series), [pos(x) for x in xs_all])
    for si, (label, group) in enumerate(series.items()):
        group = sorted(group, key=lambda c: pos(dict(c.cell)[x_key]) if x_key else 0.0)
        xs = [(pos(dict(c.cell)[x_key]) if x_key else 0.0) + offsets[si] for c in group]
        name = ", ".join(label) or None
        drawn["offsets"][name] = offsets[si]
        for ai, (ax, (fld, _, _)) in enumerate(zip(axes, panels)):
            means = [c.stats[fld].mean if c.stats[fld].n else math.nan for c in group]
            lo = [m - c.stats[fld].lo if c.stats[fld].n else 0.0 for m, c in zip(means, group)]
            hi = [c.stats[fld].hi - m if c.stats[fld].n else 0.0 for m, c in zip(means, group)]
            if any(not math.isnan(m) for m in means):
                shown[ai] = True
            line = ax.errorbar(xs, means, yerr=[lo, hi], marker="o", capsize=3, label=name)
            if fld == "coord_settle_s":  # runs that never settled: a marker at the top, with the count
                trans = blended_transform_factory(ax.transData, ax.transAxes)
                for x, c in zip(xs, group):
                    if c.never("coord"):
                        y = 0.96 - 0.05 * (si % 4)
                        ax.plot([x], [y], marker="v", ls="none", color=line[0].get_color(), transform=trans,
                                markersize=8, clip_on=False)
                        text = f"{c.never('coord')}/{c.ok} never"
                        labels.append(ax.text(x, y - 0.045, text, transform=trans, ha="center", va="top",
                                              fontsize=7, color=line[0].get_color(), zorder=5,
                                              bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none",
                                                    "alpha": 0.85}))  # readable over another series' bars
                        drawn["never"].append(text)
    for ax, ok, (_, ylabel, empty) in zip(axes, shown, panels):
        ax.set_ylabel(ylabel)
        ax.set_xlabel(axis_label(x_key) if x_key else "")
        ax.grid(True, alpha=0.3)
        ax.margins(x=0.1)
        if not numeric:
            ax.set_xticks(range(len(categories)), [str(cell_label(json.loads(c))) for c in categories],
                          fontsize=8, rotation=15 if max(map(len, categories), default=0) > 12 else 0)
        if not ok:
            ax.set_yticks([])  # no values: no scale (matplotlib's default one runs through negative times)
            ax.text(0.5, 0.5, empty, transform=ax.transAxes, ha="center", va="center", fontsize=13, color="0.4")
            drawn["empty"].append(empty)
    legend_rows = 0
    if any(shown) and (n_series > 1 or others):  # one legend for both panels, under them: it hides no point
        handles, names = axes[shown.index(True)].get_legend_handles_labels()
        ncol = min(len(names), 3)
        legend_rows = math.ceil(len(names) / ncol)
        fig.legend(handles, names, loc="lower center", ncol=ncol, fontsize=8, frameon=False)
    if not numeric and x_key:  # the ticks at the categories themselves, not at the dodged points
        for ax in axes:
            ax.set_xlim(-0.5, len(categories) - 0.5)
    if shown[1]:
        axes[1].set_yscale("log")
        plain_log_axis(axes[1])
    axes[0].set_title("Coordination settle time (▼: runs that never settled)", fontsize=10)
    axes[1].set_title("Final coordination error", fontsize=10)
    apart = "; series moved apart in x a little" if len(series) > 1 else ""
    fig.suptitle((title + "\n" if title else "") + f"points: mean over seeds; error bars: {CI_SHORT}{apart}",
                 fontsize=10)
    fig.tight_layout(rect=(0, (0.1 + 0.22 * legend_rows) / fig.get_figheight() if legend_rows else 0, 1, 1))
    _separate(fig, labels)
    fmt = path.suffix.lstrip(".").lower()
    with rc_context({"svg.hashsalt": "cdus"}):  # an SVG's ids from a fixed salt, not a random one
        fig.savefig(path, dpi=110, format=fmt if fmt in PLOT_FORMATS else None, metadata=_NO_DATE.get(fmt))
    return drawn


def _separate(fig: Any, labels: list[Any], step: float = 0.04, rows: int = 6) -> None:
    """Move each label down a row (``step`` in axes units) while it overlaps one placed before:
    neighbouring cells' "2/2 never" ran into each other on one row."""
    if len(labels) < 2:
        return
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    placed: list[Any] = []
    for t in sorted(labels, key=lambda t: t.get_position()[0]):
        x, y = t.get_position()
        for _ in range(rows):
            box = t.get_window_extent(renderer)
            if not any(box.overlaps(b) for b in placed):
                break
            y -= step
            t.set_position((x, y))
        placed.append(t.get_window_extent(renderer))

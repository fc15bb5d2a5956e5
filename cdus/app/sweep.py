"""The experiment runner: a grid of config overrides × seeds, on any executor, streamed to
disk, resumable, to a table, a summary with confidence intervals and a plot.

    cdus sweep configs/lake_circle.toml --set link.loss=0,0.2,0.4 --set link.delay.base=0,0.1 \\
        --seeds 3 --out runs/loss_sweep [--jobs J | --executor dask | --cluster tcp://127.0.0.1:8786]

Each run is `cdus sim`'s in-process fleet (or a `cdus launch --clock lockstep` fleet) of the
scenario resolved on the driver with the cell's overrides and the seed; the resolved
:class:`~cdus.scenario.model.Scenario` is what goes to the worker, so a worker needs only the
package, never the config file. A run that fails (a bad value, a diverged fleet, a crash) is
recorded as failed with its reason and the sweep goes on.

In ``out``: ``manifest.json`` (which sweep this is), ``results.jsonl`` (one row per finished
run, appended as it comes), and, written at the end from those rows, ``results.csv`` and
``results.parquet`` (one row per run in plan order: the grid values as typed columns, the
seed, the status, the metrics JSON's fields), ``summary.md`` (per cell: mean, standard
deviation and a 95 % bootstrap interval of the mean, how many settled) and ``sweep.png`` (or
``sweep.pdf``, ``sweep.svg``: ``--plot-format``).
Running the same sweep again with the same ``out`` runs only the (cell, seed) pairs not done
yet (cdus.app.sweepstore has the file formats).
"""

from __future__ import annotations

import itertools
import json
import math
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
import traceback
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence, TextIO

from tqdm import tqdm

from cdus.app.executors import CONNECT_TIMEOUT_S, make_executor
from cdus.app.stats import CI_SHORT, CI_WORDS, Stat, describe, fmt_duration, fmt_number, fmt_seconds, fmt_stat
from cdus.app.sweepstore import (
    CSV, FIELDS, PARQUET, ROWS, Manifest, RowLog, canonical, cell_label, check_out, grid_type, read_rows,
    scan_rows, write_manifest, write_tables,
)
from cdus.files import write_json
from cdus.scenario.config import ConfigError, load_scenario, parse_scenario, parse_value
from cdus.scenario.model import Scenario
from cdus.sim.fleet import InProcessFleet
from cdus.wire.bounds import finite
from cdus.wire.text import printable

__all__ = ["sweep", "SweepResult", "SweepInterrupted", "parse_grid", "check_grid", "plan", "Run", "FIELDS",
           "RUNNERS", "PLOT_FORMATS", "cell_label"]

#: how a run is run: in this process (`cdus sim`) or as a launched fleet (`cdus launch --clock lockstep`);
#: not a clock (cdus.core.vocabulary.CLOCKS: who drives time in a fleet of processes)
RUNNERS = ("inproc", "lockstep")
MAX_SEED = 2 ** 63  # a seed is an int64 column of the table
MAX_RUNS = 10_000_000  # cells × seeds of one sweep (its plan is held as lists of cells and seeds)
Grid = list[tuple[str, list[Any]]]


@dataclass(frozen=True)
class Run:
    cell: tuple[tuple[str, Any], ...]  # (key, value) pairs of the grid
    seed: int


def parse_grid(items: Sequence[str]) -> Grid:
    """``["link.loss=0,0.1", "rates.control=20,50"]`` -> [(key, [values...]), ...].

    Values are split on commas outside brackets, so ``k=[1,2],[3,4]`` gives two lists.
    """
    grid = []
    for item in items:
        key, sep, rest = item.partition("=")
        key = key.strip()
        if not sep or not key or not rest.strip():
            raise ConfigError("command line", [("--set", f"expected KEY=V1,V2,... (e.g. link.loss=0,0.1,0.3), "
                                                         f"got {item!r}")])
        values, depth, cur = [], 0, ""
        for ch in rest:
            if ch in "[{":
                depth += 1
            elif ch in "]}":
                depth -= 1
            if ch == "," and depth == 0:
                values.append(cur)
                cur = ""
            else:
                cur += ch
        values.append(cur)
        grid.append((key, [parse_value(v.strip()) for v in values if v.strip() != ""]))
    return grid


def normalize_grid(grid: Mapping[str, Sequence[Any]] | Sequence[tuple[str, Sequence[Any]]] | None) -> Grid:
    """A grid as a mapping ``{key: [values]}`` or pairs ``[(key, [values])]``, checked: each
    key once, each with at least one value, each value once."""
    pairs = list(grid.items()) if isinstance(grid, Mapping) else list(grid or [])
    out: Grid = []
    problems = []
    for item in pairs:
        if not (isinstance(item, (tuple, list)) and len(item) == 2 and isinstance(item[0], str)):
            problems.append(("grid", f"expected (key, [values]) pairs, got {item!r}"))
            continue
        key, values = item
        if hasattr(values, "tolist") and not isinstance(values, (str, bytes)):  # a numpy array: np.linspace(...)
            values = values.tolist()
        values = [values] if isinstance(values, (str, bytes, dict)) or not isinstance(values, Sequence) \
            else [_plain(v) for v in values]
        if not values:
            problems.append((key, "no values"))
        elif len({canonical(v) for v in values}) != len(values):
            problems.append((key, "a value is given twice"))
        if key in (k for k, _ in out):
            problems.append((key, "given twice"))
        if key == "scenario.seed":
            problems.append((key, "is what --seeds (seeds=) sets for every cell; give the seeds there"))
        out.append((key, values))
    if problems:
        raise ConfigError("grid", problems)
    return out


def _plain(value: Any) -> Any:
    """A numpy scalar as the Python number it holds (np.float64(0.1) -> 0.1)."""
    return value.item() if type(value).__module__ == "numpy" and hasattr(value, "item") else value


def check_grid(config: str | os.PathLike | Scenario, grid: Grid, base: Mapping[str, Any] | None = None) -> None:
    """Validate every cell of the grid, values together (``link.burst.p`` needs
    ``link.burst.r``), before any run: a typo should not cost a sweep. ``config``: a file or
    a Scenario (its data). Raises ConfigError naming the key."""
    for run in plan(grid, [0]):
        over = {**(base or {}), **dict(run.cell)}
        if isinstance(config, Scenario):
            parse_scenario(config.raw, str(config.source), over)
        else:
            load_scenario(config, over)


def plan(grid: Grid, seeds: Sequence[int]) -> list[Run]:
    """Every (cell, seed), cells in the grid's order (the last key fastest), seeds innermost."""
    p = _Plan(grid, seeds)
    return [p.run(j) for j in range(p.size)]


class _Plan:
    """The runs of a sweep, indexed 0 .. size-1 without listing them (cells × seeds)."""

    def __init__(self, grid: Grid, seeds: Sequence[int]):
        self.keys = [k for k, _ in grid]
        self.cells = list(itertools.product(*[vals for _, vals in grid])) if grid else [()]
        self.seeds = list(seeds)
        self.size = len(self.cells) * len(self.seeds)
        self._cell_index = {canonical(list(c)): i for i, c in enumerate(self.cells)}
        self._seed_index = {s: i for i, s in enumerate(self.seeds)}

    def run(self, j: int) -> Run:
        c, s = divmod(j, len(self.seeds))
        return Run(tuple(zip(self.keys, self.cells[c])), self.seeds[s])

    def index_of(self, cell: dict, seed: int) -> int | None:
        """The plan index of a row's (cell, seed); None if this plan has no such run."""
        if set(cell) != set(self.keys):
            return None
        c = self._cell_index.get(canonical([cell[k] for k in self.keys]))
        s = self._seed_index.get(seed)
        return None if c is None or s is None else c * len(self.seeds) + s


# --- one run (on a worker) ---------------------------------------------------------------

def _flatten(metrics: dict) -> dict:
    link = metrics.get("link") or {}
    rates = [v for v in (metrics.get("omega_rate_final") or {}).values() if v is not None]
    row = {k: metrics.get(k) for k in FIELDS if k in metrics}
    row["omega_rate_mean"] = statistics.mean(rates) if rates else None
    row["omega_rate_final"] = json.dumps(metrics.get("omega_rate_final") or {})
    row["live_final"] = " ".join(metrics.get("live_final") or [])
    for k in ("sent", "delivered", "dropped", "rejected", "latency_ms_p50", "latency_ms_p99"):
        row[f"link_{k}"] = link.get(k)
    return row


def run_task(scenario: Scenario, clock: str) -> dict:
    """One run of a resolved scenario (what a worker executes); never raises: a failure
    comes back as status "failed" with its reason."""
    try:
        if clock == "inproc":
            metrics = InProcessFleet(scenario, clock=time.perf_counter).run().metrics
        else:
            metrics = _run_lockstep(scenario)
        status, reason = "ok", ""
        if metrics.get("final_path_error_max") is None or not math.isfinite(metrics["final_path_error_max"]):
            status, reason = "failed", "the fleet diverged (non-finite path error)"
        return {"status": status, "reason": reason, **_flatten(metrics)}
    except ConfigError as e:
        return {"status": "failed", "reason": f"config: {e}".replace("\n", "; ")}
    except Exception as e:  # a crash in one cell must not end the sweep
        return {"status": "failed", "reason": traceback.format_exception_only(type(e), e)[-1].strip()}


def _run_lockstep(scenario: Scenario) -> dict:
    """A `cdus launch --clock lockstep` fleet of the resolved scenario (its data as JSON)."""
    with tempfile.TemporaryDirectory(prefix="cdus-sweep-") as tmp:
        config = Path(tmp) / "scenario.json"
        write_json(config, scenario.raw, allow_inf=True)
        logs = Path(tmp) / "run"
        args = [sys.executable, "-m", "cdus.app.cli", "launch", str(config), "--clock", "lockstep", "-q",
                "--rerun", "off", "--fleet", "sweep" + uuid.uuid4().hex[:8], "--logs", str(logs)]
        with subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              start_new_session=True) as proc:
            try:
                out, err = proc.communicate()
            except BaseException:  # Ctrl-C (or SIGTERM) of the sweep: the fleet stops before its directory goes
                _stop_launcher(proc)
                raise
        path = logs / "metrics.json"
        if proc.returncode != 0 or not path.exists():
            tail = (err or out).strip().splitlines()[-3:]
            raise RuntimeError(f"launch exited with {proc.returncode}: {' / '.join(tail)}")
        return json.loads(path.read_text())


LAUNCHER_STOP_S = 20.0  # how long a stopping launcher may take to stop its fleet before it is killed


def _stop_launcher(proc: subprocess.Popen) -> None:
    """Stop a launched fleet as Ctrl-C would (SIGINT to the launcher's session: it stops the
    world and the vehicles and waits for them), then kill what is left of the session."""
    import signal

    for sig, wait in ((signal.SIGINT, LAUNCHER_STOP_S), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            proc.communicate(timeout=wait)
            break
        except subprocess.TimeoutExpired:
            continue


# --- statistics of the cells ---------------------------------------------------------------

STAT_FIELDS = ("coord_settle_s", "final_coord_error_max", "path_settle_s", "final_path_error_max")
MAX_LISTED_FAILURES = 50


@dataclass
class CellSummary:
    """A cell's runs in the table: how many, how many ok, and the statistics of each of
    :data:`STAT_FIELDS` over the ok runs (settle times over the runs that settled)."""
    cell: tuple[tuple[str, Any], ...]
    runs: int = 0
    ok: int = 0
    values: dict[str, list[float]] = field(default_factory=lambda: {f: [] for f in STAT_FIELDS})
    stats: dict[str, Stat] = field(default_factory=dict)

    def settled(self, what: str = "coord") -> int:
        return len(self.values[f"{what}_settle_s"]) if not self.stats else self.stats[f"{what}_settle_s"].n

    def never(self, what: str = "coord") -> int:
        """Ok runs that never settled."""
        return self.ok - self.settled(what)

    def finish(self, seed: int) -> None:
        self.stats = {f: describe(v, seed=seed) for f, v in self.values.items()}
        self.values = {f: [] for f in STAT_FIELDS}  # the stats are kept, not the values


class _Tally:
    """Per-cell statistics gathered while the table is written (one pass over the rows)."""

    def __init__(self, p: _Plan):
        self.plan = p
        self.cells = [CellSummary(tuple(zip(p.keys, c))) for c in p.cells]
        self.failures: list[tuple[Run, str]] = []
        self.failed = 0

    def feed(self, rows: Iterator[tuple[int, dict]]) -> Iterator[dict]:
        for j, row in rows:
            c = self.cells[j // len(self.plan.seeds)]
            c.runs += 1
            if row.get("status") == "ok":
                c.ok += 1
                for f in STAT_FIELDS:
                    v = row.get(f)
                    if finite(v):
                        c.values[f].append(float(v))
            else:
                self.failed += 1
                if len(self.failures) < MAX_LISTED_FAILURES:
                    self.failures.append((self.plan.run(j), printable(str(row.get("reason") or ""), 1000)))
            yield row

    def finish(self) -> list[CellSummary]:
        for i, c in enumerate(self.cells):
            c.finish(seed=i)
        return self.cells


def summarize(keys: list[str], cells: list[CellSummary]) -> str:
    """Markdown: per cell, runs ok, how many settled, mean ± sd [95 % CI] of the settle times
    and final errors."""
    head = keys + ["runs ok", "coord settled", "coord settle s", "final coord error rad", "path settled",
                   "path settle s", "final path error m"]
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in cells:
        if c.runs == 0:
            continue
        st = c.stats
        out.append("| " + " | ".join([
            *(str(cell_label(v)) for _, v in c.cell), f"{c.ok}/{c.runs}",
            f"{st['coord_settle_s'].n}/{c.ok}", fmt_stat(st["coord_settle_s"], 1, c.never("coord")),
            fmt_stat(st["final_coord_error_max"], 4),
            f"{st['path_settle_s'].n}/{c.ok}", fmt_stat(st["path_settle_s"], 1, c.never("path")),
            fmt_stat(st["final_path_error_max"], 3)]) + " |")
    return "\n".join(out) + "\n"


def explain() -> str:
    return (f"Each cell: mean ± standard deviation [{CI_WORDS}] over its runs that finished (runs ok). Settle "
            f"times are over the runs that settled (the settled columns: of the runs ok); \"(k never)\" counts "
            f"the runs ok that never settled within the run. Errors are the worst over the vehicles (path, m) "
            f"or the edges (coordination, rad) at the end of the run.\n")


# --- the plot ----------------------------------------------------------------------------------

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


PLOT_FORMATS = ("png", "pdf", "svg")  # --plot-format: sweep.png, or a vector file for a paper
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


# --- the engine -------------------------------------------------------------------------------

@dataclass
class SweepResult:
    """What a sweep did and where its table is. ``rows()`` and ``table()`` read the files
    (nothing of the runs is held in memory)."""
    out: Path
    planned: int  # (cell, seed) pairs of the plan
    done: int  # rows in the table (done now or before)
    ran: int  # runs finished by this call
    resumed: int  # pairs already done in ``out`` before this call (skipped)
    failed: int  # rows of the table with status "failed"
    torn: int  # a torn last line of results.jsonl found at the start (ignored; its run ran again)
    unreadable: int  # whole lines of results.jsonl that are not a row of this sweep (ignored)
    lost: int  # runs the executor lost (a worker killed, the cluster gone): not recorded, run again to retry
    wall_s: float
    executor: str
    interrupted: bool = False
    cells: list[CellSummary] = field(default_factory=list)
    grid: Grid = field(default_factory=list)  # the grid as checked: [(key, [values...]), ...]
    seeds: tuple[int, ...] = ()  # the plan's seeds, in order
    plot_format: str = "png"  # the plot's file: sweep.png, sweep.pdf or sweep.svg

    @property
    def csv(self) -> Path:
        return self.out / CSV

    @property
    def parquet(self) -> Path:
        return self.out / PARQUET

    @property
    def summary(self) -> Path:
        return self.out / "summary.md"

    @property
    def plot(self) -> Path:
        return self.out / f"sweep.{self.plot_format}"

    def __len__(self) -> int:
        return self.done

    def __iter__(self) -> Iterator[dict]:
        """The rows of the table (as ``rows()``), so ``list(result)`` and
        ``pandas.DataFrame(result)`` work too."""
        return iter(self.rows())

    def rows(self) -> list[dict]:
        """The table as a list of dicts (the grid values under their keys, typed), plan order."""
        import pyarrow.parquet as pq

        return pq.read_table(self.parquet).to_pylist()

    def table(self) -> Any:
        """The table as a pandas DataFrame (needs pandas)."""
        import pyarrow.parquet as pq

        return pq.read_table(self.parquet).to_pandas()


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep: the rows done are on disk (and in the tables); ``result`` says
    how far it got and the message how to resume."""

    def __init__(self, result: SweepResult, message: str):
        super().__init__(message)
        self.result = result
        self.message = message


def run_text(run: Run, res: dict) -> str:
    """One finished run for the progress line: ``link.loss=0.3, seed 2: coord settle 141.4 s``."""
    if res.get("status") != "ok":
        return f"{cell_text(run)}: FAILED: {res.get('reason')}"
    err = res.get("final_coord_error_max")
    return (f"{cell_text(run)}: coord settle {fmt_seconds(res.get('coord_settle_s'))}, final edge error "
            f"{fmt_number(err, 4)} rad")


def base_scenario(scenario: str | os.PathLike | Scenario, overrides: Mapping[str, Any] | None,
                  duration: float | None) -> Scenario:
    """The scenario every run starts from: the file (or the Scenario's data) with the fixed
    overrides and the duration applied, validated once. Raises ConfigError."""
    over = dict(overrides or {})
    if duration is not None:
        over["scenario.duration"] = duration
    if isinstance(scenario, Scenario):
        return parse_scenario(scenario.raw, scenario.source, over) if over else scenario
    return load_scenario(scenario, over)


def sweep(scenario: str | os.PathLike | Scenario,
          grid: Mapping[str, Sequence[Any]] | Sequence[tuple[str, Sequence[Any]]] | None,
          seeds: int | Sequence[int], out: str | os.PathLike, *,
          overrides: Mapping[str, Any] | None = None, clock: str = "inproc", executor: str = "local",
          cluster: str | None = None, jobs: int | None = None, duration: float | None = None, quiet: bool = False,
          connect_timeout: float = CONNECT_TIMEOUT_S, stream: TextIO | None = None,
          plot_format: str = "png") -> SweepResult:
    """Run every (cell, seed) of ``grid`` × ``seeds`` not already done in ``out``; return
    what was done and where the table is.

    ``scenario``: a scenario file path, or a :class:`Scenario` (its ``raw`` data is used).
    ``grid``: ``{"link.loss": [0, 0.2], ...}`` or ``[("link.loss", [0, 0.2]), ...]`` (dotted
    config keys, as ``--set``); every combination is a cell. ``seeds``: a count N (the
    scenario's seed and the next N-1) or the seeds themselves. ``overrides``: fixed config
    values of every run; ``duration``: simulated seconds of every run.
    ``clock``: ``"inproc"`` (`cdus sim`'s fleet in the worker) or ``"lockstep"`` (a launched
    fleet per run). ``executor``: ``"local"`` (``jobs`` processes of this machine, default
    the number of cores, 1 for lockstep; ``jobs=1`` runs in this process) or ``"dask"`` (a LocalCluster of
    ``jobs`` processes on 127.0.0.1); ``cluster``: the address of a running Dask scheduler
    (e.g. ``"tcp://127.0.0.1:8786"``), overrides ``executor``. ``quiet``: no progress bar
    (else a tqdm bar with an ETA on ``stream``, default stderr). ``plot_format``: the plot's
    file, ``sweep.png``, ``sweep.pdf`` or ``sweep.svg`` (PLOT_FORMATS; the last two vector).

    Every cell is validated before any run (a ConfigError names the key, nothing is run);
    every run is resolved here and the worker gets the resolved Scenario. Each finished run is appended
    to ``out/results.jsonl`` at once; at the end ``results.csv``, ``results.parquet``,
    ``summary.md`` and ``sweep.png`` are written from that file. ``out`` must be new, empty
    of sweeps, or hold this same sweep (same resolved config, grid and clock; the seeds may
    differ): then only the missing pairs run.

    Raises ConfigError (nothing run, nothing written) for a bad config, grid, ``out`` of
    another sweep or an unreachable cluster; :class:`SweepInterrupted` (a KeyboardInterrupt)
    on Ctrl-C, after writing the tables of the rows done.
    """
    start = time.perf_counter()
    if getattr(multiprocessing.current_process(), "_inheriting", False):  # as multiprocessing's own check
        raise RuntimeError("a sweep was started while a worker process of a sweep was importing the main script "
                           "(local workers are spawned: they import it): put the call under "
                           "`if __name__ == \"__main__\":` (docs/api.md)")
    if clock not in RUNNERS:
        raise ConfigError("command line", [("--clock", f"expected one of {', '.join(RUNNERS)}, got {clock!r}")])
    if plot_format not in PLOT_FORMATS:
        raise ConfigError("command line", [("--plot-format", f"expected one of {', '.join(PLOT_FORMATS)}, got "
                                                             f"{printable(repr(plot_format), 40)}")])
    g = normalize_grid(grid)
    n_cells = math.prod(len(v) for _, v in g)
    n_seeds = seeds if isinstance(seeds, int) and not isinstance(seeds, bool) else None
    if n_cells * (n_seeds or 1) > MAX_RUNS:  # the plan's cells and seeds are lists: bound them before making them
        raise ConfigError("command line", [("--seeds", f"{n_cells} cells × {n_seeds or 1} seeds is more than "
                                                       f"{MAX_RUNS:,} runs; split the sweep")])
    base = base_scenario(scenario, overrides, duration)
    check_grid(base, g)  # every cell before any run: nothing run, nothing written
    if n_seeds is not None:
        if seeds < 1 or base.seed + seeds > MAX_SEED:
            raise ConfigError("command line", [("--seeds", f"must be at least 1 (and the last seed below 2**63), "
                                                           f"got {seeds}")])
        seed_list = list(range(base.seed, base.seed + seeds))
    else:
        seed_list = [_plain(s) for s in seeds]
        if not seed_list or any(type(s) is not int or not 0 <= s < MAX_SEED for s in seed_list) or \
                len(set(seed_list)) != len(seed_list):
            raise ConfigError("command line", [("seeds", f"expected distinct integers in [0, 2**63), got "
                                                         f"{printable(repr(seed_list), 200)}")])
    out = Path(out)
    manifest = Manifest.of(str(base.source), base.raw, g, clock)
    check_out(out, manifest)
    p = _Plan(g, seed_list)
    rows_path = out / ROWS
    if jobs is None and clock == "lockstep" and executor == "local" and cluster is None:
        jobs = 1  # a launched fleet is already a process per vehicle
    ex = make_executor(executor, cluster, jobs, connect_timeout)  # an unreachable cluster: nothing written yet
    if getattr(ex, "workers", None) == 0:
        print(f"warning: the Dask scheduler at {printable(str(cluster), 200)} has no workers: the runs wait until one "
              f"joins (start one with `dask worker {printable(str(cluster), 200)}`; Ctrl-C stops the sweep)",
              file=stream or sys.stderr, flush=True)
    try:
        try:
            out.mkdir(parents=True, exist_ok=True)
            log = RowLog(rows_path)  # locked: what the file holds now is all another sweep will have written
        except OSError as e:  # a file, a dangling link, a read-only or full file system
            raise ConfigError("--out", [(str(out), f"cannot hold the results ({e.strerror or e}); give a "
                                                   f"directory this user can write")]) from None
        try:
            check_out(out, manifest)  # again under the lock: another sweep may have started it meanwhile
        except BaseException:
            log.close()
            raise
    except BaseException:
        ex.close()
        raise
    try:
        with ex:
            before = scan_rows(rows_path, p.index_of)
            log.cut(before.end)
            write_manifest(out, manifest)
            write_json(out / "scenario.json", base.raw, allow_inf=True)  # what every run started from, overrides applied
            ran, lost, interrupted = _run_all(p, base, clock, ex, log, before, quiet, stream or sys.stderr, out)
        result = _finish(out, base, g, p, clock, ex.describe(), before, ran, lost, interrupted,
                         time.perf_counter() - start, plot_format)
    finally:
        log.close()
    if interrupted:
        left = result.planned - result.done
        raise SweepInterrupted(result, f"interrupted: {result.done} of {result.planned} runs done and kept in "
                                       f"{out / ROWS}; {left} left. Run the same command again (same --out) to "
                                       f"run only those.")
    return result


def cell_text(run: Run) -> str:
    """``link.loss=0.3, seed 2``."""
    return (", ".join(f"{k}={cell_label(v)}" for k, v in run.cell) or "(base)") + f", seed {run.seed}"


def _run_all(p: _Plan, base: Scenario, clock: str, ex: Any, log: RowLog, before: Any, quiet: bool, say: TextIO,
             out: Path) -> tuple[int, int, bool]:
    """Resolve, submit (a bounded window in flight), record each result as it comes:
    (runs recorded, runs lost by the executor, interrupted)."""
    resumed = len(before.offsets)
    ran = lost = failed_now = 0
    bar = tqdm(total=p.size, initial=resumed, unit="run", file=say, disable=quiet, dynamic_ncols=True,
               smoothing=0.05, mininterval=0.5 if say.isatty() else 10.0, desc="sweep")
    notes = [f"{resumed} of {p.size} runs already done in {out}: running the other {p.size - resumed}"
             if resumed else "", f"{before.torn} torn last line of {ROWS} ignored (its run runs again)"
             if before.torn else "", f"{before.unreadable} unreadable lines of {ROWS} ignored"
             if before.unreadable else ""]
    for n in filter(None, notes):
        if not quiet:
            bar.write(n, file=say)
    pending: dict[Any, int] = {}
    todo = (j for j in range(p.size) if j not in before.offsets)

    def record(j: int, res: dict) -> None:
        nonlocal ran, failed_now
        run = p.run(j)
        log.append({"cell": dict(run.cell), "seed": run.seed, **res})
        ran += 1
        if res.get("status") != "ok":
            failed_now += 1
            if failed_now <= 10 and not quiet:
                bar.write(run_text(run, res), file=say)
        bar.update(1)
        if not quiet:
            bar.set_postfix_str(run_text(run, res)[:70], refresh=False)

    try:
        exhausted = False
        while True:
            while not exhausted and len(pending) < ex.slots:
                j = next(todo, None)
                if j is None:
                    exhausted = True
                    break
                run = p.run(j)
                try:
                    resolved = parse_scenario(base.raw, str(base.source), {**dict(run.cell), "scenario.seed": run.seed})
                except ConfigError as e:
                    record(j, {"status": "failed", "reason": f"config: {e}".replace("\n", "; ")})
                    continue
                try:
                    fut = ex.submit(run_task, resolved, clock)
                except Exception as e:  # a broken executor: nothing more is sent, what is in flight comes back lost
                    lost += 1
                    exhausted = True
                    if not quiet:
                        bar.write(f"the executor failed ({type(e).__name__}: {printable(str(e), 200)}): no more "
                                  f"runs sent; the same command again runs what is missing", file=say)
                    break
                pending[fut] = j
            if not pending:
                break
            try:
                finished, _ = ex.wait(set(pending))
            except Exception as e:  # the cluster is gone (the scheduler stopped: FuturesCancelledError)
                lost += _broken(ex, pending, e, quiet, bar, say)
                return ran, lost, False
            for f in finished:
                j = pending.pop(f)
                try:
                    res = ex.result(f)
                    if not isinstance(res, dict) or res.get("status") not in ("ok", "failed"):
                        raise TypeError(f"a worker returned {type(res).__name__}, not a run's row")
                except Exception as e:  # the executor's failure, not the run's: not recorded, runs again next time
                    lost += 1
                    if lost <= 3 and not quiet:
                        bar.write(f"lost {cell_text(p.run(j))} to the executor: {type(e).__name__}: "
                                  f"{printable(str(e), 200)}", file=say)
                    continue
                record(j, {**res, "reason": printable(res.get("reason") or "", 1000)})
    except KeyboardInterrupt:
        ex.cancel(set(pending))
        return ran, lost, True
    finally:
        bar.close()
    return ran, lost, False


def _broken(ex: Any, pending: dict, e: Exception, quiet: bool, bar: Any, say: TextIO) -> int:
    """The executor failed as a whole: stop submitting, drop what is in flight (not recorded:
    a re-run with the same ``out`` runs it), so the rows done still make the tables. Returns
    how many runs were in flight (lost)."""
    if not quiet:
        why = printable(str(e).splitlines()[0] if str(e) else "", 200)
        bar.write(f"the executor failed ({type(e).__name__}: {why}); stopping: the runs done are kept, run the "
                  f"same command again to run the others", file=say)
    try:
        ex.cancel(set(pending))
    except Exception:  # already broken: nothing more to cancel
        pass
    return len(pending)


def _count(n: int, what: str) -> str:
    return f"{n} {what}" + ("" if n == 1 else "s")


def _finish(out: Path, base: Scenario, g: Grid, p: _Plan, clock: str, executor: str, before: Any, ran: int,
            lost: int, interrupted: bool, wall: float, plot_format: str = "png") -> SweepResult:
    """The tables, the summary and the plot, from results.jsonl."""
    scan = scan_rows(out / ROWS, p.index_of)
    tally = _Tally(p)
    n = write_tables(out, p.keys, [grid_type(v) for _, v in g], tally.feed(read_rows(out / ROWS, scan.offsets)))
    cells = tally.finish()
    resumed = len(before.offsets)
    result = SweepResult(out, p.size, n, ran, resumed, tally.failed, before.torn, before.unreadable, lost, wall,
                         executor, interrupted, cells, g, tuple(p.seeds), plot_format)
    seeds = p.seeds
    seed_text = f"seed {seeds[0]}" if len(seeds) == 1 else f"seeds {seeds[0]}..{seeds[-1]}" \
        if seeds == list(range(seeds[0], seeds[-1] + 1)) else "seeds " + ", ".join(map(str, seeds))
    rate = f" ({60 * ran / wall:.1f} runs per minute)" if ran and wall > 0 else ""
    lines = [f"# Sweep of {base.source}", "",
             f"{n} of {p.size} runs in the table ({_count(len(p.cells), 'cell')} × {seed_text}; "
             f"{base.duration:g} simulated s per run; {clock} clock, {executor}). This call: "
             f"{_count(ran, 'run')} in {fmt_duration(wall)}{rate}"
             + (f", {resumed} done before" if resumed else "")
             + (f", {lost} lost by the executor (run again to retry)" if lost else "")
             + (", interrupted" if interrupted else "") + "."]
    if scan.outside:
        lines.append(f"{scan.outside} rows of {ROWS} are of seeds not in this plan: kept there, not in the table.")
    lines += ["", summarize(p.keys, cells), explain()]
    if tally.failed:
        lines += ["Failed runs:", ""]
        lines += [f"- {', '.join(f'{k}={cell_label(v)}' for k, v in run.cell) or '(base)'}, seed {run.seed}: "
                  f"{reason}" for run, reason in tally.failures]
        if tally.failed > len(tally.failures):
            lines.append(f"- and {tally.failed - len(tally.failures)} more (status \"failed\" in {CSV})")
        lines.append("")
    (out / "summary.md").write_text("\n".join(lines))
    plot(p.keys, cells, result.plot, f"{base.name}: {n} runs")
    return result

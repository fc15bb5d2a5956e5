"""How does a sweep run? The experiment runner: a grid of config overrides × seeds, on any
executor, streamed to disk, resumable, to a table, a summary with confidence intervals and a plot.

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
yet.

The rooms around this one: cdus.app.sweepplan (the grid and its runs), cdus.app.sweepworker
(one run, on a worker), cdus.app.sweepcells (each cell's statistics, summary.md),
cdus.app.sweepplot (the plot), cdus.app.sweepstore (the file formats), cdus.app.sweeptable
(the typed table ``cdus.sweep`` returns).
"""

from __future__ import annotations

import math
import multiprocessing
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping, Sequence, TextIO

from tqdm import tqdm

from cdus.app.executors import CONNECT_TIMEOUT_S, make_executor
from cdus.app.stats import fmt_duration, fmt_number, fmt_seconds
from cdus.app.sweepcells import CellSummary, _Tally, explain, summarize
from cdus.app.sweepplan import MAX_RUNS, MAX_SEED, RUNNERS, Grid, Run, _plain, _Plan, check_grid, normalize_grid
from cdus.app.sweepplot import PLOT_FORMATS, plot
from cdus.app.sweepstore import (
    CSV, PARQUET, ROWS, Manifest, RowLog, cell_label, check_out, grid_type, read_rows, scan_rows, write_manifest,
    write_tables,
)
from cdus.app.sweepworker import run_task
from cdus.files import write_json
from cdus.scenario.config import ConfigError, load_scenario, parse_scenario
from cdus.scenario.model import Scenario
from cdus.wire.text import printable

# the names' old home: `from cdus.app.sweep import ...` keeps working for what moved to a room of its own
from cdus.app.sweepcells import STAT_FIELDS  # noqa: F401
from cdus.app.sweepplan import parse_grid, plan  # noqa: F401
from cdus.app.sweepplot import LABELS, axis_label, value_label  # noqa: F401
from cdus.app.sweepstore import FIELDS  # noqa: F401

__all__ = ["sweep", "SweepResult", "SweepInterrupted", "parse_grid", "check_grid", "plan", "Run", "FIELDS",
           "RUNNERS", "PLOT_FORMATS", "cell_label"]



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

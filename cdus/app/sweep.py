"""The experiment runner: a grid of config overrides × seeds, in parallel, to a table and a plot.

    cdus sweep configs/lake_circle.toml --set link.loss=0,0.2,0.4 --set link.delay.base=0,0.1 \\
        --seeds 3 --out runs/loss_sweep

Each run is `cdus sim`'s in-process fleet (or a `cdus launch --clock lockstep` fleet) with
the cell's overrides; a run that fails (a bad value, a diverged fleet, a crash) is
recorded as failed with its reason and the sweep goes on. Writes ``results.csv`` (one
row per run: the grid values, the seed, the metrics JSON's fields), ``summary.md`` (mean
and spread over seeds per cell) and ``sweep.png`` (coordination settle time and final
coordination error over the grid).
"""

from __future__ import annotations

import csv
import itertools
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
import traceback
import uuid
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import Any, Sequence

from cdus.scenario.config import ConfigError, load_scenario, parse_value
from cdus.sim.fleet import InProcessFleet

FIELDS = ("scenario", "mode", "duration_s", "path_tol", "coord_tol", "path_settle_s", "coord_settle_s",
          "final_path_error_max", "final_coord_error_max", "omega_rate_mean", "link_sent", "link_delivered",
          "link_dropped", "link_rejected", "link_latency_ms_p50", "link_latency_ms_p99", "wall_s",
          "realtime_factor", "omega_rate_final", "min_separation_m", "interventions", "completed", "policy",
          "live_final")


@dataclass(frozen=True)
class Run:
    cell: tuple[tuple[str, Any], ...]  # (key, value) pairs of the grid
    seed: int


def parse_grid(items: Sequence[str]) -> list[tuple[str, list[Any]]]:
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


def cell_label(value: Any) -> Any:
    """A grid value as the table, the CSV and the plot show it: tables and lists as compact
    JSON (``{"p":0.01,"r":0.25}``), so they can label a cell."""
    return json.dumps(value, separators=(",", ":"), sort_keys=True) if isinstance(value, (dict, list)) else value


def check_grid(config: str, grid: list[tuple[str, list[Any]]], base: dict[str, Any] | None = None) -> None:
    """Validate every cell of the grid, values together (``link.burst.p`` needs
    ``link.burst.r``), before any run: a typo should not cost a sweep. Raises ConfigError."""
    for run in plan(grid, [0]):
        load_scenario(config, {**(base or {}), **dict(run.cell)})


def plan(grid: list[tuple[str, list[Any]]], seeds: Sequence[int]) -> list[Run]:
    keys = [k for k, _ in grid]
    cells = itertools.product(*[vals for _, vals in grid]) if grid else [()]
    return [Run(tuple(zip(keys, combo)), seed) for combo in cells for seed in seeds]


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


def run_one(config: str, run: Run, clock: str, duration: float | None) -> dict:
    """One run; never raises: a failure comes back as status "failed" with its reason."""
    overrides = dict(run.cell)
    overrides["scenario.seed"] = run.seed
    if duration is not None:
        overrides["scenario.duration"] = duration
    try:
        if clock == "inproc":
            metrics = InProcessFleet(load_scenario(config, overrides), clock=time.perf_counter).run().metrics
        else:
            metrics = _run_lockstep(config, overrides)
        status, reason = "ok", ""
        if metrics.get("final_path_error_max") is None or not math.isfinite(metrics["final_path_error_max"]):
            status, reason = "failed", "the fleet diverged (non-finite path error)"
        return {"status": status, "reason": reason, **_flatten(metrics)}
    except ConfigError as e:
        return {"status": "failed", "reason": f"config: {e}".replace("\n", "; ")}
    except Exception as e:  # a crash in one cell must not end the sweep
        tb = traceback.format_exception_only(type(e), e)[-1].strip()
        return {"status": "failed", "reason": tb}


def _run_lockstep(config: str, overrides: dict) -> dict:
    with tempfile.TemporaryDirectory(prefix="cdus-sweep-") as tmp:
        args = [sys.executable, "-m", "cdus.app.cli", "launch", config, "--clock", "lockstep", "-q",
                "--fleet", "sweep" + uuid.uuid4().hex[:8], "--logs", tmp]
        for k, v in overrides.items():
            args += ["--set", f"{k}={json.dumps(v)}"]
        proc = subprocess.run(args, capture_output=True, text=True, start_new_session=True)
        path = Path(tmp) / "metrics.json"
        if proc.returncode != 0 or not path.exists():
            tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
            raise RuntimeError(f"launch exited with {proc.returncode}: {' / '.join(tail)}")
        return json.loads(path.read_text())


def summarize(grid_keys: list[str], rows: list[dict]) -> str:
    """Markdown: per cell, runs ok, mean ± std of the settle times and final errors."""
    out = ["| " + " | ".join(grid_keys + ["runs ok", "coord settle s", "final coord error rad",
                                          "path settle s", "final path error m"]) + " |",
           "|" + "---|" * (len(grid_keys) + 5)]
    cells: dict[tuple, list[dict]] = {}
    for r in rows:
        cells.setdefault(tuple(r[k] for k in grid_keys), []).append(r)
    for cell, rs in cells.items():
        ok = [r for r in rs if r["status"] == "ok"]
        out.append("| " + " | ".join([*(str(c) for c in cell), f"{len(ok)}/{len(rs)}",
                                      _spread([r.get("coord_settle_s") for r in ok]),
                                      _spread([r.get("final_coord_error_max") for r in ok], ".4f"),
                                      _spread([r.get("path_settle_s") for r in ok]),
                                      _spread([r.get("final_path_error_max") for r in ok], ".3f")]) + " |")
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        out += ["", "Failed runs:", ""]
        out += [f"- {', '.join(f'{k}={r[k]}' for k in grid_keys)}, seed {r['seed']}: {r['reason']}" for r in failed]
    return "\n".join(out) + "\n"


def _spread(values: list[Any], spec: str = ".1f") -> str:
    vals = [float(v) for v in values if v not in (None, "")]
    never = len(values) - len(vals)
    if not vals:
        return "never" if values else "-"
    s = format(statistics.mean(vals), spec)
    if len(vals) > 1:
        s += " ± " + format(statistics.stdev(vals), spec)
    return s + (f" ({never} never)" if never else "")


def plot(grid_keys: list[str], rows: list[dict], path: Path) -> None:
    """Coordination settle time and final coordination error over the first grid key,
    one line per combination of the other keys (mean over seeds, error bars = std)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    if not grid_keys:
        grid_keys = ["seed"]
    x_key, others = grid_keys[0], grid_keys[1:]
    series: dict[tuple, dict[Any, list[dict]]] = {}
    for r in rows:
        series.setdefault(tuple(r.get(k) for k in others), {}).setdefault(r.get(x_key), []).append(r)
    for label, by_x in series.items():
        xs = list(by_x)
        numeric = all(isinstance(x, (int, float)) for x in xs)
        order = sorted(xs) if numeric else xs
        pos = order if numeric else list(range(len(order)))
        name = ", ".join(f"{k}={v}" for k, v in zip(others, label)) or None
        for ax, field in zip(axes, ("coord_settle_s", "final_coord_error_max")):
            means, stds = [], []
            for x in order:
                vals = [float(r[field]) for r in by_x[x] if r["status"] == "ok" and r.get(field) not in (None, "")]
                means.append(statistics.mean(vals) if vals else float("nan"))
                stds.append(statistics.stdev(vals) if len(vals) > 1 else 0.0)
            ax.errorbar(pos, means, yerr=stds, marker="o", capsize=3, label=name)
            if not numeric:
                ax.set_xticks(pos, [str(x) for x in order])
    axes[0].set_ylabel("coordination settle time (s)")
    axes[0].set_title("coordination settle time (missing = never)")
    axes[1].set_ylabel("final coordination error (rad)")
    axes[1].set_title("final worst edge error")
    axes[1].set_yscale("log")
    for ax in axes:
        ax.set_xlabel(x_key)
        ax.grid(True, alpha=0.3)
        if others:
            ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def sweep(config: str, grid: list[tuple[str, list[Any]]], seeds: Sequence[int], out: Path,
          clock: str = "inproc", jobs: int | None = None, duration: float | None = None, quiet: bool = False) -> list[dict]:
    out.mkdir(parents=True, exist_ok=True)
    runs = plan(grid, seeds)
    keys = [k for k, _ in grid]
    jobs = jobs or (os.cpu_count() or 1 if clock == "inproc" else 1)
    rows: list[dict] = []
    start = time.perf_counter()

    def report(j: int, res: dict) -> None:
        run = runs[j]
        row = {**{k: cell_label(v) for k, v in run.cell}, "seed": run.seed, **res, "_order": j}
        rows.append(row)
        if not quiet:
            cell = ", ".join(f"{k}={v}" for k, v in run.cell) or "(base)"
            settle, err = res.get("coord_settle_s"), res.get("final_coord_error_max")
            what = (f"coord settle {'never' if settle is None else f'{settle:.1f} s'}, final edge error "
                    f"{'n/a' if err is None else f'{err:.4f} rad'}" if res["status"] == "ok"
                    else f"FAILED: {res['reason']}")
            bar = "#" * int(20 * len(rows) / len(runs))
            print(f"[{bar:<20}] {len(rows)}/{len(runs)} {cell}, seed {run.seed}: {what}", flush=True)

    if jobs <= 1:
        for j, run in enumerate(runs):
            report(j, run_one(config, run, clock, duration))
    else:
        with ProcessPoolExecutor(max_workers=jobs, mp_context=get_context("spawn")) as pool:
            futures = {pool.submit(run_one, config, run, clock, duration): j for j, run in enumerate(runs)}
            for fut in as_completed(futures):
                report(futures[fut], fut.result())
    rows.sort(key=lambda r: r.pop("_order"))
    columns = keys + ["seed", "status", "reason", *FIELDS]
    with open(out / "results.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({c: ("" if r.get(c) is None else r.get(c)) for c in columns})
    wall = time.perf_counter() - start
    header = (f"# Sweep of {config}\n\n{len(runs)} runs ({clock}), seeds {list(seeds)}, "
              f"{wall:.1f} s wall ({60 * len(runs) / wall:.1f} runs per minute)\n\n")
    (out / "summary.md").write_text(header + summarize(keys, rows))
    plot(keys, rows, out / "sweep.png")
    return rows

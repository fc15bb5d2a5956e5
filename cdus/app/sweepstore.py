"""Where does a sweep keep what it did? Its directory on disk: the manifest, the streamed
rows, and the tables made from them.

``manifest.json``  what the sweep is (the resolved config's digest, the grid, the clock): a
                   re-run with the same ``--out`` resumes only the same sweep.
``results.jsonl``  one JSON object per finished run, appended as it comes with a single
                   write + flush + fsync, so a crash leaves whole lines and at most a torn
                   last one (ignored, counted, cut off before the next append; its run runs again).
``results.csv`` and ``results.parquet``  the table in plan order, written at the end from the
                   streamed rows (never all of them in memory: the file is read by offsets).
"""

from __future__ import annotations

import csv
import fcntl
import hashlib
import json
import math
import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Iterator, Sequence

from cdus.files import write_json
from cdus.scenario.checks import is_number
from cdus.scenario.config import ConfigError
from cdus.wire.bounds import finite, is_number

PLOT_FORMATS = ("png", "pdf", "svg")  # --plot-format: sweep.png, or a vector file for a paper (cdus.app.sweepplot)

MANIFEST, ROWS, CSV, PARQUET = "manifest.json", "results.jsonl", "results.csv", "results.parquet"
FORMAT = "cdus-sweep/1"
STATUSES = ("ok", "failed")  # a row's status; a line with another is not a row



@dataclass(frozen=True)
class SweepRow:
    """One run of a sweep as its table holds it (a row of results.csv and results.parquet):
    the cell's grid values, the seed, ``status`` (``ok`` or ``failed``), ``reason`` (why it
    failed, else ""), and the run's metrics JSON flattened (docs/metrics.md; ``link_*`` are the
    ``link`` block's, ``omega_rate_mean`` the mean of ``omega_rate_final``, which is kept as
    JSON text, ``live_final`` the live ids joined by spaces). A metric is None where the run
    has no value (a failed run has none; a settle time that never came). The fields after
    ``reason`` are the table's metric columns, in order, with their types (FIELD_TYPES)."""
    cell: tuple[tuple[str, Any], ...]  # (grid key, value) in the grid's order; a table or list value as it was given
    seed: int
    status: str
    reason: str = ""
    scenario: str | None = None
    mode: str | None = None
    duration_s: float | None = None
    path_tol: float | None = None
    coord_tol: float | None = None
    path_settle_s: float | None = None
    coord_settle_s: float | None = None
    final_path_error_max: float | None = None
    final_coord_error_max: float | None = None
    omega_rate_mean: float | None = None
    link_sent: int | None = None
    link_delivered: int | None = None
    link_dropped: int | None = None
    link_rejected: int | None = None
    link_latency_ms_p50: float | None = None
    link_latency_ms_p99: float | None = None
    wall_s: float | None = None
    realtime_factor: float | None = None
    omega_rate_final: str | None = None
    min_separation_m: float | None = None
    near_collision: bool | None = None
    interventions: int | None = None
    completed: bool | None = None
    policy: str | None = None
    live_final: str | None = None

    def __getitem__(self, key: str) -> Any:
        """A column by name, as in the DataFrame: a grid key (``row["link.loss"]``), ``seed``,
        ``status``, a metric."""
        for k, v in self.cell:
            if k == key:
                return v
        if key == "cell" or key not in ROW_COLUMNS:
            raise KeyError(key)
        return getattr(self, key)

    def as_dict(self) -> dict[str, Any]:
        """The row's columns: the grid keys, then ``seed``, ``status``, ``reason`` and the metrics."""
        return {**dict(self.cell), **{c: getattr(self, c) for c in ROW_COLUMNS}}

    @classmethod
    def from_columns(cls, columns: dict[str, Any], grid: Sequence[tuple[str, Sequence[Any]]]) -> "SweepRow":
        """A row of results.parquet (``{column: value}``, as pyarrow reads it), its cell's
        values those of ``grid`` as given (the column holds them typed: 0 as 0.0 in a float
        column, a table or a list as JSON text)."""
        cell = []
        for key, values in grid:
            kind = grid_type(values)
            given = {canonical(_typed(v, kind)): v for v in values}
            v = columns.get(key)
            cell.append((key, given.get(canonical(v), v)))
        return cls(tuple(cell), **{c: columns.get(c) for c in ROW_COLUMNS})


_COLUMN_TYPES = {"str | None": "string", "float | None": "float64", "int | None": "int64", "bool | None": "bool"}
ROW_HEAD = ("seed", "status", "reason")  # the columns between the grid keys and the metrics
# The metrics fields of a row (the metrics JSON's, flattened) and their Parquet types: SweepRow's.
FIELD_TYPES: dict[str, str] = {f.name: _COLUMN_TYPES[f.type] for f in fields(SweepRow)
                               if f.name not in ("cell", *ROW_HEAD)}
FIELDS = tuple(FIELD_TYPES)
ROW_COLUMNS = (*ROW_HEAD, *FIELDS)
WALL_CLOCK_FIELDS = ("wall_s", "realtime_factor")  # differ between two runs of the same (cell, seed)


def canonical(value: Any) -> str:
    """One text per value, for keys and digests (TOML dates as text)."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), default=str)


def cell_label(value: Any) -> Any:
    """A grid value as the CSV and the plot show it: tables and lists as compact JSON
    (``{"p":0.01,"r":0.25}``), so they can label a cell."""
    return json.dumps(value, separators=(",", ":"), sort_keys=True, default=str) if isinstance(value, (dict, list)) \
        else value


def clean(value: Any) -> Any:
    """A row value as JSON takes it: non-finite floats become None (the row's status says why)."""
    if is_number(value) and not finite(value):
        return None
    if hasattr(value, "item") and not isinstance(value, (dict, list, str)):  # numpy scalars
        return clean(value.item())
    return value


@dataclass(frozen=True)
class Manifest:
    """What a sweep directory holds results of."""
    config: str  # where the config came from (informational)
    config_sha256: str  # digest of the resolved, overridden config data (every key, so the duration too)
    grid: list  # [[key, [values...]], ...]
    clock: str

    @staticmethod
    def of(source: str, raw: dict, grid: Sequence[tuple[str, Sequence[Any]]], clock: str) -> "Manifest":
        digest = hashlib.sha256(canonical(raw).encode()).hexdigest()
        return Manifest(source, digest, json.loads(canonical([[k, list(v)] for k, v in grid])), clock)

    def to_json(self) -> dict:
        return {"format": FORMAT, "config": self.config, "config_sha256": self.config_sha256, "grid": self.grid,
                "clock": self.clock}

    def differences(self, other: dict) -> list[str]:
        """How an earlier manifest (as read) differs from this one, worded; [] if it is the same sweep."""
        out = []
        if other.get("format") != FORMAT:
            return [f"it is not a cdus sweep manifest of this version ({other.get('format')!r})"]
        if other.get("config_sha256") != self.config_sha256:
            out.append(f"the config differs (it was {other.get('config')!r} with other values or overrides, "
                       f"--duration included)")
        if other.get("grid") != self.grid:
            grid = other.get("grid")
            if isinstance(grid, list) and all(isinstance(kv, list) and len(kv) == 2 and isinstance(kv[0], str)
                                              and isinstance(kv[1], list) for kv in grid):
                was = "; ".join(f"{k}={','.join(map(canonical, v))}" for k, v in grid) or "no grid"
            else:  # a manifest edited by hand or damaged: say what it holds, shortened
                was = f"not a grid: {canonical(grid)[:100]}"
            out.append(f"the grid differs (it was {was})")
        if other.get("clock") != self.clock:
            out.append(f"the clock differs (it was {other.get('clock')!r})")
        return out


def check_out(out: Path, manifest: Manifest) -> bool:
    """Refuse (ConfigError) an ``out`` that holds results of another sweep; True if it holds
    results of this one (a resume). Reads only."""
    mpath, rpath = out / MANIFEST, out / ROWS
    if not mpath.exists():
        if rpath.exists() and rpath.stat().st_size > 0:
            raise ConfigError("--out", [(str(out), f"has {ROWS} but no {MANIFEST}: not a sweep this version can "
                                                   f"resume; give another --out")])
        return False
    try:
        earlier = json.loads(mpath.read_text())
        if not isinstance(earlier, dict):
            raise ValueError("not a JSON object")
    except (OSError, ValueError, RecursionError) as e:  # RecursionError: JSON nested too deep
        raise ConfigError("--out", [(str(mpath), f"cannot be read ({type(e).__name__}: {str(e)[:200]}); give "
                                                 f"another --out")]) from None
    diff = manifest.differences(earlier)
    if diff:
        raise ConfigError("--out", [(str(out), "holds the results of another sweep: " + "; ".join(diff) +
                                     "; give another --out (or the same command as before to resume it)")])
    return rpath.exists()


def write_manifest(out: Path, manifest: Manifest) -> None:
    # allow_inf: a grid value may be inf where the config takes it (radio.shadowing_distance = inf),
    # written as Infinity, which json reads back as inf (so a resume compares equal)
    write_json(out / MANIFEST, manifest.to_json(), allow_inf=True)


@dataclass
class Scan:
    """What an existing results.jsonl holds: for each plan index, the byte offset of its row."""
    offsets: dict[int, int] = field(default_factory=dict)
    torn: int = 0  # a last line without its newline: a write cut off by a crash
    unreadable: int = 0  # whole lines that are not a row of this plan's cells
    duplicates: int = 0  # a (cell, seed) already seen (only the first counts)
    outside: int = 0  # rows of seeds this plan does not have (kept in the file, not in the table)
    end: int = 0  # where the whole lines end


def scan_rows(path: Path, index_of: Any) -> Scan:
    """Index ``path``'s rows; ``index_of(cell_values_key, seed)`` gives a row's plan index or
    None (a row of a seed this plan does not have: kept in the file, not in the table)."""
    s = Scan()
    if not path.exists():
        return s
    with open(path, "rb") as fh:
        pos = 0
        for line in fh:
            if not line.endswith(b"\n"):
                s.torn += 1
                break
            j = _index(line, index_of)
            if j is None:
                s.unreadable += 1
            elif j < 0:
                s.outside += 1
            else:
                if j in s.offsets:
                    s.duplicates += 1
                else:
                    s.offsets[j] = pos
            pos += len(line)
            s.end = pos
    return s


def _index(line: bytes, index_of: Any) -> int | None:
    """The plan index of a row line; -1 for a valid row outside the plan; None if unreadable."""
    try:
        row = json.loads(line)
    except (ValueError, RecursionError):
        return None
    if not isinstance(row, dict) or not isinstance(row.get("cell"), dict) or type(row.get("seed")) is not int \
            or row.get("status") not in STATUSES:
        return None
    j = index_of(row["cell"], row["seed"])
    return -2 if j is None else j


def row_json(row: dict) -> str:
    """A row as one JSON line: the cell's values kept (inf included: a valid config value of
    radio.shadowing_distance, radio.shadowing_time, link.down.to; a resume compares them), the
    metrics :func:`clean` (a non-finite result is None; the status says why)."""
    cell = json.dumps(row.get("cell", {}), separators=(",", ":"), allow_nan=True, default=str)
    rest = json.dumps({k: clean(v) for k, v in row.items() if k != "cell"}, separators=(",", ":"),
                      allow_nan=False, default=str)
    return '{"cell":' + cell + ("," + rest[1:] if rest != "{}" else "}")


class RowLog:
    """Appends rows to results.jsonl: one ``os.write`` of the whole line, then fsync. Holds an
    exclusive lock on the file while open, so two sweeps never write into one ``out``."""

    def __init__(self, path: Path):
        self.fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            raise ConfigError("--out", [(str(path.parent), "another sweep is running into this directory now; "
                                                           "wait for it or give another --out")]) from None

    def cut(self, end: int) -> None:
        """Cut what follows the last whole line off (a torn line), before appending."""
        if os.fstat(self.fd).st_size > end:
            os.ftruncate(self.fd, end)

    def append(self, row: dict) -> None:
        """``row["cell"]`` as it is (a config value may be inf: written as ``Infinity``, read back
        as inf, so a resume finds its run); every other value :func:`clean`."""
        data = (row_json(row) + "\n").encode()
        view = memoryview(data)
        while view:
            n = os.write(self.fd, view)
            view = view[n:]
        os.fsync(self.fd)

    def close(self) -> None:
        os.close(self.fd)


def read_rows(path: Path, offsets: dict[int, int]) -> Iterator[tuple[int, dict]]:
    """The rows at ``offsets`` in plan order: (plan index, row)."""
    with open(path, "rb") as fh:
        for j in sorted(offsets):
            fh.seek(offsets[j])
            yield j, json.loads(fh.readline())


def grid_type(values: Sequence[Any]) -> str:
    """The Parquet type of a grid key's column: numbers as numbers, else text (tables and
    lists as compact JSON)."""
    if values and all(isinstance(v, bool) for v in values):
        return "bool"
    if values and all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        return "int64"
    if values and all(is_number(v) for v in values):
        return "float64"
    if values and all(isinstance(v, str) for v in values):
        return "string"
    return "json"


def _typed(value: Any, kind: str) -> Any:
    """A value as its column's type; None where it is not one (never an exception)."""
    if value is None:
        return None
    number = is_number(value)
    if kind == "float64":
        try:
            return float(value) if number else None
        except OverflowError:  # an int beyond any float (a hand-edited results.jsonl)
            return None
    if kind == "int64":
        return int(value) if number and _int64(value) else None
    if kind == "bool":
        return value if isinstance(value, bool) else None
    if kind == "json":
        return canonical(value)
    return value if isinstance(value, str) else canonical(value)


def _int64(value: int | float) -> bool:
    """An integral number an int64 column holds."""
    try:
        return float(value).is_integer() and -2 ** 63 <= int(value) < 2 ** 63
    except OverflowError:
        return False


def table_schema(keys: Sequence[str], key_types: Sequence[str]) -> tuple[list[str], dict[str, str], Any]:
    """The table's columns (the grid keys, ``seed``, ``status``, ``reason``, the metrics), each
    column's type (:func:`grid_type`'s, FIELD_TYPES) and the Arrow schema of results.parquet."""
    import pyarrow as pa

    columns = [*keys, *ROW_COLUMNS]
    types = {**dict(zip(keys, key_types)), "seed": "int64", "status": "string", "reason": "string", **FIELD_TYPES}
    arrow = {"float64": pa.float64(), "int64": pa.int64(), "bool": pa.bool_(), "string": pa.string(),
             "json": pa.string()}
    return columns, types, pa.schema([pa.field(c, arrow[types[c]]) for c in columns])


def typed_columns(flat: dict[str, Any], columns: Sequence[str], types: dict[str, str]) -> dict[str, Any]:
    """A row's values as their columns' types (:func:`_typed`): what results.parquet holds."""
    return {c: _typed(flat.get(c), types[c]) for c in columns}


def write_tables(out: Path, keys: Sequence[str], key_types: Sequence[str], rows: Iterator[dict],
                 batch: int = 1000) -> int:
    """results.csv and results.parquet from ``rows`` (plan order), ``batch`` rows in memory
    at a time; returns how many rows."""
    columns, types, schema = table_schema(keys, key_types)
    csv_tmp, pq_tmp = out / (CSV + ".tmp"), out / (PARQUET + ".tmp")
    try:
        n = _write(csv_tmp, pq_tmp, columns, keys, types, schema, rows, batch)
    except BaseException:  # a second Ctrl-C, a full disk: no half-written table left behind
        csv_tmp.unlink(missing_ok=True)
        pq_tmp.unlink(missing_ok=True)
        raise
    os.replace(csv_tmp, out / CSV)
    os.replace(pq_tmp, out / PARQUET)
    return n


def _write(csv_tmp: Path, pq_tmp: Path, columns: list, keys: Sequence[str], types: dict, schema: Any,
           rows: Iterator[dict], batch: int) -> int:
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = 0
    with open(csv_tmp, "w", newline="") as fh, pq.ParquetWriter(pq_tmp, schema) as writer:
        w = csv.DictWriter(fh, fieldnames=columns, extrasaction="ignore")
        w.writeheader()
        chunk: list[dict] = []

        def flush() -> None:
            if chunk:
                writer.write_table(pa.Table.from_pylist(chunk, schema=schema))
                chunk.clear()

        for row in rows:
            flat = {**{k: row["cell"].get(k) for k in keys}, **{c: row.get(c) for c in columns if c not in keys}}
            w.writerow({c: "" if flat.get(c) is None else (cell_label(flat[c]) if c in keys else flat[c])
                        for c in columns})
            chunk.append(typed_columns(flat, columns, types))
            n += 1
            if len(chunk) >= batch:
                flush()
        flush()
    return n

"""What does a sweep give back? One typed table, whatever is installed.

``cdus.sweep`` returns a :class:`SweepTable`: the runs as typed rows (``SweepRow``, one per
(cell, seed) in plan order, the columns of results.parquet), the per-cell statistics of
summary.md (``CellStats``), and what the engine did (counts, file paths). pandas and xarray
views are made on demand: ``to_dataframe()`` (the table as results.parquet holds it) and
``to_xarray()`` (every column over the grid's keys × the seeds, NaN where no run is).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterator, Mapping

import numpy as np

from cdus.app.stats import Stat
from cdus.app.sweep import SweepResult
from cdus.app.sweepcells import STAT_FIELDS
from cdus.app.sweepstore import FIELD_TYPES, ROW_COLUMNS, SweepRow, canonical, cell_label, grid_type, table_schema, \
    typed_columns
from cdus.extras import needs


@dataclass(frozen=True)
class CellStats:
    """One cell's statistics (a row of summary.md): its runs, how many were ok, and for each
    of STAT_FIELDS (coord_settle_s, final_coord_error_max, path_settle_s,
    final_path_error_max) a :class:`~cdus.app.stats.Stat` over the ok runs with a value (a
    settle time: the runs that settled): ``n``, ``mean``, ``std`` (n - 1; None below 2),
    ``lo`` and ``hi`` (the 95 % percentile bootstrap interval of the mean, seeded)."""

    cell: tuple[tuple[str, Any], ...]
    runs: int
    ok: int
    stats: Mapping[str, Stat]

    def __getitem__(self, key: str) -> Any:
        """A grid value of the cell by its key."""
        for k, v in self.cell:
            if k == key:
                return v
        raise KeyError(key)


def _units(column: str) -> str | None:
    """A metric column's unit, from its name (docs/metrics.md)."""
    if "latency_ms" in column:
        return "ms"
    if column in ("coord_tol", "final_coord_error_max"):
        return "rad"
    if column == "omega_rate_mean":
        return "rad/s"
    if column.endswith("_s"):
        return "s"
    if column.endswith("_m") or column in ("path_tol", "final_path_error_max"):
        return "m"
    return None


@dataclass(frozen=True, eq=False)
class SweepTable:
    """A sweep's table (docs/api.md): ``rows`` one :class:`SweepRow` per run done, in plan
    order (cells in the grid's order, the last key fastest, seeds innermost; a run the
    executor lost is not there: ``planned - len(table)`` of them); ``cells`` the per-cell
    statistics; ``grid`` and ``seeds`` the plan; ``result`` the engine's
    ``cdus.app.sweep.SweepResult`` (counts, wall time, ``csv``, ``parquet``, ``summary``,
    ``plot`` paths). ``len(table)``, ``iter(table)`` and ``table[i]`` go over the rows."""

    grid: tuple[tuple[str, tuple[Any, ...]], ...]
    seeds: tuple[int, ...]
    rows: tuple[SweepRow, ...]
    cells: tuple[CellStats, ...]
    result: SweepResult | None = None  # what the engine did (None for a table made by hand)

    @classmethod
    def of(cls, result: SweepResult) -> "SweepTable":
        """The table of a finished sweep (``cdus.app.sweep.sweep``'s result): its rows read
        from results.parquet."""
        import pyarrow.parquet as pq

        grid = tuple((k, tuple(v)) for k, v in result.grid)
        rows = tuple(SweepRow.from_columns(r, grid) for r in pq.read_table(result.parquet).to_pylist())
        cells = tuple(CellStats(c.cell, c.runs, c.ok, dict(c.stats)) for c in result.cells)
        return cls(grid, tuple(result.seeds), rows, cells, result)

    @property
    def keys(self) -> tuple[str, ...]:
        """The grid's keys, in order."""
        return tuple(k for k, _ in self.grid)

    @property
    def planned(self) -> int:
        """(cell, seed) pairs of the plan."""
        return math.prod(len(v) for _, v in self.grid) * len(self.seeds)

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self) -> Iterator[SweepRow]:
        return iter(self.rows)

    def __getitem__(self, i: int) -> SweepRow:
        return self.rows[i]

    def _columns(self) -> tuple[list[str], dict[str, str], Any]:
        return table_schema(self.keys, [grid_type(list(v)) for _, v in self.grid])

    def to_dataframe(self):
        """A pandas DataFrame, one row per run, the columns and types of results.parquet: a
        column per grid key (numbers as numbers; a table or list value as compact JSON text),
        ``seed``, ``status``, ``reason`` and the metrics (an integer column with a missing
        value is float, NaN there). Needs pandas (the ``api`` extra)."""
        needs("pandas", "SweepTable.to_dataframe")
        import pyarrow as pa

        columns, types, schema = self._columns()
        return pa.Table.from_pylist([typed_columns(r.as_dict(), columns, types) for r in self.rows],
                                    schema=schema).to_pandas()

    def to_xarray(self):
        """An xarray Dataset over dims (the grid's keys..., ``seed``), one variable per column
        (``status``, ``reason`` and the metrics), so ``ds.coord_settle_s.mean("seed")`` is a
        cell's mean. A coordinate holds its key's values in the grid's order (a table or list
        value as compact JSON text). Where no run is (lost, or not run yet), a number is NaN
        and a text None; a number or bool column with such a hole is float. Needs xarray (the
        ``api`` extra)."""
        xr = needs("xarray", "SweepTable.to_xarray")
        dims = (*self.keys, "seed")
        shape = tuple(len(v) for _, v in self.grid) + (len(self.seeds),)
        where = {k: {canonical(v): i for i, v in enumerate(vals)} for k, vals in self.grid}
        seed_at = {s: i for i, s in enumerate(self.seeds)}
        at = [tuple(where[k][canonical(v)] for k, v in r.cell) + (seed_at[r.seed],) for r in self.rows]
        full = len(self.rows) == math.prod(shape)
        data = {}
        for column in ROW_COLUMNS[1:]:  # seed is a dimension
            kind = "string" if column in ("status", "reason") else FIELD_TYPES[column]
            values = [getattr(r, column) for r in self.rows]
            if kind == "string":
                arr = np.full(shape, None, dtype=object)
            elif full and kind in ("int64", "bool") and all(v is not None for v in values):
                arr = np.zeros(shape, dtype=np.int64 if kind == "int64" else bool)
            else:
                arr = np.full(shape, np.nan)
                values = [np.nan if v is None else v for v in values]
            for idx, v in zip(at, values):
                arr[idx] = v
            unit = _units(column)
            data[column] = (dims, arr, {"units": unit} if unit else {})
        coords = {k: [cell_label(v) for v in vals] for k, vals in self.grid}
        return xr.Dataset(data, coords={**coords, "seed": list(self.seeds)})


def cell_statistics(table: Any):
    """A sweep's per-cell statistics as a pandas DataFrame (what summary.md shows), one row
    per cell: the grid values, ``runs``, ``ok``, and for each statistic's field ``<field>_n``,
    ``_mean``, ``_std``, ``_ci_lo`` and ``_ci_hi``. ``table``: a :class:`SweepTable` (or the
    engine's SweepResult: anything with ``cells``). Needs pandas (the ``api`` extra)."""
    pd = needs("pandas", "cdus.cell_statistics")
    rows = []
    for c in table.cells:
        row: dict[str, Any] = {k: v for k, v in c.cell}
        row["runs"], row["ok"] = c.runs, c.ok
        for f in STAT_FIELDS:
            st = c.stats.get(f)
            for name, attr in (("n", "n"), ("mean", "mean"), ("std", "std"), ("ci_lo", "lo"), ("ci_hi", "hi")):
                row[f"{f}_{name}"] = None if st is None else getattr(st, attr)
        rows.append(row)
    return pd.DataFrame(rows)


"""cdus.app.sweeptable: the typed table cdus.sweep returns (SweepTable, SweepRow, CellStats), its
DataFrame (results.parquet's columns and types) and its Dataset over grid x seed. Tables made by
hand here (no run): any grid, any seeds, any runs missing."""

from __future__ import annotations

import itertools
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from cdus.app.stats import Stat
from cdus.app.sweeptable import CellStats, SweepTable
from cdus.app.sweepstore import FIELD_TYPES, ROW_COLUMNS, SweepRow, canonical, grid_type, table_schema, \
    typed_columns

pd = pytest.importorskip("pandas")
xr = pytest.importorskip("xarray")

_numbers = {"float64": hs.floats(-1e6, 1e6, allow_nan=False), "int64": hs.integers(0, 10 ** 6),
            "bool": hs.booleans(), "string": hs.text(max_size=5)}
_values = hs.one_of(
    hs.lists(hs.integers(-5, 5), min_size=1, max_size=3, unique=True),
    hs.lists(hs.sampled_from([0, 0.1, 0.25, 1, math.inf]), min_size=1, max_size=3, unique=True),
    hs.lists(hs.sampled_from(["hold", "timeout", "extrapolate"]), min_size=1, max_size=3, unique=True),
    hs.lists(hs.sampled_from([{"p": 0.01, "r": 0.5}, {"p": 0.1, "r": 0.5}, [1, 2]]), min_size=1, max_size=3,
             unique_by=canonical),
)


@hs.composite
def tables(draw) -> SweepTable:
    keys = draw(hs.lists(hs.sampled_from(["link.loss", "link.policy", "rates.control", "link.burst"]),
                         max_size=2, unique=True))
    grid = tuple((k, tuple(draw(_values))) for k in keys)
    seeds = tuple(draw(hs.lists(hs.integers(0, 2 ** 40), min_size=1, max_size=3, unique=True)))
    rows = []
    for cell in itertools.product(*[v for _, v in grid]):
        for seed in seeds:
            if draw(hs.booleans()) and draw(hs.booleans()):  # about a quarter of the runs are missing
                continue
            metrics = {f: draw(hs.none() | _numbers[t]) for f, t in FIELD_TYPES.items()}
            rows.append(SweepRow(tuple(zip(keys, cell)), seed, draw(hs.sampled_from(["ok", "failed"])), "", **metrics))
    cells = tuple(CellStats(tuple(zip(keys, c)), 0, 0, {}) for c in itertools.product(*[v for _, v in grid]))
    return SweepTable(grid, seeds, tuple(rows), cells)


@settings(max_examples=30, deadline=None)
@given(tables())
def test_a_row_read_back_from_its_columns_is_the_row(table):
    columns, types, _ = table_schema(table.keys, [grid_type(list(v)) for _, v in table.grid])
    for row in table.rows:
        assert SweepRow.from_columns(typed_columns(row.as_dict(), columns, types), table.grid) == row


@settings(max_examples=30, deadline=None)
@given(tables())
def test_the_dataframe_holds_each_row_in_order_typed_as_the_parquet(table):
    df = table.to_dataframe()
    assert list(df.columns) == [*table.keys, *ROW_COLUMNS] and len(df) == len(table)
    for (_, got), row in zip(df.iterrows(), table.rows):
        for k, v in row.cell:
            kind = grid_type(list(dict(table.grid)[k]))
            assert got[k] == (canonical(v) if kind == "json" else v)
        for c in ROW_COLUMNS:
            want = getattr(row, c)
            assert (pd.isna(got[c]) if want is None else got[c] == want), c


@settings(max_examples=30, deadline=None)
@given(tables())
def test_the_dataset_puts_each_run_at_its_cell_and_seed_and_holes_where_none(table):
    ds = table.to_xarray()
    assert dict(ds.sizes) == {**{k: len(v) for k, v in table.grid}, "seed": len(table.seeds)}
    assert list(ds.seed.values) == list(table.seeds)
    at = {}
    for row in table.rows:
        at[tuple(canonical(v) for _, v in row.cell) + (row.seed,)] = row
    for cell in itertools.product(*[v for _, v in table.grid]):
        for j, seed in enumerate(table.seeds):
            index = {k: [canonical(x) for x in vals].index(canonical(v)) for (k, vals), v in zip(table.grid, cell)}
            point = ds.isel({**index, "seed": j})
            row = at.get(tuple(canonical(v) for v in cell) + (seed,))
            for c in ROW_COLUMNS[1:]:
                got = point[c].item()
                want = None if row is None else getattr(row, c)
                if want is None:
                    assert got is None or (isinstance(got, float) and math.isnan(got)), c
                else:
                    assert got == want, c


def test_a_full_table_keeps_its_integer_and_bool_columns():
    row = SweepRow((("link.loss", 0),), 1, "ok", link_sent=10, completed=True)
    table = SweepTable((("link.loss", (0,)),), (1,), (row,), (CellStats((("link.loss", 0),), 1, 1,
                                                                         {"coord_settle_s": Stat(0, *[None] * 4)}),))
    ds = table.to_xarray()
    assert ds.link_sent.dtype.kind == "i" and ds.completed.dtype == bool
    assert ds.coord_settle_s.dtype.kind == "f" and math.isnan(float(ds.coord_settle_s[0, 0]))
    assert table.cells[0]["link.loss"] == 0 and table[0]["link.loss"] == 0 and row["link_sent"] == 10
    with pytest.raises(KeyError):
        row["nothing"]

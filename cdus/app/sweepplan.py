"""Which runs make a sweep? The grid of config overrides (from ``--set`` or a mapping),
checked, and the plan: every (cell, seed), indexed without listing them.
"""

from __future__ import annotations

import itertools
import os
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

from cdus.app.sweepstore import canonical
from cdus.scenario.config import ConfigError, load_scenario, parse_scenario, parse_value
from cdus.scenario.model import Scenario


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

"""What does a sweep say about each cell? The statistics of its runs (mean, standard
deviation, a 95 % bootstrap interval, how many settled) and summary.md's table of them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator

from cdus.app.stats import CI_WORDS, Stat, describe, fmt_stat
from cdus.app.sweepplan import Run, _Plan
from cdus.app.sweepstore import cell_label
from cdus.wire.bounds import finite
from cdus.wire.text import printable

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

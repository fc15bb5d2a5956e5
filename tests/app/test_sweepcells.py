"""Each cell's statistics and summary.md's table (cdus/app/sweepcells.py)."""

import json
import math

from cdus.app.stats import Stat
from cdus.app.sweepcells import CellSummary, summarize


def cell_of(value, ok, settle, error):
    c = CellSummary((("link.delay.base", value),), runs=ok, ok=ok)
    c.values["coord_settle_s"] = settle
    c.values["final_coord_error_max"] = error
    c.finish(seed=0)
    return c


def test_summary_cells_show_mean_sd_and_interval():
    c = cell_of(0.0, 3, [10.0, 12.0, 11.0], [0.01, 0.02, 0.015])
    st = c.stats["coord_settle_s"]
    assert st.n == 3 and st.mean == 11.0 and math.isclose(st.std, 1.0)
    assert st.lo <= 11.0 <= st.hi
    line = summarize(["link.delay.base"], [c]).splitlines()[2]
    assert line.startswith("| 0.0 | 3/3 | 3/3 | 11.0 ± 1.0 [") and "0.0150 ± 0.0050 [" in line
    assert isinstance(st, Stat)
    json.dumps(st.__dict__)  # plain numbers, no numpy types

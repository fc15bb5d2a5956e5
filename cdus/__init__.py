"""What is cdus, and what does ``import cdus`` give? An emulator of cross-domain unmanned fleets
under the distributed guiding-vector-field controller, and its Python API (docs/api.md):

    import cdus
    sc = cdus.load("configs/lake_circle.toml", {"scenario.duration": 60})
    res = cdus.run(sc)                                 # or clock="lockstep": one process per vehicle
    res.metrics.coord_settle_s, res.trace.to_dataframe()
    table = cdus.sweep("configs/lake_circle.toml", {"link.loss": [0, 0.2]}, seeds=3, out="runs/sw")
    table.rows, table.cells, table.to_dataframe(), table.to_xarray()   # a SweepTable, typed rows

``import cdus`` is cheap: the names below are loaded from :mod:`cdus.api` on first use, and
neither Zenoh nor Rerun is imported until a run needs them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__all__ = [
    "RUNNERS", "ClosestPair", "ConfigError", "DivergedError", "DroppedBy", "Event", "FaultCounters", "Integrity",
    "LinkFaults", "LinkMetrics", "LinkStateChange", "Metrics", "RadioMetrics", "RejectedByReason", "Result",
    "RunError", "RunInterrupted", "SafetyInfo", "Scenario", "SweepRow", "SweepTable", "CellStats", "Trace",
    "Utilisation", "WorldLost", "cell_statistics", "load", "override", "run", "sweep",
]

if TYPE_CHECKING:  # for type checkers and editors; at run time __getattr__ loads them
    from cdus.api import (  # noqa: F401
        RUNNERS, ClosestPair, ConfigError, DivergedError, DroppedBy, Event, FaultCounters, Integrity, LinkFaults,
        LinkMetrics, LinkStateChange, Metrics, RadioMetrics, RejectedByReason, Result, RunError, RunInterrupted,
        SafetyInfo, Scenario, SweepRow, SweepTable, CellStats, Trace, Utilisation, WorldLost, cell_statistics, load,
        override, run, sweep,
    )


def __getattr__(name: str) -> Any:
    if name in __all__:
        from cdus import api  # loaded on first use (numpy, the scenario layer, the in-process fleet)

        value = getattr(api, name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'cdus' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))

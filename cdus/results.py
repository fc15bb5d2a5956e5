"""What did a run measure and record? The typed metrics and trace that :func:`cdus.run` returns.

- :class:`Metrics` (and the records it holds: :class:`LinkMetrics`, :class:`FaultCounters`,
  :class:`RadioMetrics`, :class:`Event`, :class:`SafetyInfo`, ...): a run's metrics, as the run
  built them (cdus.sim.summary), or a metrics JSON read into types, every field checked once
  where it enters (:meth:`Metrics.from_json`); ``to_dict()`` is the JSON (docs/metrics.md). They are defined in the pure layer
  (:mod:`cdus.sim.runmetrics`) and exported here.
- :class:`Trace`: the recorded time series (numpy arrays; pandas and xarray helpers).
- :class:`Result`: the scenario that ran, its metrics and its trace.

The public names are :mod:`cdus.api`'s (``import cdus``); docs/api.md is the reference.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cdus.core.metrics import TRACE_ARRAYS, Recorder, read_trace, trace_shape_problem
from cdus.extras import needs
from cdus.scenario.model import Scenario
from cdus.sim.runmetrics import (ClosestPair, DroppedBy, Event, FaultCounters, Integrity, LinkFaults,  # noqa: F401
                                 LinkMetrics, LinkStateChange, Metrics, RadioMetrics, RejectedByReason, SafetyInfo,
                                 Utilisation, WorldLost)


# --------------------------------------------------------------------------- the trace


@dataclass(frozen=True, eq=False)
class Trace:
    """A run's time series, one row per control tick (sampled after the controller's update;
    docs/metrics.md), as numpy arrays: T ticks, N vehicles (``ids``), E metric edges
    (``edge_names``, "<id_i>__<id_k>"). A vehicle not live at a tick (killed, paused) repeats
    its last row there; ``live`` says who stepped."""

    t: np.ndarray  # (T,) simulated s
    ids: tuple[str, ...]  # (N,) in scenario order
    q: np.ndarray  # (T, N, 3) position, m (a boat's z is 0)
    heading: np.ndarray  # (T, N) rad
    omega: np.ndarray  # (T, N) the path parameter ω, rad
    omega_rate: np.ndarray  # (T, N) ω̇, rad/s
    path_error: np.ndarray  # (T, N) |Φ_i|, m
    edge_names: tuple[str, ...]  # (E,)
    edge_error: np.ndarray  # (T, E) |ω_i - ω_k - Δ_ik|, rad
    live: np.ndarray  # (T, N) bool: stepping at that tick
    # (T, N) int: each vehicle's safety-filter interventions so far (None: a trace written before it was kept)
    interventions: np.ndarray | None = None

    def __post_init__(self) -> None:
        why = trace_shape_problem({k: getattr(self, k) for k in (*TRACE_ARRAYS, "interventions")},
                                  len(self.ids), len(self.edge_names))
        if why is not None:
            raise ValueError(f"trace: {why}")

    def __len__(self) -> int:
        return len(self.t)

    @classmethod
    def from_recorder(cls, rec: Recorder) -> "Trace":
        """A copy of a Recorder's series (cdus.core.metrics)."""
        return cls(t=rec.view("t").copy(), ids=tuple(rec.ids), q=rec.view("q").copy(),
                   heading=rec.view("heading").copy(), omega=rec.view("omega").copy(),
                   omega_rate=rec.view("omega_rate").copy(), path_error=rec.view("path_error").copy(),
                   edge_names=tuple(e.name for e in rec.edges), edge_error=rec.edge_error(),
                   live=rec.view("live").copy(), interventions=rec.view("interventions").copy())

    @classmethod
    def from_npz(cls, path: str | os.PathLike) -> "Trace":
        """Read a ``--trace-out`` file (``.npz``)."""
        arrays = read_trace(os.fspath(path))
        return cls(**arrays)

    def save(self, path: str | os.PathLike) -> None:
        """Write as ``--trace-out`` does (a compressed ``.npz``; :meth:`from_npz` reads it)."""
        np.savez_compressed(path, t=self.t, ids=np.array(self.ids), q=self.q, heading=self.heading,
                            omega=self.omega, omega_rate=self.omega_rate, path_error=self.path_error,
                            edge_error=self.edge_error, edge_names=np.array(self.edge_names), live=self.live,
                            **({} if self.interventions is None else {"interventions": self.interventions}))

    def to_dataframe(self):
        """A pandas DataFrame, one row per (tick, vehicle): ``t, vehicle, x, y, z, heading,
        omega, omega_rate, path_error, live`` and ``interventions`` when the trace has them
        (needs pandas: the ``api`` extra)."""
        pd = needs("pandas", "Trace.to_dataframe")
        T, N = len(self.t), len(self.ids)
        return pd.DataFrame({
            "t": np.repeat(self.t, N), "vehicle": pd.Categorical(np.tile(np.array(self.ids, dtype=object), T),
                                                                 categories=list(self.ids)),
            "x": self.q[:, :, 0].ravel(), "y": self.q[:, :, 1].ravel(), "z": self.q[:, :, 2].ravel(),
            "heading": self.heading.ravel(), "omega": self.omega.ravel(), "omega_rate": self.omega_rate.ravel(),
            "path_error": self.path_error.ravel(), "live": self.live.ravel(),
            **({} if self.interventions is None else {"interventions": self.interventions.ravel()}),
        })

    def edges_dataframe(self):
        """A pandas DataFrame, one row per (tick, metric edge): ``t, edge, error`` (rad)."""
        pd = needs("pandas", "Trace.edges_dataframe")
        T, E = len(self.t), len(self.edge_names)
        return pd.DataFrame({"t": np.repeat(self.t, E),
                             "edge": pd.Categorical(np.tile(np.array(self.edge_names, dtype=object), T),
                                                    categories=list(self.edge_names)),
                             "error": self.edge_error.ravel()})

    def to_xarray(self):
        """An xarray Dataset over dims ``t``, ``vehicle``, ``axis`` (x, y, z) and ``edge``, with
        units in each variable's attrs (needs xarray: the ``api`` extra)."""
        xr = needs("xarray", "Trace.to_xarray")
        tv = ("t", "vehicle")
        data = {
            "q": (("t", "vehicle", "axis"), self.q, {"units": "m", "long_name": "position"}),
            "heading": (tv, self.heading, {"units": "rad"}),
            "omega": (tv, self.omega, {"units": "rad", "long_name": "path parameter ω"}),
            "omega_rate": (tv, self.omega_rate, {"units": "rad/s", "long_name": "ω̇"}),
            "path_error": (tv, self.path_error, {"units": "m", "long_name": "|Φ_i|"}),
            "live": (tv, self.live, {"long_name": "stepping at that tick"}),
            "edge_error": (("t", "edge"), self.edge_error, {"units": "rad", "long_name": "|ω_i - ω_k - Δ_ik|"}),
        }
        if self.interventions is not None:
            data["interventions"] = (tv, self.interventions, {"long_name": "safety-filter interventions so far"})
        return xr.Dataset(data, coords={"t": ("t", self.t, {"units": "s"}), "vehicle": list(self.ids),
                                        "axis": ["x", "y", "z"], "edge": list(self.edge_names)})


@dataclass(frozen=True, eq=False)
class Result:
    """What :func:`run` returns: the scenario that ran, its metrics and its trace."""

    scenario: Scenario
    metrics: Metrics
    trace: Trace | None  # None only when a lockstep fleet's world died before writing it
    run_dir: Path | None = None  # a lockstep run's directory (logs, metrics.json, trace.npz) if one was given
    log: tuple[str, ...] = ()  # a lockstep run's launcher lines

"""How well does the fleet do? The metric definitions, the same in every clock mode.

(docs/metrics.md)
- path error of vehicle i: |Φ_i| = |q_i - f_i(ω_i)|, sampled at control instants after the
  controller's update;
- coordination error of edge (i, k): |ω_i - ω_k - Δ_ik|, Δ_ik the offset in force at that
  tick (a formation change moves it: cdus.core.formation);
- settle time: the first sample time after which the worst value stays below a tolerance
  for the rest of the run; None if it never does;
- ω̇ final: the mean rate over the last second, (ω(T) - ω(T - 1 s)) / 1 s;
- closest approach: per domain, the pair of vehicles that came closest, when, and whether
  both were live then; a vehicle that does not step (killed, paused) counts where it
  stopped (its row repeats its last state): a killed vehicle stays an obstacle where it died.

Pure: arrays in, numbers out. The recorder grows NumPy arrays row by row.
"""

from __future__ import annotations

import bisect
import math
import zipfile
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np

from cdus.core.graph import MetricEdge  # noqa: F401 (defined there: building a node needs no numpy)

METRICS_FIELDS = (
    "scenario", "mode", "seed", "duration_s", "path_tol", "coord_tol", "path_settle_s",
    "coord_settle_s", "final_path_error_max", "final_coord_error_max", "omega_rate_final",
    "link", "wall_s", "realtime_factor",
)


def edge_errors(omega: np.ndarray, edges: Sequence[MetricEdge], deltas: np.ndarray | None = None) -> np.ndarray:
    """|ω_i - ω_k - Δ_ik| for every edge; ``omega`` is (..., N); ``deltas`` (..., E): the Δs in
    force per row (default: each edge's own ``delta``)."""
    if not edges:
        return np.zeros(omega.shape[:-1] + (0,))
    i = np.array([e.i for e in edges])
    k = np.array([e.k for e in edges])
    d = np.array([e.delta for e in edges]) if deltas is None else deltas
    return np.abs(omega[..., i] - omega[..., k] - d)


def settle_time(t: np.ndarray, worst: np.ndarray, tol: float) -> float | None:
    """First sample time after which ``worst`` stays below ``tol`` to the end; None if never."""
    if len(t) == 0:
        return None
    above = np.nonzero(~(worst < tol))[0]  # NaN counts as not settled
    if len(above) == 0:
        return float(t[0])
    last = above[-1]
    return None if last + 1 >= len(t) else float(t[last + 1])


def percentile_ms(samples: Iterable[float], q: float) -> float | None:
    arr = np.asarray(list(samples), dtype=float)
    return None if arr.size == 0 else float(np.percentile(arr, q) * 1000.0)


class Recorder:
    """Time series of a run, one row per control instant."""

    def __init__(self, ids: Sequence[str], dims: Sequence[int], edges: Sequence[MetricEdge], capacity: int = 1024):
        self.ids = tuple(ids)
        self.dims = tuple(dims)
        self.edges = tuple(edges)
        n = len(ids)
        self._n = 0
        self._cap = max(16, capacity)
        self.t = np.zeros(self._cap)
        self.q = np.zeros((self._cap, n, 3))
        self.heading = np.zeros((self._cap, n))
        self.omega = np.zeros((self._cap, n))
        self.omega_rate = np.zeros((self._cap, n))
        self.path_error = np.zeros((self._cap, n))
        self.live = np.ones((self._cap, n), dtype=bool)  # stepping at that instant (not killed, not paused)
        #: per vehicle, control steps at which its safety filter intervened, summed over its
        #: processes, as the runner knew it when it recorded the row (docs/metrics.md)
        self.interventions = np.zeros((self._cap, n), dtype=np.int64)
        #: the fleet's phases over ticks and the control period (set_formation); None: the edges' Δs
        self.formation: Any = None
        self.period = 0.0

    def set_formation(self, schedule: Any, period: float) -> None:
        """Measure coordination against the offsets of ``schedule`` (a
        cdus.core.formation.FormationSchedule, the same object's data every runner holds), a row
        at time t being tick round(t / ``period``)."""
        self.formation = schedule
        self.period = period

    def deltas(self, lo: int = 0, hi: int | None = None) -> np.ndarray | None:
        """The Δ of every edge in force at rows [lo, hi) (rows x edges), None when no formation
        change applies to them (every edge's own ``delta``)."""
        f = self.formation
        hi = self._n if hi is None else min(hi, self._n)
        if f is None or not self.edges or hi <= lo or not f.changed_by(int(round(self.t[hi - 1] / self.period))):
            return None
        ticks = np.rint(self.t[lo:hi] / self.period).astype(np.int64)
        out = np.tile(np.array([e.delta for e in self.edges]), (hi - lo, 1))
        epochs = f.epochs()
        starts = [c for c, _ in epochs]
        # only the epochs the rows [lo, hi) fall in (rows are in tick order): the world's status
        # asks for its newest row every second, whatever the number of changes a ground station made
        first = max(0, bisect.bisect_right(starts, int(ticks.min())) - 1)
        last = bisect.bisect_right(starts, int(ticks.max()))
        for j in range(first, last):
            c, theta = epochs[j]
            rows = ticks >= c
            if j + 1 < len(starts):
                rows &= ticks < starts[j + 1]
            if rows.any():
                out[rows] = [theta[e.i] - theta[e.k] for e in self.edges]
        return out
    def __len__(self) -> int:
        return self._n

    def _grow(self) -> None:
        self._cap *= 2
        for name in ("t", "q", "heading", "omega", "omega_rate", "path_error", "live", "interventions"):
            old = getattr(self, name)
            new = np.zeros((self._cap,) + old.shape[1:], dtype=old.dtype)
            new[: self._n] = old[: self._n]
            setattr(self, name, new)

    def record(self, t: float, rows: Sequence[Any], live: Sequence[bool] | None = None,
               interventions: Sequence[int] | None = None) -> None:
        """``rows``: one telemetry per vehicle, in scenario order (attrs q, heading, omega, omega_rate,
        path_error); a vehicle not stepping (killed, paused) repeats its last row. ``live``: which
        vehicles step at this instant (default: all). ``interventions``: each vehicle's count of
        filter interventions so far (default: the previous row's)."""
        if self._n == self._cap:
            self._grow()
        n = self._n
        self.t[n] = t
        self.live[n] = True if live is None else live
        if interventions is not None:
            self.interventions[n] = interventions
        elif n:
            self.interventions[n] = self.interventions[n - 1]
        for j, tel in enumerate(rows):
            q = tel.q
            self.q[n, j, : len(q)] = q
            self.heading[n, j] = tel.heading
            self.omega[n, j] = tel.omega
            self.omega_rate[n, j] = tel.omega_rate
            self.path_error[n, j] = tel.path_error
        self._n += 1

    def view(self, name: str) -> np.ndarray:
        return getattr(self, name)[: self._n]

    def edge_error(self, lo: int = 0, hi: int | None = None) -> np.ndarray:
        """|ω_i - ω_k - Δ_ik| at rows [lo, hi), against the offsets in force at each row."""
        hi = self._n if hi is None else min(hi, self._n)
        return edge_errors(self.omega[lo:hi], self.edges, self.deltas(lo, hi))

    def worst_errors(self, start: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Per instant, the worst |Φ| over the live vehicles and the worst edge error over the
        edges whose two ends are live (0 where no edge has two live ends): a killed or paused
        vehicle's frozen ω and position are not the formation's error (docs/metrics.md). Where
        no vehicle at all is live both are NaN: nothing to call settled."""
        rows = max(0, len(self) - start)
        live = self.view("live")[start:]
        pe = np.where(live, self.view("path_error")[start:], 0.0)
        worst_path = pe.max(axis=1) if pe.size else np.zeros(rows)
        nobody = ~live.any(axis=1) if live.size else np.zeros(rows, dtype=bool)
        worst_path = np.where(nobody, np.nan, worst_path)
        ee = self.edge_error(start)
        if not ee.size:
            return worst_path, np.where(nobody, np.nan, 0.0)
        both = np.stack([live[:, e.i] & live[:, e.k] for e in self.edges], axis=1)
        return worst_path, np.where(nobody, np.nan, np.where(both, ee, 0.0).max(axis=1))

    def omega_rate_final(self, window: float = 1.0) -> dict[str, float | None]:
        t, w = self.view("t"), self.view("omega")
        if len(t) < 2:
            return {}
        j = int(np.searchsorted(t, t[-1] - window - 1e-9))
        j = min(j, len(t) - 2)
        dt = t[-1] - t[j]
        return {vid: _finite((w[-1, n] - w[j, n]) / dt) for n, vid in enumerate(self.ids)}

    def summary(self, *, scenario: str, mode: str, seed: int, path_tol: float, coord_tol: float,
                link: dict, wall_s: float) -> dict[str, Any]:
        """The metrics JSON (docs/metrics.md field names)."""
        t = self.view("t")
        pe = self.view("path_error")
        worst_path, worst_coord = self.worst_errors()
        duration = float(t[-1] - t[0]) if len(t) else 0.0
        return {
            "scenario": scenario,
            "mode": mode,
            "seed": seed,
            "duration_s": duration,
            "path_tol": path_tol,
            "coord_tol": coord_tol,
            "path_settle_s": settle_time(t, worst_path, path_tol),
            "coord_settle_s": settle_time(t, worst_coord, coord_tol),
            "final_path_error_max": _finite(worst_path[-1]) if len(t) else None,
            "final_coord_error_max": _finite(worst_coord[-1]) if len(t) else None,
            "omega_rate_final": self.omega_rate_final(),
            "final_path_error": {vid: _finite(pe[-1, n]) for n, vid in enumerate(self.ids)} if len(t) else {},
            "live_final": [vid for n, vid in enumerate(self.ids) if self.live[len(t) - 1, n]] if len(t) else [],
            "link": link,
            "wall_s": wall_s,
            "realtime_factor": (duration / wall_s) if wall_s > 0 else None,
        }

    def save_trace(self, path: str) -> None:
        """All series as a compressed ``.npz`` (``numpy.load`` reads it back)."""
        np.savez_compressed(
            path, t=self.view("t"), ids=np.array(self.ids), q=self.view("q"),
            heading=self.view("heading"), omega=self.view("omega"),
            omega_rate=self.view("omega_rate"), path_error=self.view("path_error"),
            edge_error=self.edge_error(), edge_names=np.array([e.name for e in self.edges]), live=self.view("live"),
            interventions=self.view("interventions"),
        )


TRACE_ARRAYS = ("t", "q", "heading", "omega", "omega_rate", "path_error", "edge_error", "live")


def trace_shape_problem(arrays: dict[str, Any], n_ids: int, n_edges: int) -> str | None:
    """Why the arrays of a trace (T ticks of ``n_ids`` vehicles and ``n_edges`` edges) do not fit
    together, or None. ``interventions`` may be None (a trace written before it was kept)."""
    T = len(arrays["t"])
    want = {"t": (T,), "q": (T, n_ids, 3), "heading": (T, n_ids), "omega": (T, n_ids),
            "omega_rate": (T, n_ids), "path_error": (T, n_ids), "edge_error": (T, n_edges), "live": (T, n_ids),
            "interventions": (T, n_ids)}
    for name, shape in want.items():
        a = arrays.get(name)
        if a is not None and a.shape != shape:
            return f"{name} has shape {a.shape}, expected {shape} ({T} ticks, {n_ids} vehicles, {n_edges} edges)"
    return None


def read_trace(path: Any) -> dict[str, Any]:
    """The arrays of a ``--trace-out`` file (:meth:`Recorder.save_trace`), checked: every one
    there, numeric (``ids`` and ``edge_names`` tuples of names), shapes that fit together, times
    finite. A file that is not such a trace (truncated, empty, a pickle, another archive) is a
    ValueError "PATH: not a cdus trace: why"; OSError (no such file, a directory) as it is."""
    where = str(path)
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):  # a plain .npy: one array
            raise ValueError("a single array, not an .npz archive")
        with z:
            missing = [k for k in (*TRACE_ARRAYS, "ids", "edge_names") if k not in z.files]
            if missing:
                raise ValueError(f"no {', '.join(missing)}")
            names = [*TRACE_ARRAYS, "ids", "edge_names"] + (["interventions"] if "interventions" in z.files else [])
            arrays = {k: z[k] for k in names}
    except (EOFError, zipfile.BadZipFile, ValueError, UnicodeError) as e:
        raise ValueError(f"{where}: not a cdus trace: {e}") from None
    for k, a in arrays.items():  # a member that is not a .npy comes back as bytes
        text = k in ("ids", "edge_names")
        if not isinstance(a, np.ndarray) or (a.ndim != 1 if text else a.ndim == 0 or a.dtype.kind not in "biuf"):
            what = type(a).__name__ if not isinstance(a, np.ndarray) else f"{a.ndim}-d {a.dtype}"
            raise ValueError(f"{where}: not a cdus trace: {k} is {what}, expected "
                             + ("a 1-d array of names" if text else "a numeric array"))
    arrays["ids"] = tuple(str(x) for x in arrays["ids"])
    arrays["edge_names"] = tuple(str(x) for x in arrays["edge_names"])
    arrays.setdefault("interventions", None)
    why = trace_shape_problem(arrays, len(arrays["ids"]), len(arrays["edge_names"]))
    if why is None and not np.all(np.isfinite(arrays["t"])):
        why = "t has a time that is not finite"
    if why is not None:
        raise ValueError(f"{where}: not a cdus trace: {why}")
    return arrays


def _finite(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def min_separation(q: np.ndarray, domains: Sequence[str]) -> float | None:
    """The smallest distance between two vehicles of the same domain over a run (m).

    ``q``: positions (ticks, vehicles, 3), a boat's z being 0; ``domains``: "usv" or "uav"
    per vehicle. Boats are compared on the water (x, y), drones in 3-D. None without a pair.
    """
    best = math.inf
    if q.shape[0] == 0:
        return None
    for j in range(len(domains)):
        for k in range(j + 1, len(domains)):
            if domains[j] != domains[k]:
                continue
            axes = 2 if domains[j] == "usv" else 3
            d = q[:, j, :axes] - q[:, k, :axes]
            best = min(best, float(np.sqrt(np.min(np.einsum("ij,ij->i", d, d)))))
    return best if math.isfinite(best) else None


#: the domain of a closest pair between a drone and a boat (the boat a point on the water)
CROSS_DOMAIN = "uav-usv"


@dataclass(frozen=True)
class ClosestPair:
    """The closest approach of a run within one domain: vehicles ``a`` and ``b`` (scenario
    order), ``distance`` m apart at simulated time ``t``; ``a_live``/``b_live``: whether each
    was stepping then (one that was not is counted where it stopped: killed or paused)."""

    domain: str  # "usv", "uav" or CROSS_DOMAIN
    a: str
    b: str
    distance: float
    t: float
    a_live: bool
    b_live: bool

    @property
    def both_live(self) -> bool:
        return self.a_live and self.b_live

    def as_dict(self) -> dict[str, Any]:
        """The metrics JSON entry (docs/metrics.md, ``closest_pairs``)."""
        return {"domain": self.domain, "a": self.a, "b": self.b, "distance_m": round(self.distance, 6),
                "t_s": round(self.t, 9), "a_live": self.a_live, "b_live": self.b_live, "both_live": self.both_live}


def closest_pairs(t: np.ndarray, q: np.ndarray, live: np.ndarray, ids: Sequence[str],
                  domains: Sequence[str]) -> dict[str, ClosestPair]:
    """The closest pair of each domain over a run, as :func:`min_separation` measures it
    (boats on the water in x, y; drones in 3-D), and, when the fleet has both kinds, of
    drone and boat (``CROSS_DOMAIN``: the drone in 3-D to the boat's point on the water,
    (x, y, 0), as a drone's filter sees a boat).

    ``t`` (ticks,), ``q`` (ticks, vehicles, 3), ``live`` (ticks, vehicles): the Recorder's
    rows, in which a vehicle not stepping repeats the row it stopped with, so a killed
    vehicle counts where it died. Non-finite distances (a diverged vehicle) are skipped. Ties
    go to the earlier time, then to the pair first in scenario order. A domain without a
    pair, or with no finite distance, is absent.
    """
    out: dict[str, ClosestPair] = {}
    if q.shape[0] == 0:
        return out
    n = len(domains)
    pairs: dict[str, list[tuple[int, int]]] = {}
    for j in range(n):  # scenario order: (j, k) lexicographic
        for k in range(j + 1, n):
            pairs.setdefault(domains[j] if domains[j] == domains[k] else CROSS_DOMAIN, []).append((j, k))
    for domain, jk in pairs.items():
        a, b = np.array(jk).T
        if domain == CROSS_DOMAIN:  # the drone in 3-D minus the boat at (x, y, 0)
            drone = np.where(np.asarray(domains)[a] == "uav", a, b)
            found = _closest(q, drone, np.where(drone == a, b, a), 3, second_on_surface=True)
        else:
            found = _closest(q, a, b, 2 if domain == "usv" else 3)
        if found is not None:
            d2, i, m = found
            out[domain] = ClosestPair(domain, ids[a[m]], ids[b[m]], math.sqrt(d2), float(t[i]), bool(live[i, a[m]]),
                                      bool(live[i, b[m]]))
    return out


#: (ticks x pairs) distances computed at once, at most: bounds the memory of a big fleet's run
_CHUNK = 1 << 20


def _closest(q: np.ndarray, first: np.ndarray, second: np.ndarray, axes: int,
             second_on_surface: bool = False) -> tuple[float, int, int] | None:
    """The smallest finite |q[first] - q[second]|² over the rows and the pairs, on the first
    ``axes`` axes (``second_on_surface``: ``second`` taken at z = 0): (d², row, pair), the
    earliest row and then the first pair on ties; None if nothing is finite."""
    step = max(1, _CHUNK // len(first))
    best: tuple[float, int, int] | None = None
    for r0 in range(0, q.shape[0], step):
        block = q[r0:r0 + step]
        with np.errstate(invalid="ignore", over="ignore"):  # inf - inf, a huge square: skipped below
            d2 = np.zeros((block.shape[0], len(first)))
            for k in range(axes):
                x = block[:, :, k]
                d = x[:, first] if k == 2 and second_on_surface else x[:, first] - x[:, second]
                d2 += d * d
        d2 = np.where(np.isfinite(d2), d2, np.inf)
        flat = int(np.argmin(d2))  # row-major: the earliest row, then the first pair
        r, m = divmod(flat, d2.shape[1])
        if math.isfinite(d2[r, m]) and (best is None or d2[r, m] < best[0]):
            best = (float(d2[r, m]), r0 + r, m)
    return best

"""Metric definitions: settle time, edge errors, the recorder, the summary and the trace."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from cdus.core.metrics import (
    METRICS_FIELDS, MetricEdge, Recorder, edge_errors, percentile_ms, settle_time,
)


# --------------------------------------------------------------------------- settle_time


def test_settle_time_never_above_is_the_first_sample():
    t = np.arange(0.0, 5.0, 0.5) + 2.0
    assert settle_time(t, np.full(len(t), 0.01), 0.05) == 2.0


def test_settle_time_ends_above_is_none():
    t = np.arange(10.0)
    worst = np.zeros(10)
    worst[-1] = 1.0
    assert settle_time(t, worst, 0.05) is None


def test_settle_time_typical():
    t = np.arange(0.0, 10.0, 1.0)
    worst = np.array([5.0, 3.0, 0.01, 0.2, 0.04, 0.03, 0.02, 0.01, 0.0, 0.0])
    # dips below at t=2 but goes back above at t=3: settles at t=4
    assert settle_time(t, worst, 0.05) == 4.0


def test_settle_time_equal_to_tol_is_not_settled():
    t = np.arange(4.0)
    assert settle_time(t, np.array([1.0, 0.05, 0.01, 0.01]), 0.05) == 2.0


def test_settle_time_nan_counts_as_not_settled():
    t = np.arange(6.0)
    worst = np.array([0.0, 0.0, np.nan, 0.0, 0.0, 0.0])
    assert settle_time(t, worst, 0.05) == 3.0
    worst[-1] = np.nan
    assert settle_time(t, worst, 0.05) is None


def test_settle_time_empty():
    assert settle_time(np.array([]), np.array([]), 0.1) is None


# --------------------------------------------------------------------------- edges


EDGES = (MetricEdge(0, 1, 0.5, "a__b"), MetricEdge(2, 0, -1.0, "c__a"))


def test_edge_errors_values_and_shapes():
    omega = np.array([[1.0, 0.5, 3.0], [10.0, 9.0, 9.0]])  # (T=2, N=3)
    ee = edge_errors(omega, EDGES)
    assert ee.shape == (2, 2)
    assert ee == pytest.approx(np.array([[0.0, 3.0], [0.5, 0.0]]))
    one = edge_errors(omega[0], EDGES)  # (N,) -> (E,)
    assert one == pytest.approx(np.array([0.0, 3.0]))


def test_edge_errors_without_edges():
    assert edge_errors(np.zeros((7, 3)), ()).shape == (7, 0)


def test_percentile_ms():
    assert percentile_ms([], 50) is None
    assert percentile_ms([0.001, 0.002, 0.003], 50) == pytest.approx(2.0)


# --------------------------------------------------------------------------- recorder


def _tel(q, omega, rate=-1.0, phi=0.0, heading=0.0):
    return SimpleNamespace(q=q, heading=heading, omega=omega, omega_rate=rate, path_error=phi)


def _recorded(n=300, T=0.02, capacity=16):
    """Three vehicles (two USVs, one UAV) moving at ω̇ = -1, -1, -0.5 from (0, 0.5, 3)."""
    rec = Recorder(["a", "b", "c"], [2, 2, 3], EDGES, capacity=capacity)
    for j in range(n):
        t = j * T
        rows = [
            _tel((t, 0.0), -t, phi=1.0 / (1 + t)),
            _tel((0.0, t), 0.5 - t, phi=0.5 / (1 + t)),
            _tel((1.0, 2.0, 20.0), 3.0 - 0.5 * t, rate=-0.5, phi=0.0),
        ]
        rec.record(t, rows)
    return rec


def test_recorder_grows_beyond_capacity_and_keeps_rows():
    rec = _recorded(n=300, capacity=16)
    assert len(rec) == 300
    t = rec.view("t")
    assert t.shape == (300,)
    assert t == pytest.approx(np.arange(300) * 0.02)
    q = rec.view("q")
    assert q.shape == (300, 3, 3)
    assert q[299, 0] == pytest.approx((299 * 0.02, 0.0, 0.0))  # a 2-D q is padded with 0
    assert q[17, 2] == pytest.approx((1.0, 2.0, 20.0))
    assert rec.view("omega")[0] == pytest.approx((0.0, 0.5, 3.0))
    assert rec.view("omega")[123, 2] == pytest.approx(3.0 - 0.5 * 123 * 0.02)


def test_recorder_edge_error():
    rec = _recorded(n=50)
    ee = rec.edge_error()
    assert ee.shape == (50, 2)
    # a - b = -0.5 always, Δ = 0.5: error 1.0; c - a = 3 + 0.5 t, Δ = -1: error 4 + 0.5 t
    assert ee[:, 0] == pytest.approx(np.full(50, 1.0))
    assert ee[:, 1] == pytest.approx(4.0 + 0.5 * rec.view("t"))


def test_omega_rate_final_is_the_mean_over_the_last_second():
    rec = Recorder(["a"], [2], (), capacity=16)
    T = 0.02
    for j in range(501):  # t = 0 .. 10 s; ω̇ = -1 up to 9 s, then -3 (with wiggles)
        t = j * T
        w = -t if t <= 9.0 else -9.0 - 3.0 * (t - 9.0) + 0.1 * math.sin(40 * t) * (t < 10.0 - 1e-9)
        rec.record(t, [_tel((0.0, 0.0), w, rate=123.0)])  # the reported rate is not used
    assert rec.omega_rate_final()["a"] == pytest.approx(-3.0, abs=1e-6)
    assert rec.omega_rate_final(window=10.0)["a"] == pytest.approx(-1.2, abs=1e-6)


def test_omega_rate_final_short_runs():
    rec = Recorder(["a", "b"], [2, 2], ())
    assert all(math.isnan(v) for v in rec.omega_rate_final().values())
    rec.record(0.0, [_tel((0, 0), 0.0), _tel((0, 0), 1.0)])
    rec.record(0.5, [_tel((0, 0), -1.0), _tel((0, 0), 1.0)])
    assert rec.omega_rate_final() == {"a": pytest.approx(-2.0), "b": pytest.approx(0.0)}


def test_summary_has_every_field():
    rec = _recorded(n=300)
    link = {"sent": 10, "delivered": 9}
    s = rec.summary(scenario="lake", mode="inprocess", seed=7, path_tol=0.1, coord_tol=0.05,
                    link=link, wall_s=2.0)
    for name in METRICS_FIELDS:
        assert name in s, name
    assert s["scenario"] == "lake" and s["mode"] == "inprocess" and s["seed"] == 7
    assert s["duration_s"] == pytest.approx(299 * 0.02)
    assert s["realtime_factor"] == pytest.approx(299 * 0.02 / 2.0)
    assert s["link"] == link
    # worst path error 1/(1+t) < 0.1 from t > 9: never within 6 s
    assert s["path_settle_s"] is None
    assert s["final_path_error_max"] == pytest.approx(1.0 / (1 + 299 * 0.02))
    assert s["final_coord_error_max"] == pytest.approx(4.0 + 0.5 * 299 * 0.02)
    assert s["omega_rate_final"] == {"a": pytest.approx(-1.0), "b": pytest.approx(-1.0),
                                     "c": pytest.approx(-0.5)}
    assert set(s["final_path_error"]) == {"a", "b", "c"}


def test_summary_settle_times_and_non_finite():
    rec = Recorder(["a", "b"], [2, 2], (MetricEdge(0, 1, 0.0, "a__b"),))
    for j in range(20):
        t = float(j)
        rec.record(t, [_tel((0, 0), 0.0, phi=max(0.0, 1.0 - 0.1 * t)),
                       _tel((0, 0), 0.3 if j < 12 else 0.01, phi=0.0)])
    s = rec.summary(scenario="x", mode="lockstep", seed=0, path_tol=0.15, coord_tol=0.05,
                    link={}, wall_s=0.0)
    assert s["path_settle_s"] == 9.0  # 1 - 0.1 t < 0.15 from t = 9
    assert s["coord_settle_s"] == 12.0
    assert s["realtime_factor"] is None
    rec.record(20.0, [_tel((0, 0), 0.0, phi=math.nan), _tel((0, 0), 0.0)])
    s = rec.summary(scenario="x", mode="lockstep", seed=0, path_tol=0.1, coord_tol=0.05,
                    link={}, wall_s=1.0)
    assert s["path_settle_s"] is None
    assert s["final_path_error"]["a"] is None  # NaN reported as null, JSON-safe


def test_save_trace_loads_back_with_numpy(tmp_path):
    rec = _recorded(n=40)
    out = tmp_path / "trace.npz"
    rec.save_trace(str(out))
    with np.load(out) as data:
        assert set(data.files) >= {"t", "ids", "q", "heading", "omega", "omega_rate",
                                   "path_error", "edge_error", "edge_names"}
        assert data["t"] == pytest.approx(rec.view("t"))
        assert data["q"].shape == (40, 3, 3)
        assert data["omega"] == pytest.approx(rec.view("omega"))
        assert data["edge_error"] == pytest.approx(rec.edge_error())
        assert list(data["ids"]) == ["a", "b", "c"]
        assert list(data["edge_names"]) == ["a__b", "c__a"]

"""Fading and shadowing (cdus/core/fading.py, docs/radio.md): their moments and correlations
over independent streams, within bounds set by the sample size (tests/core/test_radio.py's
z_bound: a normal bound at a Bonferroni-corrected alpha)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cdus.core.fading import ShadowField, fading_gain, fading_grid, fading_mean
from cdus.core.link import stream_key
from tests.core.test_radio import z_bound


def field_values(n: int, sigma: float, points) -> np.ndarray:
    """Shadowing of n independent links (one seed each) at each point x (the field's input)."""
    out = np.empty((n, len(points)))
    for i in range(n):
        f = ShadowField(stream_key(i, "a", "b", "radio-shadow"), sigma)
        for j, x in enumerate(points):
            out[i, j] = f(np.asarray(x, dtype=float))
    return out


def test_shadowing_mean_variance_and_correlation_in_space_and_time():
    """Over independent links: mean 0, variance σ², corr(Δ) = exp(-|Δ|) in the scaled input
    (Gudmundson's exp(-Δd/D) for one end moving Δd, exp(-Δt/T) in time)."""
    n, sigma = 3000, 6.0
    base = np.array([0.3, -1.2, 0.02, 2.0, 0.5, 0.04, 7.0])
    moves = {"one end 0.5 D": (0, 0.5), "one end 1 D": (1, 1.0), "other end 2 D": (4, 2.0),
             "time 0.25 T": (6, 0.25), "time 1 T": (6, 1.0)}
    points = [base] + [base + np.eye(7)[axis] * step for axis, step in moves.values()]
    v = field_values(n, sigma, points)
    z = z_bound(2 + len(moves))
    x0 = v[:, 0]
    assert abs(x0.mean()) <= z * sigma / math.sqrt(n)
    m4 = np.mean((x0 - x0.mean()) ** 4)
    assert abs(x0.var() - sigma ** 2) <= z * math.sqrt((m4 - x0.var() ** 2) / n)
    for j, (name, (axis, step)) in enumerate(moves.items(), start=1):
        r = np.corrcoef(x0, v[:, j])[0, 1]
        rho = math.exp(-step)
        # Fisher's z: atanh(r) ~ N(atanh(ρ), 1/(n - 3))
        assert abs(math.atanh(r) - math.atanh(rho)) <= z / math.sqrt(n - 3), (name, r, rho)


@pytest.mark.parametrize("kind,param", [("rician", 0.0), ("rician", 3.0), ("rician", 10.0), ("nakagami", 0.6),
                                        ("nakagami", 1.0), ("nakagami", 2.5)])
def test_fading_moments(kind, param):
    """E[g] = 1; Var[g] = (1 + 2K)/(1 + K)² (Rician), 1/m (Nakagami); the quadrature weights
    give the same two moments."""
    n = 20000
    k, m = (param, 1.0) if kind == "rician" else (10.0, param)
    key = stream_key(3, "a", "b", "radio-fading")
    g = np.array([fading_gain(kind, k, m, key, s) for s in range(n)])
    var = (1 + 2 * k) / (1 + k) ** 2 if kind == "rician" else 1.0 / m
    z = z_bound(2)
    assert abs(g.mean() - 1.0) <= z * math.sqrt(var / n)
    d2 = (g - g.mean()) ** 2
    assert abs(g.var() - var) <= z * d2.std() / math.sqrt(n)
    assert fading_mean(fading_grid(), kind, k, m) == pytest.approx(1.0, abs=1e-4)
    assert fading_mean(fading_grid() ** 2, kind, k, m) - 1.0 == pytest.approx(var, rel=1e-3, abs=1e-4)

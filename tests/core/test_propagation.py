"""The path loss between two antennas (cdus/core/propagation.py, docs/radio.md): free space,
and the exact two-ray loss over water against the field written out independently."""

from __future__ import annotations

import cmath
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdus.core.propagation import C_LIGHT, free_space_db, two_ray_loss_db, water_permittivity
from cdus.core.reception import per_from_snr


@pytest.mark.parametrize("d", [1.0, 10.0, 100.0, 1000.0])
def test_free_space_is_friis(d):
    f = 2.4e9
    lam = C_LIGHT / f
    assert free_space_db(d, f) == pytest.approx(-10 * math.log10((lam / (4 * math.pi * d)) ** 2), abs=1e-9)


def two_ray_reference(d: float, ht: float, hr: float, f: float, er: float, sigma: float, pol: str) -> float:
    """The two-ray field written out independently: direct and reflected complex amplitudes."""
    lam = C_LIGHT / f
    k = 2 * math.pi / lam
    r1 = math.sqrt(d * d + (ht - hr) ** 2)
    r2 = math.sqrt(d * d + (ht + hr) ** 2)
    psi = math.atan2(ht + hr, d)
    eps = er - 1j * sigma / (2 * math.pi * f * 8.8541878128e-12)
    root = cmath.sqrt(eps - math.cos(psi) ** 2)
    if pol == "horizontal":
        gamma = (math.sin(psi) - root) / (math.sin(psi) + root)
    else:
        gamma = (eps * math.sin(psi) - root) / (eps * math.sin(psi) + root)
    field = cmath.exp(-1j * k * r1) / r1 + gamma * cmath.exp(-1j * k * r2) / r2
    return -20 * math.log10(lam / (4 * math.pi) * abs(field))


@pytest.mark.parametrize("pol", ["vertical", "horizontal"])
@pytest.mark.parametrize("d,ht,hr", [(5.0, 1.0, 1.0), (50.0, 1.0, 1.0), (217.0, 1.0, 1.0), (800.0, 1.0, 1.5),
                                     (120.0, 30.0, 1.0), (2000.0, 10.0, 1.0)])
@pytest.mark.parametrize("water", [(80.0, 0.01), (70.0, 4.0)])
def test_two_ray_at_known_distances(pol, d, ht, hr, water):
    f = 5.18e9
    eps = water_permittivity(water[0], water[1], f)
    got = two_ray_loss_db(d, ht, hr, f, eps, pol, 1.0)
    assert got == pytest.approx(two_ray_reference(d, ht, hr, f, water[0], water[1], pol), abs=1e-6)


def test_two_ray_far_field_is_the_crossover_form():
    """Beyond the crossover 4π ht hr / λ the loss tends to 40 log d - 20 log(ht hr) (Γ -> -1)."""
    f, ht, hr = 5.18e9, 1.0, 1.0
    eps = water_permittivity(80.0, 0.01, f)
    crossover = 4 * math.pi * ht * hr * f / C_LIGHT
    for mult in (20.0, 50.0, 100.0):
        d = mult * crossover
        assert two_ray_loss_db(d, ht, hr, f, eps, "horizontal") == pytest.approx(
            40 * math.log10(d) - 20 * math.log10(ht * hr), abs=0.2)


@given(st.floats(1.0, 5000.0), st.floats(0.0, 50.0), st.floats(0.0, 50.0))
@settings(max_examples=200, deadline=None)
def test_two_ray_never_beats_free_space_by_more_than_6_db(d, ht, hr):
    """|1/r1 + Γ e^{..}/r2| <= 2/r1 (|Γ| <= 1), so the loss is at least free space at r1 - 6.02 dB."""
    f = 5.18e9
    got = two_ray_loss_db(d, ht, hr, f, water_permittivity(80.0, 0.01, f), "vertical", 1.0)
    r1 = max(math.hypot(d, max(ht, 0.01) - max(hr, 0.01)), 1.0)
    assert got >= free_space_db(r1, f) - 20 * math.log10(2.0) - 1e-9


def test_two_ray_near_field_is_evaluated_where_the_direct_path_is_d0():
    f = 5.18e9
    eps = water_permittivity(80.0, 0.01, f)
    at_d0 = two_ray_loss_db(1.0, 1.0, 1.0, f, eps)
    assert two_ray_loss_db(0.0, 1.0, 1.0, f, eps) == at_d0 == two_ray_loss_db(1e-300, 1.0, 1.0, f, eps)
    assert two_ray_loss_db(0.2, 1.0, 1.5, f, eps) == pytest.approx(two_ray_reference(math.sqrt(0.75), 1.0, 1.5, f, 80.0,
                                                                                     0.01, "vertical"), abs=1e-9)
    assert math.isfinite(per_from_snr(float("nan"), 10)) and per_from_snr(float("nan"), 10) == 1.0
    assert per_from_snr(1e6, 10) == 0.0

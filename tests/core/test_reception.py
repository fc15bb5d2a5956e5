"""The bit and packet error rates at an SNR (cdus/core/reception.py, docs/radio.md)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdus.core.reception import ber, erfc_vec, per_curve, per_from_snr


def test_ber_at_textbook_points():
    ebn0 = 10 ** (9.6 / 10)  # BPSK reaches 1e-5 at 9.6 dB
    assert ber(ebn0, "bpsk") == pytest.approx(0.5 * math.erfc(math.sqrt(ebn0)), rel=1e-12)
    assert 0.9e-5 < ber(ebn0, "bpsk") < 1.1e-5
    assert ber(ebn0, "qpsk") == ber(ebn0, "bpsk")
    x = 10 ** (10.0 / 10)
    assert ber(x, "16qam") == pytest.approx(3 / 8 * math.erfc(math.sqrt(0.4 * x)), rel=1e-12)
    assert ber(x, "64qam") == pytest.approx(7 / 24 * math.erfc(math.sqrt(x / 7)), rel=1e-12)
    assert ber(0.0, "bpsk") == 0.5


def test_per_is_one_minus_bit_survival():
    snr, size = 3.0, 96
    b = ber(10 ** (snr / 10) * 20e6 / 6e6, "bpsk")
    assert per_from_snr(snr, size, "bpsk", 20e6, 6e6) == pytest.approx(1 - (1 - b) ** (8 * size), rel=1e-12)


def test_vector_erfc_and_per_curve_agree_with_math():
    x = np.linspace(0.0, 8.0, 401)
    exact = np.array([math.erfc(v) for v in x])
    assert np.all(np.abs(erfc_vec(x) - exact) <= 1.2e-7 * exact + 1e-300)
    snr = np.linspace(-10, 20, 61)
    for mod in ("bpsk", "16qam"):
        curve = per_curve(snr, 96, mod, 20e6, 6e6)
        scalar = np.array([per_from_snr(s, 96, mod, 20e6, 6e6) for s in snr])
        assert np.all(np.abs(curve - scalar) <= 1e-6)


@given(st.sampled_from(["bpsk", "qpsk", "16qam", "64qam"]), st.floats(-30.0, 40.0), st.floats(0.0, 10.0),
       st.integers(1, 2000), st.integers(0, 2000))
@settings(max_examples=300, deadline=None)
def test_per_is_monotone_in_snr_and_size(mod, snr, dsnr, size, dsize):
    p = per_from_snr(snr, size, mod)
    assert 0.0 <= p <= 1.0
    assert per_from_snr(snr + dsnr, size, mod) <= p + 1e-15  # more SNR, fewer errors
    assert per_from_snr(snr, size + dsize, mod) >= p - 1e-15  # a longer message, more errors

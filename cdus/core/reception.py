"""Is a message received at this SNR? The bit error rate of the modulation, the packet error
rate of a message of this size, and how long the message holds the air (docs/radio.md,
"Reception").

Pure: the per-message decisions use ``math``; the array forms (for the delivery probability
averaged over the fading) numpy, imported where it is used.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is imported where it is used: an agent without [radio] loads none
    import numpy as np


def q_function(x: float) -> float:
    """Q(x) = P(N(0, 1) > x) = erfc(x / √2) / 2."""
    return 0.5 * math.erfc(x / math.sqrt(2.0))


def ber(ebn0: float, modulation: str) -> float:
    """Bit error rate at Eb/N0 = ``ebn0`` (linear), coherent detection, Gray coding, uncoded:
    bpsk, qpsk: Q(√(2 Eb/N0)); M-QAM: (4/k)(1 - 1/√M) Q(√(3k/(M-1) Eb/N0)), k = log2 M
    (the nearest-neighbour approximation); at most 1/2."""
    if ebn0 <= 0.0:
        return 0.5
    scale, factor = _ber_form(modulation)
    return min(scale * q_function(math.sqrt(factor * ebn0)), 0.5)


def _ber_form(modulation: str) -> tuple[float, float]:
    """(a, b) of the modulation's bit error rate a Q(√(b Eb/N0)): bpsk, qpsk (1, 2); M-QAM
    ((4/k)(1 - 1/√M), 3k/(M-1)), k = log2 M."""
    if modulation in ("bpsk", "qpsk"):
        return 1.0, 2.0
    m = 16 if modulation == "16qam" else 64
    kb = math.log2(m)
    return (4.0 / kb) * (1.0 - 1.0 / math.sqrt(m)), 3.0 * kb / (m - 1)


def per_from_snr(snr_db: float, size_bytes: int, modulation: str = "bpsk", bandwidth: float = 20.0e6,
                 rate: float = 6.0e6) -> float:
    """Packet error rate: 1 - (1 - BER)^(8 · size), BER at Eb/N0 = SNR · bandwidth / rate (the
    SNR is measured over ``bandwidth``, the bits come at ``rate``)."""
    if not snr_db > -300.0:  # also nan: no signal
        return 1.0 if size_bytes > 0 else 0.0
    ebn0 = 10.0 ** (min(snr_db, 300.0) / 10.0) * bandwidth / rate
    b = ber(ebn0, modulation)
    if b <= 0.0:
        return 0.0
    if b >= 0.5 and size_bytes > 0:
        return -math.expm1(8 * size_bytes * math.log1p(-0.5))
    return -math.expm1(8 * size_bytes * math.log1p(-b))


def erfc_vec(x: np.ndarray) -> np.ndarray:
    """erfc over an array (x >= 0), relative error < 1.2e-7 (Numerical Recipes' erfcc, a
    Chebyshev fit); the per-message decisions use math.erfc."""
    import numpy as np

    z = np.abs(x)
    t = 1.0 / (1.0 + 0.5 * z)
    poly = -z * z - 1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 + t * (
        -0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 + t * (-0.82215223 + t * 0.17087277))))))))
    r = t * np.exp(poly)
    return np.where(x >= 0.0, r, 2.0 - r)


def _q_vec(x: np.ndarray) -> np.ndarray:
    return 0.5 * erfc_vec(x / math.sqrt(2.0))


def per_curve(snr_db: np.ndarray, size_bytes: int, modulation: str, bandwidth: float, rate: float) -> np.ndarray:
    """:func:`per_from_snr` over an array of SNRs (dB)."""
    import numpy as np

    ebn0 = 10.0 ** (np.clip(np.nan_to_num(snr_db, nan=-300.0), -300.0, 300.0) / 10.0) * bandwidth / rate
    scale, factor = _ber_form(modulation)
    b = np.minimum(scale * _q_vec(np.sqrt(factor * ebn0)), 0.5)
    return -np.expm1(8 * size_bytes * np.log1p(-b))


def airtime(size_bytes: int, capacity: float, preamble: float) -> float:
    """Seconds one message holds the medium: preamble + 8 · size / capacity."""
    return preamble + 8.0 * size_bytes / capacity

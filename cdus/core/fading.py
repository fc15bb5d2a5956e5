"""How much do fading and shadowing change a link's signal? The per-message fading gain
(Rician, Nakagami) drawn from a link's random stream, its average over the gains, and the
shadowing of a link as a random field of the antenna positions and the time (docs/radio.md,
"Shadowing and fading").

Pure: every draw is :func:`cdus.core.link.uniform` of a stream at a fixed index, in plain
float arithmetic and ``math`` (the same bits in every process); numpy only for the
quadrature of the fading's average, imported where it is used.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

from cdus.core.link import uniform

if TYPE_CHECKING:  # numpy is imported where it is used: an agent without [radio] loads none
    import numpy as np

FEATURES = 64  # random Fourier features of the shadowing field


def normal_pair(u1: float, u2: float) -> tuple[float, float]:
    """Two independent N(0, 1) from two uniforms in [0, 1) (Box-Muller)."""
    r = math.sqrt(-2.0 * math.log(1.0 - u1))
    a = 2.0 * math.pi * u2
    return r * math.cos(a), r * math.sin(a)


def fading_gain(fading: str, k_factor: float, m: float, key: int, seq: int) -> float:
    """One power gain |h|² of mean 1 for message ``seq`` of the stream ``key``.

    rician: h = √(K/(K+1)) + √(1/(K+1)) · CN(0, 1) (a line-of-sight part and a scattered one);
    nakagami: |h|² ~ Gamma(m, 1/m), drawn by Marsaglia-Tsang (2000) from the uniforms
    ``key`` at 64 seq + j, j < 64 (for m < 1: Gamma(m + 1) · U^(1/m)). none: 1.
    """
    if fading == "rician":
        z1, z2 = normal_pair(uniform(key, 2 * seq), uniform(key, 2 * seq + 1))
        s = math.sqrt(1.0 / (2.0 * (k_factor + 1.0)))
        re = math.sqrt(k_factor / (k_factor + 1.0)) + s * z1
        return re * re + (s * z2) ** 2
    if fading == "nakagami":
        return gamma_draw(m, key, seq) / m
    return 1.0


def gamma_draw(shape: float, key: int, seq: int) -> float:
    """Gamma(shape, 1) from the uniforms of ``key`` at 64 seq + j (Marsaglia & Tsang 2000)."""
    base = 64 * seq
    j = 0
    boost = 1.0
    a = shape
    if a < 1.0:
        boost = uniform(key, base + 63) ** (1.0 / a)
        a += 1.0
    d = a - 1.0 / 3.0
    c = 1.0 / math.sqrt(9.0 * d)
    while j < 60:
        z, _ = normal_pair(uniform(key, base + j), uniform(key, base + j + 1))
        u = uniform(key, base + j + 2)
        j += 3
        v = 1.0 + c * z
        if v <= 0.0:
            continue
        v = v * v * v
        if math.log(1.0 - u) < 0.5 * z * z + d - d * v + d * math.log(v):
            return d * v * boost
    return d * boost  # 20 rejections in a row: P < 1e-25


def fading_mean(f: np.ndarray, fading: str, k_factor: float, m: float) -> float:
    """E[f(g)] over the power gain g of the fading, f given on :data:`FADING_GRID` (trapezoid in
    ln g; the density vanishes past the grid's ends for K <= 100, m >= 0.5)."""
    import numpy as np

    w = _fading_weights(fading, k_factor, m)
    return float(np.dot(w, f))


_GRID: list = []  # FADING_GRID, made when first needed (numpy is imported only by a [radio] run)


def fading_grid() -> np.ndarray:
    """The power gains of the fading quadrature: 3,001 points, log-spaced from 1e-12 to 60."""
    if not _GRID:
        import numpy as np

        _GRID.append(np.exp(np.linspace(math.log(1e-12), math.log(60.0), 3001)))
    return _GRID[0]


def _LOG10_GRID():
    """log10 of the fading grid (dB / 10 of every gain), made once."""
    if len(_GRID) < 2:
        import numpy as np

        _GRID.append(np.log10(fading_grid()))
    return _GRID[1]


def __getattr__(name: str):  # FADING_GRID, as it was a module constant
    if name == "FADING_GRID":
        return fading_grid()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


_WEIGHTS: dict[tuple, np.ndarray] = {}


def _fading_weights(fading: str, k_factor: float, m: float) -> np.ndarray:
    key = (fading, k_factor, m)
    w = _WEIGHTS.get(key)
    if w is not None:
        return w
    import numpy as np

    g = fading_grid()
    if fading == "rician":
        kk = k_factor
        z = 2.0 * np.sqrt(kk * (kk + 1.0) * g)
        # ln I0(z) = z + ln(i0e(z)); numpy's i0 overflows past ~700, so use the scaled form
        big = np.maximum(z, 700.0)
        log_i0 = np.where(z < 700.0, np.log(np.i0(np.minimum(z, 700.0))), big - 0.5 * np.log(2.0 * np.pi * big))
        logpdf = math.log(kk + 1.0) - kk - (kk + 1.0) * g + log_i0
    else:
        logpdf = m * math.log(m) - math.lgamma(m) + (m - 1.0) * np.log(g) - m * g
    dens = np.exp(logpdf) * g  # density in ln g
    h = np.diff(np.log(g))
    w = np.zeros_like(g)
    w[:-1] += 0.5 * h * dens[:-1]
    w[1:] += 0.5 * h * dens[1:]
    w /= w.sum()  # the grid holds all but < 1e-9 of the mass; renormalised
    _WEIGHTS[key] = w
    return w


class ShadowField:
    """Log-normal shadowing of one (unordered) link as a Gaussian random field, in dB.

    S(x) = σ √(2/M) Σ_m cos(w_m · x + φ_m), M = :data:`FEATURES`, x = (p_a / D, p_b / D, t / T)
    (the two antenna positions, the sample time; D = shadowing_distance, T = shadowing_time,
    an infinite scale drops its coordinates), w_m = Z_m / |g_m| (Z_m ~ N(0, I_7), g_m ~ N(0, 1):
    the 7-D Cauchy law, whose characteristic function is exp(-|Δ|)) and φ_m ~ U(0, 2π). Over
    the draws of the features: mean 0, variance σ², correlation exp(-√((Δd/D)² + (Δt/T)²)) with
    Δd² = |Δp_a|² + |Δp_b|² (Gudmundson's exp(-Δd/D) when one end moves); close to Gaussian
    (excess kurtosis -1.5/M). The features are drawn once from the link's own stream.
    """

    __slots__ = ("w", "phi", "amp")

    def __init__(self, key: int, sigma: float):
        w = []
        for i in range(FEATURES):
            z = []
            for j in range(4):
                z.extend(normal_pair(uniform(key, 8 * i + 2 * j), uniform(key, 8 * i + 2 * j + 1)))
            g = max(abs(z[7]), 1e-12)  # |w| < 1e13: w · x stays finite (P(|g| < 1e-12) ~ 1e-12)
            w.append(tuple(zk / g for zk in z[:7]))
        self.w = tuple(w)
        self.phi = tuple(2.0 * math.pi * uniform(key, 8 * FEATURES + i) for i in range(FEATURES))
        self.amp = sigma * math.sqrt(2.0 / FEATURES)

    def __call__(self, x: Sequence[float]) -> float:
        """S(x), in plain float arithmetic and math.cos (no BLAS, no SIMD paths: the same bits
        in every process)."""
        x0, x1, x2, x3, x4, x5, x6 = (float(v) for v in x)
        total = 0.0
        for (w0, w1, w2, w3, w4, w5, w6), phi in zip(self.w, self.phi):
            total += math.cos(w0 * x0 + w1 * x1 + w2 * x2 + w3 * x3 + w4 * x4 + w5 * x5 + w6 * x6 + phi)
        return self.amp * total

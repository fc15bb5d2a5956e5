"""How much signal does the path between two antennas lose? Free-space, log-distance and the
exact two-ray loss over water (docs/radio.md, "Propagation"); no shadowing, no fading.

Pure: plain float arithmetic and ``math`` (numpy's complex square root for the Fresnel
coefficient, imported where it is used).
"""

from __future__ import annotations

import math

C_LIGHT = 299_792_458.0  # m/s
EPSILON_0 = 8.8541878128e-12  # F/m
MIN_HEIGHT = 0.01  # m: an antenna at or below the water is taken 1 cm above it (two-ray needs h > 0)


def free_space_db(d: float, frequency: float) -> float:
    """Friis free-space loss (dB) at distance d (m): 20 log10(4π d f / c)."""
    return 20.0 * math.log10(4.0 * math.pi * d * frequency / C_LIGHT)


def path_loss_db(d: float, exponent: float, d0: float, pl0: float) -> float:
    """Log-distance loss (dB): PL0 + 10 n log10(d / d0), d taken as d0 below d0."""
    return pl0 + 10.0 * exponent * math.log10(max(d, d0) / d0)


def reflection_coefficient(sin_psi: float, cos_psi: float, eps: complex, polarization: str) -> complex:
    """Fresnel reflection coefficient of a flat surface of complex relative permittivity ``eps``
    at grazing angle ψ: Γ_h = (sin ψ - √(ε - cos²ψ)) / (sin ψ + √(ε - cos²ψ)),
    Γ_v = (ε sin ψ - √(ε - cos²ψ)) / (ε sin ψ + √(ε - cos²ψ))."""
    import numpy as np  # here, not at the top: an agent without [radio] loads no numpy (tests/vehicle_agent)

    root = complex(np.sqrt(complex(eps - cos_psi * cos_psi)))
    if polarization == "horizontal":
        return (sin_psi - root) / (sin_psi + root)
    return (eps * sin_psi - root) / (eps * sin_psi + root)


def water_permittivity(permittivity: float, conductivity: float, frequency: float) -> complex:
    """ε_c = ε_r - j σ / (2π f ε0) (≈ ε_r - j 60 σ λ)."""
    return complex(permittivity, -conductivity / (2.0 * math.pi * frequency * EPSILON_0))


def two_ray_loss_db(d: float, ht: float, hr: float, frequency: float, eps: complex,
                    polarization: str = "vertical", d_min: float = 1.0) -> float:
    """The exact two-ray loss (dB) over a flat reflecting surface, isotropic antennas:

        PL = -20 log10( λ/(4π) · | 1/r1 + Γ(ψ) e^{-j k (r2 - r1)} / r2 | )

    with r1 = √(d² + (ht - hr)²) the direct path, r2 = √(d² + (ht + hr)²) the reflected one,
    k = 2π/λ, ψ the grazing angle (sin ψ = (ht + hr)/r2) and Γ the Fresnel coefficient of the
    surface. d (m) is the horizontal distance, ht, hr (m) the heights above the surface
    (at least MIN_HEIGHT); with r1 < ``d_min`` (the near field) it is evaluated at the
    horizontal distance where r1 = d_min. Far beyond the
    crossover 4π ht hr / λ, Γ -> -1 and PL -> 40 log10 d - 20 log10(ht hr).
    """
    ht, hr = max(ht, MIN_HEIGHT), max(hr, MIN_HEIGHT)
    lam = C_LIGHT / frequency
    r1 = math.hypot(d, ht - hr)
    r2 = math.hypot(d, ht + hr)
    if r1 < d_min:  # inside the near field: evaluated where the direct path is d_min long
        d = math.sqrt(d_min * d_min - (ht - hr) ** 2)
        r1, r2 = d_min, math.hypot(d, ht + hr)
    dr = 4.0 * ht * hr / (r1 + r2)  # r2 - r1 without cancellation
    gamma = reflection_coefficient((ht + hr) / r2, d / r2, eps, polarization)
    k = 2.0 * math.pi / lam
    total = 1.0 / r1 + gamma * complex(math.cos(k * dr), -math.sin(k * dr)) / r2
    mag = abs(total) * lam / (4.0 * math.pi)
    return -20.0 * math.log10(mag) if mag > 0.0 else math.inf

"""Does a message get through the radio? A channel model from the geometry (docs/radio.md).

The ``[radio]`` table (built by :mod:`cdus.scenario.radio` into a :class:`RadioSpec`)
decides each message on top of the hand-set link faults: the path loss between the two
antennas (log-distance, or the exact two-ray model over water), log-normal shadowing
correlated in space and time, optional Rician or Nakagami fading per message, a packet
error rate from the SNR, the modulation and the message's size, and a shared medium
(airtime, offered load, collisions, queueing). Topology ``adhoc`` (vehicle to vehicle) or
``station`` (every message relayed by a base station: both legs can lose it).

Determinism. Nothing here keeps state that depends on the order of the calls: every random
draw is :func:`cdus.core.link.uniform` of a stream keyed by (seed, link, purpose) at the
message's seq (fading, PER, collision, queue) or a fixed index (the shadowing field's
features, drawn once per link). The shadowing is a random field, a pure function of the
link's end positions and the sample time (random Fourier features of the exponential
kernel), so a decision is a pure function of (seed, src, dst, seq, geometry, the epoch in
force at t_send). Caches hold values of pure functions only.

Pure: no I/O, no clocks. Everything a decision depends on is plain float arithmetic and
``math`` (the same bits in every process); numpy only averages the fading for the delivery
probability.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Iterable, Sequence

from cdus.core.link import stream_key, uniform
from cdus.core.vocabulary import KINDS, RADIO_CAUSES
from cdus.wire.messages import OmegaMsg, encode_omega

if TYPE_CHECKING:  # numpy is imported where it is used: an agent without [radio] loads none
    import numpy as np

C_LIGHT = 299_792_458.0  # m/s
EPSILON_0 = 8.8541878128e-12  # F/m
THERMAL_DBM_HZ = -174.0  # kT at 290 K, dBm/Hz
STATION = "station"  # the base station's name in the random streams and the counters
PROPAGATIONS = ("log_distance", "two_ray")
TOPOLOGIES = ("adhoc", "station")
FADINGS = ("none", "rician", "nakagami")
MODULATIONS = ("bpsk", "qpsk", "16qam", "64qam")
POLARIZATIONS = ("vertical", "horizontal")
ACCESSES = ("csma", "aloha")
MIN_HEIGHT = 0.01  # m: an antenna at or below the water is taken 1 cm above it (two-ray needs h > 0)
FEATURES = 64  # random Fourier features of the shadowing field
DEFAULT_RATE = 50.0  # Hz: the default [rates] broadcast
MAX_CACHED = 8192  # legs (link x epoch x geometry) kept before the cache is emptied


def omega_size(n_vehicles: int) -> int:
    """The ω message's wire size (bytes) in a fleet of ``n_vehicles`` (32, or 33 past 256)."""
    return len(encode_omega(OmegaMsg(max(0, n_vehicles - 1), 0, 0.0, 0.0, 0.0)))


# --------------------------------------------------------------------------- the spec


@dataclass(frozen=True)
class RadioSpec:
    """The validated ``[radio]`` table (docs/config.md lists the fields, docs/radio.md the model).

    Units: m, s, Hz, dB, dBm, bit/s, bytes. ``noise_floor`` None: from bandwidth and noise
    figure. ``pl0`` None: free-space loss at ``d0`` for ``frequency``. ``antenna`` is
    (usv, uav, station) heights above the vehicle's position; ``antenna_override`` (id,
    height) pairs. ``station`` (x, y, z) is the base of the station's antenna mast.
    """

    topology: str = "adhoc"
    station: tuple[float, float, float] = (0.0, 0.0, 0.0)
    relay_delay: float = 0.001
    sample_period: float = 0.2
    seed: int | None = None
    # propagation
    propagation: str = "two_ray"
    frequency: float = 5.18e9
    exponent: float = 2.0
    d0: float = 1.0
    pl0: float | None = None
    permittivity: float = 80.0
    conductivity: float = 0.01
    polarization: str = "vertical"
    antenna: tuple[float, float, float] = (1.0, 0.1, 10.0)
    antenna_override: tuple[tuple[str, float], ...] = ()
    # shadowing and fading
    shadowing_sigma: float = 4.0
    shadowing_distance: float = 50.0
    shadowing_time: float = math.inf
    fading: str = "none"
    rician_k: float = 10.0
    nakagami_m: float = 1.0
    # reception
    tx_power: float = 20.0
    noise_floor: float | None = None
    bandwidth: float = 20.0e6
    noise_figure: float = 10.0
    modulation: str = "bpsk"
    header: int = 64
    # the shared medium
    capacity: float = 6.0e6
    preamble: float = 5.0e-5
    access: str = "csma"
    slot: float = 9.0e-6
    queue: int = 8

    @property
    def noise_dbm(self) -> float:
        """The noise floor (dBm): given, or kTB + noise figure."""
        if self.noise_floor is not None:
            return self.noise_floor
        return THERMAL_DBM_HZ + 10.0 * math.log10(self.bandwidth) + self.noise_figure

    @property
    def wavelength(self) -> float:
        return C_LIGHT / self.frequency

    @property
    def loss_d0(self) -> float:
        """PL0 (dB): given, or the free-space loss at d0."""
        return self.pl0 if self.pl0 is not None else free_space_db(self.d0, self.frequency)


# --------------------------------------------------------------------------- propagation


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


# --------------------------------------------------------------------------- reception


def q_function(x: float) -> float:
    """Q(x) = P(N(0, 1) > x) = erfc(x / √2) / 2."""
    return 0.5 * math.erfc(x / math.sqrt(2.0))


def ber(ebn0: float, modulation: str) -> float:
    """Bit error rate at Eb/N0 = ``ebn0`` (linear), coherent detection, Gray coding, uncoded:
    bpsk, qpsk: Q(√(2 Eb/N0)); M-QAM: (4/k)(1 - 1/√M) Q(√(3k/(M-1) Eb/N0)), k = log2 M
    (the nearest-neighbour approximation); at most 1/2."""
    if ebn0 <= 0.0:
        return 0.5
    if modulation in ("bpsk", "qpsk"):
        b = q_function(math.sqrt(2.0 * ebn0))
    else:
        m = 16 if modulation == "16qam" else 64
        kb = math.log2(m)
        b = (4.0 / kb) * (1.0 - 1.0 / math.sqrt(m)) * q_function(math.sqrt(3.0 * kb / (m - 1) * ebn0))
    return min(b, 0.5)


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
    if modulation in ("bpsk", "qpsk"):
        b = _q_vec(np.sqrt(2.0 * ebn0))
    else:
        m = 16 if modulation == "16qam" else 64
        kb = math.log2(m)
        b = (4.0 / kb) * (1.0 - 1.0 / math.sqrt(m)) * _q_vec(np.sqrt(3.0 * kb / (m - 1) * ebn0))
    b = np.minimum(b, 0.5)
    return -np.expm1(8 * size_bytes * np.log1p(-b))


def airtime(size_bytes: int, capacity: float, preamble: float) -> float:
    """Seconds one message holds the medium: preamble + 8 · size / capacity."""
    return preamble + 8.0 * size_bytes / capacity


# --------------------------------------------------------------------------- random draws


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


# --------------------------------------------------------------------------- geometry and decisions

Point = tuple[float, float, float]


@dataclass(frozen=True)
class Geometry:
    """Where everyone was at one world sample (docs/radio.md, the geometry schedule).

    ``tick``: the sample's control tick; ``positions``: (x, y, z) per vehicle, indexed like the
    scenario's vehicles (None: not live at the sample; a boat is at z = 0); ``station``: the
    station's position in force (None: the channel's, from the spec and its updates); ``t``:
    the sample's simulated time (None: tick × the channel's tick_period).
    """

    tick: int
    positions: tuple[Point | None, ...]
    station: Point | None = None
    t: float | None = None

    @classmethod
    def of(cls, tick: int, positions: Iterable[Sequence[float] | None], station: Sequence[float] | None = None,
           t: float | None = None) -> "Geometry":
        pts = tuple(None if q is None else (float(q[0]), float(q[1]), float(q[2]) if len(q) > 2 else 0.0)
                    for q in positions)
        st = None if station is None else (float(station[0]), float(station[1]),
                                           float(station[2]) if len(station) > 2 else 0.0)
        return cls(int(tick), pts, st, t)


@dataclass(frozen=True)
class RadioDecision:
    delivered: bool
    delay: float  # s: queueing + airtime (+ relay and the second leg in station mode)
    cause: str | None  # range | fading | collision | queue; None when delivered
    p: float  # the model's delivery probability of this message (given the geometry)


@dataclass
class RadioCounters:
    """Messages decided on the radio (one directed link, or all) and what became of them
    (docs/metrics.md, ``radio``): drops by cause (RADIO_CAUSES; the channel alone never counts
    ``fault``, the hand-set [link] fault that cdus.core.radiolink.RadioLink decides first)."""

    sent: int = 0
    delivered: int = 0
    fault: int = 0
    range: int = 0
    fading: int = 0
    collision: int = 0
    queue: int = 0
    no_geometry: int = 0  # decided without the sample in force (realtime only; passed through)

    def add(self, other: "RadioCounters") -> None:
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))

    def as_dict(self) -> dict:
        return {"sent": self.sent, "delivered": self.delivered,
                "dropped": sum(getattr(self, c) for c in RADIO_CAUSES),
                "dropped_by": {c: getattr(self, c) for c in RADIO_CAUSES}, "no_geometry": self.no_geometry}

    @classmethod
    def from_dict(cls, d: dict) -> "RadioCounters":
        return cls(sent=d["sent"], delivered=d["delivered"], no_geometry=d.get("no_geometry", 0),
                   **{c: d["dropped_by"][c] for c in RADIO_CAUSES})


@dataclass(frozen=True)
class Medium:
    """The shared medium at one geometry (docs/radio.md, "The shared medium")."""

    airtime: float  # s per message
    transmitters: int  # live vehicles (+ the station in station mode)
    utilisation: float  # offered airtime per second, ρ
    wait: float  # s, the mean queueing wait (M/D/1, capped by the queues)
    queue_drop: float  # P(dropped at a full queue) = max(0, 1 - 1/ρ)
    live: int  # live vehicles
    offered: float  # transmissions/s offered to the medium (relayed copies included)


@dataclass(frozen=True)
class _Epoch:
    tx_power: float
    station: Point


@dataclass
class _Leg:
    """One transmission a -> b at one geometry and epoch: what every message on it shares."""

    snr: float  # dB, with shadowing, without fading
    per: float  # PER without fading
    success: float  # P(through the air) averaged over the fading
    collision: float  # P(collision)


class RadioChannel:
    """The ``[radio]`` channel (docs/radio.md).

    ``ids``, ``kinds``: the scenario's vehicles in order (kinds usv | uav); ``seed``: the radio
    seed (``Scenario.radio_seed``). Keywords: ``rate`` (Hz) every vehicle's ω broadcast rate
    (``scenario.rates.broadcast``), ``size`` (bytes) the ω payload (default: its wire size for
    this fleet), ``tick_period`` (s per ``Geometry.tick``, i.e. 1 / control rate; needed when
    the shadowing is correlated in time and the geometry carries no ``t``).
    """

    def __init__(self, spec: RadioSpec, ids: Sequence[str], kinds: Sequence[str], seed: int, *,
                 rate: float = DEFAULT_RATE, size: int | None = None, tick_period: float | None = None):
        if len(ids) != len(kinds):
            raise ValueError(f"{len(ids)} ids but {len(kinds)} kinds")
        if not (rate > 0.0 and math.isfinite(rate)):
            raise ValueError(f"broadcast rate must be a finite number > 0 Hz, got {rate!r}")
        self.spec = spec
        self.ids = tuple(ids)
        self.kinds = tuple(kinds)
        self.seed = seed
        self.rate = float(rate)
        self.size = omega_size(len(self.ids)) if size is None else int(size)
        self.bytes = self.size + spec.header
        self.tick_period = tick_period
        heights = dict(zip(KINDS, spec.antenna[:2]))
        over = dict(spec.antenna_override)
        self.heights = tuple(over.get(v, heights.get(k, spec.antenna[0])) for v, k in zip(self.ids, self.kinds))
        self.eps = water_permittivity(spec.permittivity, spec.conductivity, spec.frequency)
        self.air = airtime(self.bytes, spec.capacity, spec.preamble)
        self._starts: list[float] = [-math.inf]
        self._epochs: list[_Epoch] = [_Epoch(spec.tx_power, spec.station)]
        self._keys: dict[tuple[str, str, str], int] = {}
        self._fields: dict[tuple[int, int], ShadowField] = {}
        self._legs: dict[tuple[int, int, int, int], tuple[Geometry, _Leg | None]] = {}
        self._media: tuple = (None, None)
        self._links: dict[tuple[int, int], RadioCounters] = {}
        if tick_period is not None and not (tick_period > 0.0 and math.isfinite(tick_period)):
            raise ValueError(f"tick_period must be a finite number > 0 s, got {tick_period!r}")
        #: the shadowing changes with time, so a geometry without ``t`` needs tick_period
        self.timed = spec.shadowing_sigma > 0.0 and math.isfinite(spec.shadowing_time)

    # ---- run-time changes

    @property
    def epochs(self) -> tuple[tuple[float, float, Point], ...]:
        """(from t_send, tx_power dBm, station) of every epoch."""
        return tuple((s, e.tx_power, e.station) for s, e in zip(self._starts, self._epochs))

    def update(self, at: float, tx_power_dbm: float | None = None, station: Sequence[float] | None = None) -> None:
        """From t_send >= ``at`` on, the transmit power and/or the station position change (the
        others stay). Updates come in time order; the same ``at`` again replaces that epoch."""
        if not math.isfinite(at):  # nan would sit in the bisected starts; inf would refuse every later one
            raise ValueError(f"radio update time must be a finite number of s, got {at!r}")
        if at < self._starts[-1]:
            raise ValueError(f"radio update at t = {at:g} s is before the previous one at t = {self._starts[-1]:g} s; "
                             f"updates must come in time order")
        old = self._epochs[-1]
        tx = old.tx_power if tx_power_dbm is None else float(tx_power_dbm)
        if not math.isfinite(tx):
            raise ValueError(f"tx_power must be a finite number of dBm, got {tx_power_dbm!r}")
        st = old.station if station is None else (float(station[0]), float(station[1]),
                                                  float(station[2]) if len(station) > 2 else 0.0)
        if not all(math.isfinite(x) for x in st):
            raise ValueError(f"station must be finite coordinates in m, got {station!r}")
        new = _Epoch(tx, st)
        if at == self._starts[-1]:
            self._epochs[-1] = new
        else:
            self._starts.append(at)
            self._epochs.append(new)

    def _epoch(self, t: float | None) -> int:
        if t is None or len(self._starts) == 1:
            return len(self._starts) - 1 if t is None else 0
        return bisect.bisect_right(self._starts, t) - 1

    # ---- geometry

    def _station(self, geo: Geometry, epoch: int) -> Point:
        return geo.station if geo.station is not None else self._epochs[epoch].station

    def antenna(self, node: int, geo: Geometry, epoch: int) -> Point | None:
        """The antenna position (x, y, height above the water) of vehicle ``node`` (or the
        station: ``node == len(ids)``), None if the vehicle is not live in ``geo``."""
        if node == len(self.ids):
            x, y, z = self._station(geo, epoch)
            return (x, y, z + self.spec.antenna[2])
        q = geo.positions[node] if node < len(geo.positions) else None
        if q is None:
            return None
        return (q[0], q[1], q[2] + self.heights[node])

    def _name(self, node: int) -> str:
        return STATION if node == len(self.ids) else self.ids[node]

    def _key(self, a: str, b: str, purpose: str) -> int:
        k = (a, b, purpose)
        key = self._keys.get(k)
        if key is None:
            key = self._keys[k] = stream_key(self.seed, a, b, "radio-" + purpose)
        return key

    def path_loss(self, pa: Point, pb: Point) -> float:
        """The propagation loss (dB) between two antennas (no shadowing, no fading)."""
        s = self.spec
        d = math.hypot(pa[0] - pb[0], pa[1] - pb[1])
        if s.propagation == "two_ray":
            return two_ray_loss_db(d, pa[2], pb[2], s.frequency, self.eps, s.polarization, s.d0)
        return path_loss_db(math.hypot(d, pa[2] - pb[2]), s.exponent, s.d0, s.loss_d0)

    def shadowing(self, a: int, b: int, pa: Point, pb: Point, geo: Geometry) -> float:
        """The shadowing (dB) of the link a-b (unordered) at these antenna positions and the
        sample's time: :class:`ShadowField`."""
        s = self.spec
        if s.shadowing_sigma <= 0.0:
            return 0.0
        lo, hi = (a, b) if a < b else (b, a)
        if a > b:
            pa, pb = pb, pa
        f = self._fields.get((lo, hi))
        if f is None:
            f = self._fields[(lo, hi)] = ShadowField(self._key(self._name(lo), self._name(hi), "shadow"),
                                                     s.shadowing_sigma)
        x = [0.0] * 7
        if math.isfinite(s.shadowing_distance):
            x[:6] = [c / s.shadowing_distance for c in (*pa, *pb)]
        if math.isfinite(s.shadowing_time):
            t = geo.t
            if t is None:
                if self.tick_period is None:
                    raise ValueError("[radio] shadowing_time is finite: give the channel tick_period "
                                     "(1 / control rate) or the geometry its time t")
                t = geo.tick * self.tick_period
            x[6] = t / s.shadowing_time
        return f(x)

    # ---- the medium

    def medium(self, geo: Geometry) -> Medium:
        """Airtime, load, queueing of the shared medium at ``geo`` (docs/radio.md)."""
        cached_geo, m = self._media
        if cached_geo is not None and (cached_geo is geo or cached_geo.positions == geo.positions):
            return m
        s = self.spec
        live = sum(1 for q in geo.positions if q is not None)
        copies = 2 if s.topology == "station" else 1
        tx = live + (1 if s.topology == "station" and live else 0)
        rho = live * self.rate * copies * self.air
        if rho < 1.0:
            wait = rho * self.air / (2.0 * (1.0 - rho))
            drop = 0.0
        else:
            wait = math.inf
            drop = 1.0 - 1.0 / rho
        wait = min(wait, s.queue * max(tx, 1) * self.air)
        m = Medium(self.air, tx, rho, wait, drop, live, live * self.rate * copies)
        self._media = (geo, m)
        return m

    def utilisation(self, geo: Geometry) -> float:
        """Offered airtime per second of the shared medium (0..; > 1: saturated)."""
        return self.medium(geo).utilisation

    def _collision(self, m: Medium, own: float) -> float:
        """P(a transmission collides): 1 - exp(-λ_others W), λ_others the carried rate of the
        other transmitters ((offered - own) × (1 - queue_drop)), W = slot (csma) or 2 airtimes
        (unslotted aloha)."""
        others = max(0.0, (m.offered - own) * (1.0 - m.queue_drop))
        window = self.spec.slot if self.spec.access == "csma" else 2.0 * m.airtime
        return -math.expm1(-others * window)

    # ---- one leg

    def _leg(self, a: int, b: int, geo: Geometry, epoch: int) -> _Leg | None:
        # cached per (link, epoch, geometry object): the cache holds the geometry, so its id is
        # not reused while cached; an equal geometry in a new object is computed again (same value)
        key = (a, b, epoch, id(geo))
        cached = self._legs.get(key)
        if cached is not None and cached[0] is geo:
            return cached[1]
        pa, pb = self.antenna(a, geo, epoch), self.antenna(b, geo, epoch)
        if pa is None or pb is None:
            leg = None
        else:
            s = self.spec
            snr = self._epochs[epoch].tx_power - self.path_loss(pa, pb) - self.shadowing(a, b, pa, pb, geo) \
                - s.noise_dbm
            per = per_from_snr(snr, self.bytes, s.modulation, s.bandwidth, s.capacity)
            if s.fading == "none":
                success = 1.0 - per
            else:
                curve = per_curve(snr + 10.0 * _LOG10_GRID(), self.bytes, s.modulation, s.bandwidth,
                                  s.capacity)
                # the weights sum to 1 within rounding: 1 + 2e-16 when every gain gets through
                success = min(1.0, max(0.0, fading_mean(1.0 - curve, s.fading, s.rician_k, s.nakagami_m)))
            m = self.medium(geo)
            own = self.rate * (m.live if a == len(self.ids) else 1)  # the station relays everyone's
            leg = _Leg(snr, per, success, self._collision(m, own))
        if len(self._legs) >= MAX_CACHED:
            self._legs.clear()
        self._legs[key] = (geo, leg)
        return leg

    def _through(self, leg: _Leg, a: int, b: int, seq: int, tag: str) -> str | None:
        """One transmission on ``leg``: None if it got through, else the cause."""
        s = self.spec
        an, bn = self._name(a), self._name(b)
        if leg.collision > 0.0 and uniform(self._key(an, bn, "collision" + tag), seq) < leg.collision:
            return "collision"
        p_err = leg.per
        if s.fading != "none":
            g = fading_gain(s.fading, s.rician_k, s.nakagami_m, self._key(an, bn, "fading" + tag), seq)
            p_err = per_from_snr(leg.snr + 10.0 * math.log10(max(g, 1e-300)), self.bytes, s.modulation,
                                 s.bandwidth, s.capacity)
        u = uniform(self._key(an, bn, "per" + tag), seq)
        if u < p_err:
            return "range" if u < leg.per else "fading"
        return None

    # ---- the public decisions

    def delivery_probability(self, src: int, dst: int, geo: Geometry, t: float | None = None) -> float:
        """The model's probability that a message src -> dst sent with this geometry (at time
        ``t``, default: under the newest epoch) is delivered: over the per-message draws
        (fading, collision, queue), given the geometry (shadowing included)."""
        epoch = self._epoch(t)
        m = self.medium(geo)
        keep = 1.0 - m.queue_drop
        if self.spec.topology == "station":
            st = len(self.ids)
            up, down = self._leg(src, st, geo, epoch), self._leg(st, dst, geo, epoch)
            if up is None or down is None:
                return 0.0
            return keep * (1.0 - up.collision) * up.success * keep * (1.0 - down.collision) * down.success
        leg = self._leg(src, dst, geo, epoch)
        if leg is None:
            return 0.0
        return keep * (1.0 - leg.collision) * leg.success

    def decide(self, src: int, dst: int, seq: int, t_send: float, geo: Geometry) -> RadioDecision:
        """Is message ``seq`` of ``src`` delivered to ``dst``? Pure in (seed, src, dst, seq,
        geo, the epoch in force at t_send); counted per link."""
        c = self._links.get((src, dst))
        if c is None:
            c = self._links[(src, dst)] = RadioCounters()
        c.sent += 1
        epoch = self._epoch(t_send)
        m = self.medium(geo)
        p = self.delivery_probability(src, dst, geo, t_send)
        cause = None
        delay = m.wait + m.airtime
        sname = self.ids[src]
        if self.spec.topology == "station":
            st = len(self.ids)
            up, down = self._leg(src, st, geo, epoch), self._leg(st, dst, geo, epoch)
            if up is None or down is None:
                cause = "range"
            elif m.queue_drop > 0.0 and uniform(self._key(sname, STATION, "queue"), seq) < m.queue_drop:
                cause = "queue"
            else:
                cause = self._through(up, src, st, seq, "")  # the uplink: the same for every receiver
                if cause is None:
                    if m.queue_drop > 0.0 and uniform(self._key(STATION, sname, "queue"), seq) < m.queue_drop:
                        cause = "queue"
                    else:
                        cause = self._through(down, st, dst, seq, "|" + sname)
                delay += self.spec.relay_delay + m.wait + m.airtime
        else:
            leg = self._leg(src, dst, geo, epoch)
            if leg is None:
                cause = "range"
            elif m.queue_drop > 0.0 and uniform(self._key(sname, "*", "queue"), seq) < m.queue_drop:
                cause = "queue"
            else:
                cause = self._through(leg, src, dst, seq, "")
        if cause is None:
            c.delivered += 1
            return RadioDecision(True, delay, None, p)
        setattr(c, cause, getattr(c, cause) + 1)
        return RadioDecision(False, 0.0, cause, p)

    # ---- records

    @property
    def counters(self) -> RadioCounters:
        """Every link's counts added up."""
        total = RadioCounters()
        for c in self._links.values():
            total.add(c)
        return total

    def link_counters(self) -> dict[tuple[int, int], RadioCounters]:
        """Per directed link (src, dst), the links decided so far."""
        return dict(sorted(self._links.items()))

    def counters_summary(self) -> dict:
        """``{"total": {...}, "links": {"usv1->usv2": {...}}}``, each ``{sent, delivered, dropped,
        dropped_by: {fault (always 0 here), range, fading, collision, queue}, no_geometry}``."""
        return {"total": self.counters.as_dict(),
                "links": {f"{self.ids[s]}->{self.ids[d]}": c.as_dict() for (s, d), c in self.link_counters().items()}}

"""What is a Lissajous path? f_k = c_k + A_k cos(a_k βω + δ_k) on 2 or 3 axes, with f' and f'';
its period, and where one retraces itself (:func:`turning_point`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

from cdus.core.paths.geometry import Planar
from cdus.core.paths.registry import TAU, Centred, Family, Param, Path, PathError, Vec, register
from cdus.wire.bounds import MIN_RATE


@dataclass(frozen=True)
class Lissajous(Centred):
    """General Lissajous: f_k = c_k + A_k cos(a_k βω + δ_k), k over 2 or 3 axes."""

    center: Vec
    amplitude: Vec
    frequency: Vec
    phase: Vec
    beta: float = 1.0
    direction: float = -1.0

    @property
    def period(self) -> float | None:
        return _common_period(self.frequency, self.beta)

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        f, f1, f2 = [], [], []
        b = self.beta
        for c, amp, fr, ph in zip(self.center, self.amplitude, self.frequency, self.phase):
            k = fr * b
            cs, sn = math.cos(k * w + ph), math.sin(k * w + ph)
            f.append(c + amp * cs)
            f1.append(-amp * k * sn)
            f2.append(-amp * k * k * cs)
        return tuple(f), tuple(f1), tuple(f2)


RETRACE_TURNS = 20_000  # turning-point candidates tried (a period holds 2 a_1/gcd(a_k) of them)


def turning_point(path: Path) -> float | None:
    """An ω at which a Lissajous path, as a vehicle follows it (a USV: its x, y), stops and turns
    back, or None if it never does (every other family: None).

    f'_k(ω) = -A_k a_k β sin(a_k βω + δ_k) vanishes for every moving axis k at once exactly where
    each a_k βω + δ_k is a multiple of π; there f(ω0 + τ) = f(ω0 - τ) for every τ: the curve runs
    back over itself (all phases 0 do it at ω = 0: the classic degenerate Lissajous, an open
    curve traced back and forth). Vehicles half a lap apart then meet head-on, and at ω0 the
    path has no tangent. A path with no moving axis (a point) turns at 0."""
    inner, dims = (path.inner, 2) if isinstance(path, Planar) else (path, path.dim)
    if not isinstance(inner, Lissajous):
        return None
    b = inner.beta
    moving = [(fr * b, ph) for amp, fr, ph in list(zip(inner.amplitude, inner.frequency, inner.phase))[:dims]
              if amp != 0.0 and fr != 0.0]
    if not moving:
        return 0.0
    (k0, d0), rest = moving[0], moving[1:]
    period = path.period
    turns = RETRACE_TURNS if period is None else min(RETRACE_TURNS, math.ceil(abs(k0) * period / math.pi) + 1)
    for m in range(turns):
        w = (m * math.pi - d0) / k0  # axis 0 is still here; are the others?
        if all(abs(math.sin(k * w + d)) < max(1e-9, 1e-14 * abs(k * w + d)) for k, d in rest):  # float error only
            return w
    return None


def _common_period(freqs: Vec, beta: float) -> float | None:
    """Smallest T > 0 with every a_k β T a multiple of 2π, if the frequencies are rational."""
    fr = [Fraction(f).limit_denominator(1000) for f in freqs if f != 0]
    if not fr or any(abs(float(q) - f) > 1e-9 for q, f in zip(fr, [f for f in freqs if f != 0])):
        return None
    # T·a_k/(2π) is an integer for every k  <=>  T/(2π) is a multiple of 1/gcd(a_k)
    g = _fraction_gcd([abs(q) for q in fr])
    return TAU / (float(g) * abs(beta))


def _fraction_gcd(values: list[Fraction]) -> Fraction:
    g = values[0]
    for v in values[1:]:
        g = Fraction(
            math.gcd(g.numerator * v.denominator, v.numerator * g.denominator),
            g.denominator * v.denominator,
        )
    return g


def _no_slow_frequency(fr: Vec) -> None:
    slow = [f for f in fr if f != 0 and not abs(f) >= MIN_RATE]
    if slow:  # a frequency of 1e-308 put a turning point at ω = π / 2e-309 = inf
        raise PathError("frequency", f"must contain numbers that are 0 or at least {MIN_RATE:g} in size, got "
                                     f"{slow[0]:g}: a vehicle cannot follow such a path (its numbers overflow)")


def _lissajous(center: Vec, amplitude: Vec, frequency: Vec, phase: Vec | None, beta: float,
               direction: float) -> Lissajous:
    return Lissajous(center, amplitude, frequency, (0.0,) * len(center) if phase is None else phase, beta, direction)


register(Family(
    "lissajous", "center, amplitude, frequency, phase: lists of 2 or 3 numbers",
    (Param("center", "vector", required=True), Param("amplitude", "vector", required=True, dims="center"),
     Param("frequency", "vector", required=True, dims="center", check=_no_slow_frequency),
     Param("phase", "vector", dims="center")),
    _lissajous))

"""What is a path? A parametric curve f(ω) with f', f'' in closed form.

One small class per family, each giving ``eval(ω) -> (f, f', f'')`` and nothing else;
the guidance never knows which path it follows (the Paparazzi ``gvf_parametric``
separation). Vectors are plain tuples of floats: at 2-3 components, pure Python is
several times faster than NumPy and keeps the agent's control loop cheap.

Every family takes ``beta`` (speed scaling, f(ω) -> f(βω): the on-path speed becomes
β|f0'| at |ω̇| = 1) and ``direction`` s = ±1 (the paper's (-1)^3 = -1 is the default;
the guidance uses s as the travel direction, docs/control.md §2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Callable, Mapping, Protocol

from cdus.wire.bounds import BOUNDS, MAX_PHASE, MIN_RATE, finite

Vec = tuple[float, ...]

TAU = 2.0 * math.pi


class PathError(ValueError):
    """A path spec that cannot be built. ``field`` names the offending parameter."""

    def __init__(self, field: str, message: str):
        super().__init__(f"{field}: {message}")
        self.field = field
        self.message = message


class Path(Protocol):
    dim: int  # 2 (planar) or 3
    period: float | None  # ω-period of a closed path, None for an open one
    direction: float  # s = ±1: steady state has ω̇ = s

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        """f(ω), f'(ω), f''(ω)."""
        ...


# --------------------------------------------------------------------------- families


@dataclass(frozen=True)
class Circle:
    """f = c + r (cos βω, sin βω [, c_z])."""

    center: Vec
    radius: float
    beta: float = 1.0
    direction: float = -1.0

    @property
    def dim(self) -> int:
        return len(self.center)

    @property
    def period(self) -> float:
        return TAU / abs(self.beta)

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        b, r = self.beta, self.radius
        cs, sn = math.cos(b * w), math.sin(b * w)
        cx, cy = self.center[0], self.center[1]
        if len(self.center) == 3:
            return (
                (cx + r * cs, cy + r * sn, self.center[2]),
                (-r * b * sn, r * b * cs, 0.0),
                (-r * b * b * cs, -r * b * b * sn, 0.0),
            )
        return (
            (cx + r * cs, cy + r * sn),
            (-r * b * sn, r * b * cs),
            (-r * b * b * cs, -r * b * b * sn),
        )


@dataclass(frozen=True)
class Ellipse:
    """f = c + R(ρ) (a cos βω, b sin βω) [, c_z], R(ρ) a rotation by ``rotation`` rad."""

    center: Vec
    a: float
    b: float
    rotation: float = 0.0
    beta: float = 1.0
    direction: float = -1.0

    @property
    def dim(self) -> int:
        return len(self.center)

    @property
    def period(self) -> float:
        return TAU / abs(self.beta)

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        k = self.beta
        cs, sn = math.cos(k * w), math.sin(k * w)
        cr, sr = math.cos(self.rotation), math.sin(self.rotation)
        # local components and their derivatives
        lx, ly = self.a * cs, self.b * sn
        dx, dy = -self.a * k * sn, self.b * k * cs
        ddx, ddy = -self.a * k * k * cs, -self.b * k * k * sn

        def rot(x: float, y: float) -> tuple[float, float]:
            return (cr * x - sr * y, sr * x + cr * y)

        f = rot(lx, ly)
        f1 = rot(dx, dy)
        f2 = rot(ddx, ddy)
        cx, cy = self.center[0], self.center[1]
        if len(self.center) == 3:
            return (cx + f[0], cy + f[1], self.center[2]), (*f1, 0.0), (*f2, 0.0)
        return (cx + f[0], cy + f[1]), f1, f2


@dataclass(frozen=True)
class Lissajous:
    """General Lissajous: f_k = c_k + A_k cos(a_k βω + δ_k), k over 2 or 3 axes."""

    center: Vec
    amplitude: Vec
    frequency: Vec
    phase: Vec
    beta: float = 1.0
    direction: float = -1.0

    @property
    def dim(self) -> int:
        return len(self.center)

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


def self_intersecting(d: float = 0.0, center: Vec = (0.0, 0.0, 0.0), beta: float = 1.0,
                      direction: float = -1.0) -> Lissajous:
    """The paper's self-intersecting path: f = (16 cos(ω/2), 6 cos(ω + π/2) - d, -2 cos ω).

    ``center`` shifts the whole curve (e.g. a UAV altitude in z); d ∈ {0, ±7, ±14} in
    the paper's simulation. A USV uses the first two components.
    """
    cx, cy, cz = (tuple(center) + (0.0, 0.0, 0.0))[:3]
    return Lissajous(
        center=(cx, cy - d, cz),
        amplitude=(16.0, 6.0, -2.0),
        frequency=(0.5, 1.0, 1.0),
        phase=(0.0, math.pi / 2.0, 0.0),
        beta=beta,
        direction=direction,
    )


@dataclass(frozen=True)
class Trefoil:
    """Trefoil knot: f = c + s (sin βω + 2 sin 2βω, cos βω - 2 cos 2βω, -h sin 3βω)."""

    center: Vec
    scale: float = 1.0
    height: float = 1.0
    beta: float = 1.0
    direction: float = -1.0

    dim = 3

    @property
    def period(self) -> float:
        return TAU / abs(self.beta)

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        b, s, h = self.beta, self.scale, self.height
        t = b * w
        s1, c1 = math.sin(t), math.cos(t)
        s2, c2 = math.sin(2 * t), math.cos(2 * t)
        s3, c3 = math.sin(3 * t), math.cos(3 * t)
        cx, cy, cz = self.center
        f = (cx + s * (s1 + 2 * s2), cy + s * (c1 - 2 * c2), cz - s * h * s3)
        f1 = (s * b * (c1 + 4 * c2), s * b * (-s1 + 4 * s2), -s * h * 3 * b * c3)
        f2 = (s * b * b * (-s1 - 8 * s2), s * b * b * (-c1 + 8 * c2), s * h * 9 * b * b * s3)
        return f, f1, f2


@dataclass(frozen=True)
class Line:
    """Straight line f = p0 + βω·u with u the unit direction: |f'| = β m per unit ω."""

    origin: Vec
    heading: Vec  # normalised at construction
    beta: float = 1.0
    direction: float = -1.0

    @property
    def dim(self) -> int:
        return len(self.origin)

    period = None

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        b = self.beta
        f = tuple(p + b * w * u for p, u in zip(self.origin, self.heading))
        f1 = tuple(b * u for u in self.heading)
        zero = tuple(0.0 for _ in self.heading)
        return f, f1, zero


@dataclass(frozen=True)
class Planar:
    """The first two components of a 3-D path (what a USV follows on a 3-D curve)."""

    inner: Any

    dim = 2

    @property
    def period(self) -> float | None:
        return self.inner.period

    @property
    def direction(self) -> float:
        return self.inner.direction

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        f, f1, f2 = self.inner.eval(w)
        return f[:2], f1[:2], f2[:2]


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


# --------------------------------------------------------------------------- construction

FAMILIES: dict[str, str] = {
    "circle": "center=[x, y(, z)], radius>0 (or speed>0 m/s instead of beta)",
    "ellipse": "center=[x, y(, z)], a>0, b>0, rotation (rad)",
    "self_intersecting": "d (offset, paper: 0, ±7, ±14), center=[x, y, z]",
    "lissajous": "center, amplitude, frequency, phase: lists of 2 or 3 numbers",
    "trefoil": "center=[x, y, z], scale>0, height>0",
    "line": "origin=[x, y(, z)], heading=[dx, dy(, dz)] (non-zero)",
}

_COMMON = {"family", "beta", "direction", "speed"}


def make_path(spec: Mapping[str, Any]) -> Path:
    """Build a path from a config table such as ``{family = "circle", center = [0, 0], radius = 10}``.

    Raises :class:`PathError` naming the offending key and what would be valid.
    """
    family = spec.get("family")
    if family is None:
        raise PathError("family", f"missing; choose one of {', '.join(FAMILIES)}")
    if family not in FAMILIES:
        raise PathError("family", f"unknown path family {family!r}; choose one of {', '.join(FAMILIES)}")
    builder, allowed, required = _BUILDERS[family]
    unknown = sorted(set(spec) - allowed - _COMMON)
    if unknown:
        raise PathError(unknown[0], f"not a parameter of a {family} path; it takes {FAMILIES[family]}")
    for key in required:
        if key not in spec:
            raise PathError(key, f"missing; a {family} path takes {FAMILIES[family]}")
    beta = _number(spec, "beta", 1.0)
    if beta == 0:
        raise PathError("beta", "must be non-zero (speed scaling f(βω))")
    direction = _number(spec, "direction", -1.0, bounded=False)
    if direction not in (-1.0, 1.0):
        raise PathError("direction", f"must be -1 (the paper's choice) or +1, got {direction}")
    if "speed" in spec:
        if "beta" in spec:
            raise PathError("speed", "give either speed or beta, not both")
        if family not in ("circle", "line"):
            raise PathError("speed", f"only circle and line have a constant on-path speed; use beta for {family}")
        speed = _positive(spec, "speed")
        beta = speed / (_positive(spec, "radius") if family == "circle" else 1.0)
    if not abs(beta) >= MIN_RATE or not BOUNDS["path.beta"].holds(beta):
        what = "speed / radius" if "speed" in spec and family == "circle" else "speed" if "speed" in spec else "beta"
        raise PathError("speed" if "speed" in spec else "beta",
                        f"{what} (β, the speed scaling f(βω)) must be within ±{BOUNDS['path.beta'].hi:g} and at "
                        f"least {MIN_RATE:g} in size, got {beta:g}: a vehicle cannot follow such a path (its "
                        f"numbers overflow, or its lap 2π/β does)")
    return builder(spec, beta, direction)


def _number(spec: Mapping[str, Any], key: str, default: float | None = None, bounded: bool = True) -> float:
    """A finite number within its bound (cdus.wire.bounds.BOUNDS["path.<key>"])."""
    v = spec.get(key, default)
    if not finite(v):
        raise PathError(key, f"must be a finite number, got {v!r}")
    b = BOUNDS[f"path.{key}"] if bounded else None
    if b is not None and not b.holds(v):
        raise PathError(key, f"{b.problem(v, _UNITS.get(key, ''))}: a vehicle cannot follow such a path (its "
                             f"numbers overflow)")
    return float(v)


#: what the numbers of a path are, in a refusal
_UNITS = {"radius": " m", "a": " m", "b": " m", "scale": " m", "height": " m", "d": " m", "speed": " m/s",
          "rotation": " rad", "beta": " (speed scaling f(βω))"}


def _positive(spec: Mapping[str, Any], key: str) -> float:
    v = spec.get(key)
    if finite(v) and v <= 0:
        raise PathError(key, f"must be > 0, got {float(v)}")
    return _number(spec, key)


def _vector(spec: Mapping[str, Any], key: str, dims: tuple[int, ...] = (2, 3), default: Any = None) -> Vec:
    v = spec.get(key, default)
    if not isinstance(v, (list, tuple)) or len(v) not in dims:
        want = " or ".join(str(d) for d in dims)
        raise PathError(key, f"must be a list of {want} numbers, got {v!r}")
    out = []
    b = BOUNDS[f"path.{key}"]
    for x in v:
        if not finite(x):
            raise PathError(key, f"must contain finite numbers, got {v!r}")
        if not b.holds(x):
            raise PathError(key, f"must contain numbers {b.text()} (m, or a rate), got {x:g}: a vehicle cannot "
                                 f"follow such a path (its numbers overflow)")
        out.append(float(x))
    return tuple(out)


def _build_circle(s, beta, direction):
    return Circle(_vector(s, "center"), _positive(s, "radius"), beta, direction)


def _build_ellipse(s, beta, direction):
    return Ellipse(_vector(s, "center"), _positive(s, "a"), _positive(s, "b"),
                   _number(s, "rotation", 0.0), beta, direction)


def _build_self_intersecting(s, beta, direction):
    return self_intersecting(_number(s, "d", 0.0), _vector(s, "center", (3,), (0.0, 0.0, 0.0)), beta, direction)


def _build_lissajous(s, beta, direction):
    c = _vector(s, "center")
    n = len(c)
    amp = _vector(s, "amplitude", (n,))
    fr = _vector(s, "frequency", (n,))
    slow = [f for f in fr if f != 0 and not abs(f) >= MIN_RATE]
    if slow:  # a frequency of 1e-308 put a turning point at ω = π / 2e-309 = inf
        raise PathError("frequency", f"must contain numbers that are 0 or at least {MIN_RATE:g} in size, got "
                                     f"{slow[0]:g}: a vehicle cannot follow such a path (its numbers overflow)")
    ph = _vector(s, "phase", (n,), (0.0,) * n)
    return Lissajous(c, amp, fr, ph, beta, direction)


def _build_trefoil(s, beta, direction):
    scale = _positive(s, "scale") if "scale" in s else 1.0
    height = _positive(s, "height") if "height" in s else 1.0
    return Trefoil(_vector(s, "center", (3,)), scale, height, beta, direction)


def _build_line(s, beta, direction):
    o = _vector(s, "origin")
    h = _vector(s, "heading", (len(o),))
    norm = math.sqrt(sum(x * x for x in h))
    if norm == 0:
        raise PathError("heading", "must be a non-zero vector")
    return Line(o, tuple(x / norm for x in h), beta, direction)


_BUILDERS: dict[str, tuple[Callable[..., Path], set[str], tuple[str, ...]]] = {
    "circle": (_build_circle, {"center", "radius"}, ("center", "radius")),
    "ellipse": (_build_ellipse, {"center", "a", "b", "rotation"}, ("center", "a", "b")),
    "self_intersecting": (_build_self_intersecting, {"d", "center"}, ()),
    "lissajous": (_build_lissajous, {"center", "amplitude", "frequency", "phase"},
                  ("center", "amplitude", "frequency")),
    "trefoil": (_build_trefoil, {"center", "scale", "height"}, ("center",)),
    "line": (_build_line, {"origin", "heading"}, ("origin", "heading")),
}


def for_dimension(path: Path, dim: int) -> Path:
    """The path as a vehicle of dimension ``dim`` follows it (a USV takes x, y of a 3-D path).

    Raises ``PathError`` for a 3-D vehicle on a planar path.
    """
    if path.dim == dim:
        return path
    if path.dim == 3 and dim == 2:
        return Planar(path)
    raise PathError("path", f"a {dim}-D vehicle needs a {dim}-D path; this one is {path.dim}-D "
                            f"(give the center/origin a z component)")


#: the ω at which a path is evaluated before a vehicle takes it (:func:`not_finite_at`): its
#: phases are within ±MAX_PHASE
PROBE_OMEGAS = (0.0, 1.0, -1.0, 1e3, -1e3, 1e6, -1e6, MAX_PHASE, -MAX_PHASE)


def not_finite_at(path: Path) -> float | None:
    """The first of :data:`PROBE_OMEGAS` at which f, f' or f'' of ``path`` is not finite (a
    vehicle cannot follow it), None if there is none."""
    for w in PROBE_OMEGAS:
        if not all(math.isfinite(x) for v in path.eval(w) for x in v):
            return w
    return None


# --------------------------------------------------------------------------- geometry


def nearest_omega(path: Path, q: Vec, hint: float = 0.0, samples: int = 720) -> float:
    """The ω of the point of ``path`` nearest to ``q``.

    Closed paths: the best of ``samples`` points over one period starting at ``hint``,
    refined by Newton on g(ω) = (f(ω) - q)·f'(ω). Open paths: Newton from ``hint``.
    The result lies within one period of ``hint``, so it can continue an unwrapped ω.
    """
    period = path.period
    if period is None:
        w = hint
    else:
        best, w = math.inf, hint
        ev = path.eval
        # the squared distance written out for 2-D and 3-D: the same sums, in the same order, as
        # sum((a - b) ** 2 ...) (which starts from 0, exactly), so the same ω to the bit, 2x faster
        # (a realtime agent calls this when it resumes after a stall: bench/realtime_capacity.py)
        if len(q) == 2:
            q0, q1 = q
            for j in range(samples):
                cand = hint + period * j / samples
                f = ev(cand)[0]
                d = (f[0] - q0) ** 2 + (f[1] - q1) ** 2
                if d < best:
                    best, w = d, cand
        elif len(q) == 3:
            q0, q1, q2 = q
            for j in range(samples):
                cand = hint + period * j / samples
                f = ev(cand)[0]
                d = (f[0] - q0) ** 2 + (f[1] - q1) ** 2 + (f[2] - q2) ** 2
                if d < best:
                    best, w = d, cand
        else:
            for j in range(samples):
                cand = hint + period * j / samples
                f, _, _ = ev(cand)
                d = sum((a - b) ** 2 for a, b in zip(f, q))
                if d < best:
                    best, w = d, cand
    for _ in range(30):
        f, f1, f2 = path.eval(w)
        e = [a - b for a, b in zip(f, q)]
        g = sum(x * y for x, y in zip(e, f1))
        dg = sum(x * x for x in f1) + sum(x * y for x, y in zip(e, f2))
        if dg <= 1e-12:
            break
        step = g / dg
        w -= step
        if abs(step) < 1e-13:
            break
    return w

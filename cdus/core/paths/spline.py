"""What is a spline path? A smooth curve through a list of 2-D or 3-D waypoints, with f' and f''.

The interpolant is a cubic spline, periodic for a closed path (the last waypoint joins the first)
and natural for an open one (f'' = 0 at both ends, where the curve runs on along its end
tangents, so an open path is C² for every ω, as the DGVF's open paths must be). Why a cubic
spline: it is the C² interpolant of least bending (∫|f''|² is minimal among C² curves through
the waypoints), so f'' is bounded and small, its f, f', f'' are exact polynomials per segment
(closed form, as every other family's), and it needs only a tridiagonal solve at construction
(pure Python, O(n): the same numbers on every machine and in every process of a fleet). A
Catmull-Rom or Bézier chain is only C¹ (f'' jumps at the waypoints: the UAV regulator and the
USV heading law use f''); B-splines smooth more but do not pass through the waypoints.

Parametrisation: the knots are spaced by each segment's arc length (first by the chord
lengths, then refitted once with the arc lengths of that first fit), so the parameter is
close to arc length and |f₀'| stays near 1: its mean over every segment is 1 to within the
refit's error, and the checks below refuse a waypoint list on which it leaves
[:data:`MIN_SPEED`, :data:`MAX_SPEED`] anywhere. With β (or ``speed``, which sets β = speed)
f(ω) = f₀(βω), so at ω̇ = -1 a vehicle on the path moves at |β|·|f₀'| ≈ ``speed`` m/s.

A list that would break the DGVF's assumptions (a bounded, never-vanishing tangent) is refused
with a :class:`PathError` naming the waypoint (index and value) and the fix: too few waypoints,
two consecutive ones at the same place (also a closed list that repeats its first waypoint at
the end), a turn back (a cusp: the curve would stop or loop there), or a tangent that falls
below :data:`MIN_SPEED` (or rises above :data:`MAX_SPEED`) between two waypoints.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass

from cdus.core.paths.registry import Family, Param, PathError, Vec, register

#: m: the least distance between consecutive waypoints (closer ones are the same point)
MIN_GAP = 1e-3
#: degrees: the sharpest turn at a waypoint; a sharper one (up to 180°, going back the way it
#: came) makes a cusp or a loop of the spline
MAX_TURN = 150.0
#: |f₀'| (the speed asked, as a fraction of ``speed``) allowed anywhere on the curve
MIN_SPEED = 0.5
MAX_SPEED = 1.5
#: |f₀'| samples per segment in the check (and the Gauss-Legendre nodes of the arc lengths)
SPEED_SAMPLES = 32
_GAUSS = ((-0.9602898564975363, 0.1012285362903763), (-0.7966664774136267, 0.2223810344533745),
          (-0.5255324099163290, 0.3137066458778873), (-0.1834346424956498, 0.3626837833783620),
          (0.1834346424956498, 0.3626837833783620), (0.5255324099163290, 0.3137066458778873),
          (0.7966664774136267, 0.2223810344533745), (0.9602898564975363, 0.1012285362903763))

Segment = tuple[Vec, Vec, Vec, Vec]  # a, b, c, d: S(u) = a + b u + c u² + d u³, 0 <= u <= h


@dataclass(frozen=True)
class Spline:
    """f(ω) = S(βω): S the cubic spline through ``waypoints`` with knots ``knots`` (S(knots[i]) =
    waypoints[i]), closed (periodic, ω-period knots[-1]/|β|) or open (straight on beyond the ends).
    Build it with :func:`spline`, which checks the waypoints and fits the coefficients."""

    waypoints: tuple[Vec, ...]  # moved by the center, lifted to its height
    closed: bool
    knots: tuple[float, ...]  # 0 = t_0 < t_1 < ... < t_m: the parameter at each waypoint (and t_m at the first again)
    segments: tuple[Segment, ...]
    beta: float = 1.0
    direction: float = -1.0

    @property
    def dim(self) -> int:
        return len(self.waypoints[0])

    @property
    def length(self) -> float:
        """The parameter's range, ≈ the curve's length (m) over a lap or from end to end."""
        return self.knots[-1]

    @property
    def period(self) -> float | None:
        return self.knots[-1] / abs(self.beta) if self.closed else None

    @property
    def span(self) -> tuple[float, float] | None:
        """The ω interval of an open spline's body (None for a closed one)."""
        if self.closed:
            return None
        a, b = 0.0, self.knots[-1] / self.beta
        return (a, b) if a <= b else (b, a)

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        b = self.beta
        t = b * w
        knots, m = self.knots, len(self.segments)
        if self.closed:
            t %= knots[-1]
        elif t < 0.0:  # straight on before the start (f''= 0 there: natural end)
            a, v, _, _ = self.segments[0]
            return (tuple(p + t * x for p, x in zip(a, v)), tuple(b * x for x in v), tuple(0.0 for _ in a))
        elif t > knots[-1]:  # and after the end
            f, f1, _ = _at(self.segments[-1], knots[-1] - knots[-2])
            t -= knots[-1]
            return (tuple(p + t * x for p, x in zip(f, f1)), tuple(b * x for x in f1), tuple(0.0 for _ in f))
        i = min(max(bisect_right(knots, t) - 1, 0), m - 1)
        f, f1, f2 = _at(self.segments[i], t - knots[i])
        bb = b * b
        return f, tuple(b * x for x in f1), tuple(bb * x for x in f2)


def _at(seg: Segment, u: float) -> tuple[Vec, Vec, Vec]:
    """S, S', S'' of one segment at u."""
    a, b, c, d = seg
    f = tuple(a_ + u * (b_ + u * (c_ + u * d_)) for a_, b_, c_, d_ in zip(a, b, c, d))
    f1 = tuple(b_ + u * (2.0 * c_ + 3.0 * u * d_) for b_, c_, d_ in zip(b, c, d))
    f2 = tuple(2.0 * c_ + 6.0 * u * d_ for c_, d_ in zip(c, d))
    return f, f1, f2


def spline(waypoints: tuple[Vec, ...], closed: bool = True, beta: float = 1.0, direction: float = -1.0,
           center: Vec | None = None) -> Spline:
    """The spline through ``waypoints`` (2 or 3 finite numbers each, one length for all) moved by
    ``center`` (2-D waypoints with a 3-D center: a 3-D path at height c_z, as a circle's), checked
    against the DGVF's assumptions: raises :class:`PathError` on ``waypoints`` naming the
    waypoint at fault and the fix."""
    pts = tuple(tuple(float(x) for x in p) for p in waypoints)
    if center is not None and len(center) != len(pts[0]) and not (len(pts[0]) == 2 and len(center) == 3):
        raise PathError("center", f"has {len(center)} coordinates, the waypoints {len(pts[0])}: give it "
                                  f"{len(pts[0])} (or 3 with 2-D waypoints: a path at height z)")
    n = len(pts)
    least = 3 if closed else 2
    if n < least:
        raise PathError("waypoints", f"a {'closed' if closed else 'open'} spline needs at least {least} waypoints, got "
                                     f"{n}: add waypoints" + (" (or set closed = false for a single leg)" if closed else ""))
    legs = list(range(n if closed else n - 1))
    for i in legs:
        j = (i + 1) % n
        gap = _norm(_sub(pts[j], pts[i]))
        if gap < MIN_GAP:
            fix = (f"a closed spline joins its last waypoint to its first itself: drop waypoint {i}"
                   if closed and j == 0 else "drop one of them")
            raise PathError("waypoints", f"waypoint {max(i, j)} {_show(pts[max(i, j)])} repeats waypoint {min(i, j)} "
                                         f"{_show(pts[min(i, j)])} ({gap:g} m apart, under {MIN_GAP:g} m): {fix}")
    for i in range(n) if closed else range(1, n - 1):
        into, out = _sub(pts[i], pts[i - 1]), _sub(pts[(i + 1) % n], pts[i])
        cos = _dot(into, out) / (_norm(into) * _norm(out))
        turn = math.degrees(math.acos(max(-1.0, min(1.0, cos))))
        if turn > MAX_TURN:
            raise PathError("waypoints", f"waypoint {i} {_show(pts[i])}: the path turns back by {turn:.0f}° there "
                                         f"(more than {MAX_TURN:g}°): a cusp, where the curve would stop or loop; "
                                         f"round the turn with a waypoint beside it, or move it")
    shown = pts
    if center is not None:
        pts = tuple(tuple(x + c for x, c in zip(p, center)) + tuple(center[len(p):]) for p in pts)
    chords = [_norm(_sub(pts[(i + 1) % n], pts[i])) for i in legs]
    arcs = [_arc(seg, h) for seg, h in zip(_fit(pts, chords, closed), chords)]
    segs = _fit(pts, arcs, closed)
    knots = [0.0]
    for h in arcs:
        knots.append(knots[-1] + h)
    for i, (seg, h) in enumerate(zip(segs, arcs)):
        speeds = [_norm(_at(seg, h * k / SPEED_SAMPLES)[1]) for k in range(SPEED_SAMPLES + 1)]
        worst = min(speeds) if min(speeds) < MIN_SPEED else max(speeds)
        if not MIN_SPEED <= worst <= MAX_SPEED:
            j = (i + 1) % n
            raise PathError("waypoints", f"between waypoint {i} {_show(shown[i])} and waypoint {j} {_show(shown[j])} the "
                                         f"curve's speed {'falls' if worst < MIN_SPEED else 'rises'} to {worst:.2f} of "
                                         f"the speed asked (allowed: {MIN_SPEED:g} to {MAX_SPEED:g}; "
                                         f"{'near a cusp' if worst < MIN_SPEED else 'an overshoot'}): the waypoints "
                                         f"around it are spaced too unevenly for their turns; space them more evenly "
                                         f"or add one between")
    return Spline(pts, closed, tuple(knots), segs, beta, direction)


def _fit(pts: tuple[Vec, ...], hs: list[float], closed: bool) -> tuple[Segment, ...]:
    """The cubic spline's segments through ``pts`` with parameter spacings ``hs``: periodic
    (closed) or natural (open), from its second derivatives M at the waypoints."""
    n, dim = len(pts), len(pts[0])
    m = len(hs)  # segments: n closed, n - 1 open
    ms = []  # M per axis, at each waypoint
    for k in range(dim):
        y = [p[k] for p in pts]
        slope = [(y[(i + 1) % n] - y[i]) / hs[i] for i in range(m)]
        if closed:
            sub = [hs[i - 1] for i in range(n)]
            diag = [2.0 * (hs[i - 1] + hs[i]) for i in range(n)]
            sup = [hs[i] for i in range(n)]
            rhs = [6.0 * (slope[i] - slope[i - 1]) for i in range(n)]
            ms.append(_cyclic(sub, diag, sup, rhs))
        elif n == 2:
            ms.append([0.0, 0.0])
        else:
            sub = [hs[i - 1] for i in range(1, n - 1)]
            diag = [2.0 * (hs[i - 1] + hs[i]) for i in range(1, n - 1)]
            sup = [hs[i] for i in range(1, n - 1)]
            rhs = [6.0 * (slope[i] - slope[i - 1]) for i in range(1, n - 1)]
            ms.append([0.0] + _tridiagonal(sub, diag, sup, rhs) + [0.0])
    segs = []
    for i in range(m):
        j, h = (i + 1) % n, hs[i]
        a = pts[i]
        b = tuple((pts[j][k] - pts[i][k]) / h - h * (2.0 * ms[k][i] + ms[k][j]) / 6.0 for k in range(dim))
        c = tuple(ms[k][i] / 2.0 for k in range(dim))
        d = tuple((ms[k][j] - ms[k][i]) / (6.0 * h) for k in range(dim))
        segs.append((a, b, c, d))
    return tuple(segs)


def _tridiagonal(sub: list[float], diag: list[float], sup: list[float], rhs: list[float]) -> list[float]:
    """x with sub[i] x[i-1] + diag[i] x[i] + sup[i] x[i+1] = rhs[i] (Thomas; the spline's
    matrix is strictly diagonally dominant, so no pivoting is needed)."""
    n = len(diag)
    c, d = [0.0] * n, [0.0] * n
    for i in range(n):
        den = diag[i] - (sub[i] * c[i - 1] if i else 0.0)
        c[i] = sup[i] / den
        d[i] = (rhs[i] - (sub[i] * d[i - 1] if i else 0.0)) / den
    x = [0.0] * n
    for i in range(n - 1, -1, -1):
        x[i] = d[i] - (c[i] * x[i + 1] if i < n - 1 else 0.0)
    return x


def _cyclic(sub: list[float], diag: list[float], sup: list[float], rhs: list[float]) -> list[float]:
    """The same with the corners sub[0] (of x[n-1] in row 0) and sup[n-1] (of x[0] in row n-1):
    Sherman-Morrison on the tridiagonal part (n >= 3)."""
    n = len(diag)
    gamma = -diag[0]
    dd = list(diag)
    dd[0] -= gamma
    dd[-1] -= sup[-1] * sub[0] / gamma
    x = _tridiagonal(sub, dd, sup, rhs)
    u = [0.0] * n
    u[0], u[-1] = gamma, sup[-1]
    z = _tridiagonal(sub, dd, sup, u)
    fact = (x[0] + sub[0] * x[-1] / gamma) / (1.0 + z[0] + sub[0] * z[-1] / gamma)
    return [xi - fact * zi for xi, zi in zip(x, z)]


def _arc(seg: Segment, h: float) -> float:
    """The length of one segment (8-point Gauss-Legendre of |S'|)."""
    return 0.5 * h * sum(wt * _norm(_at(seg, 0.5 * h * (1.0 + x))[1]) for x, wt in _GAUSS)


def _spline(waypoints: tuple[Vec, ...], closed: bool, center: Vec | None, beta: float, direction: float) -> Spline:
    return spline(waypoints, closed, beta, direction, center)


register(Family(
    "spline", "waypoints=[[x, y(, z)], ...] (3 or more; 2 or more when closed = false), closed (true), "
              "center=[x, y(, z)] (moves them; a 3-D center lifts 2-D waypoints to height z)",
    (Param("waypoints", "points", required=True), Param("closed", "flag", default=True),
     Param("center", "vector")),
    _spline, speed="1"))


def _sub(p: Vec, q: Vec) -> Vec:
    return tuple(a - b for a, b in zip(p, q))


def _dot(p: Vec, q: Vec) -> float:
    return sum(a * b for a, b in zip(p, q))


def _norm(p: Vec) -> float:
    return math.sqrt(_dot(p, p))


def _show(p: Vec) -> str:
    return "[" + ", ".join(f"{x:g}" for x in p) + "]"

"""Where on a path is a vehicle, and what does a vehicle of fewer axes follow? The geometry
every family shares: the x, y of a 3-D path (:class:`Planar`), the probe for non-finite values,
and the ω of the point nearest a position (:func:`nearest_omega`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from cdus.core.paths.registry import Path, PathError, Vec
from cdus.wire.bounds import MAX_PHASE


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

    @property
    def span(self) -> tuple[float, float] | None:
        return getattr(self.inner, "span", None)

    def eval(self, w: float) -> tuple[Vec, Vec, Vec]:
        f, f1, f2 = self.inner.eval(w)
        return f[:2], f1[:2], f2[:2]


def for_dimension(path: Path, dim: int) -> Path:
    """The path as a vehicle of dimension ``dim`` follows it (a USV takes x, y of a 3-D path).

    Raises ``PathError`` for a 3-D vehicle on a planar path.
    """
    if path.dim == dim:
        return path
    if path.dim == 3 and dim == 2:
        return Planar(path)
    fix = ("give the center/origin a z component; a spline: give its waypoints a z component, or a center "
           "[x, y, z] to fly it at height z")
    raise PathError("path", f"a {dim}-D vehicle needs a {dim}-D path; this one is {path.dim}-D ({fix})")


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
    refined by Newton on g(ω) = (f(ω) - q)·f'(ω). Open paths with a ``span`` (the ω interval
    of an open curve's body, beyond which it runs straight on: a spline through waypoints):
    the best of ``samples`` points over the span, refined so. Other open paths: Newton from
    ``hint``. On a closed path the result lies within one period of ``hint``, so it can
    continue an unwrapped ω.
    """
    period = path.period
    span = getattr(path, "span", None) if period is None else None
    if period is None and span is None:
        w = hint
    else:
        if period is None:
            hint, period = span[0], span[1] - span[0]
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

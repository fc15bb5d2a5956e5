"""Collision avoidance: a minimally invasive control-barrier-function filter (docs/safety.md).

For vehicle i with velocity reference u_ref and every sensed vehicle k, with
h_ik = |q_i - q_k|² - R² (h ≥ 0: at least R apart), the safe set is kept invariant by
ḣ_ik ≥ -γ h_ik (the paper's remark prints ḣ ≤ h, which is wrong: it lets h fall).
Neither vehicle knows the other's velocity, so each takes its share w of each pair
constraint (w = 1/2 between two vehicles that both run the filter):

    u = argmin |u - u_ref|²   s.t.   2 (q_i - q_k)ᵀ u ≥ -w γ h_ik   for every contact k

and the two halves add up to the pair constraint 2 (q_i - q_k)ᵀ (u_i - u_k) ≥ -γ h_ik.
A contact that does not react (a boat seen by a drone) is taken whole: w = 1.

A pure function in the spirit of the Robotarium barrier certificates: positions and
velocities in, a velocity out, no state, no I/O. Each row is normalised to a unit
normal n̂ = (q_i - q_k)/|q_i - q_k| and a required speed β along it. Solved in order of
cost: u_ref itself if it is safe; the projection on one violated constraint if that
satisfies the others (then it is the QP's optimum: it solves a relaxation); else the QP
with quadprog (Goldfarb-Idnani dual active set, compiled, exact for these small dense
problems).

What never raises and never freezes:

- *Inside R* (h < 0) the constraint asks for separation at β = wγ(R² - |d|²)/(2|d|),
  which grows without bound as |d| → 0; |d| is floored at ``ESCAPE_FLOOR`` R there so
  the requirement stays finite.
- *Contradicting constraints* (squeezed between vehicles that are inside R): the QP is
  infeasible; then the filter solves the same problem with one slack δ ≥ 0 relaxing every
  row, n̂ᵀu ≥ β - δ, penalised by ``SLACK_WEIGHT`` δ²: the least worst violation, then
  the u nearest u_ref. ``info.slack`` reports δ.
- *Coincident positions* have no direction. Given ids, the pair separates along a
  direction derived from both ids, opposite for the two (the same for every run); without
  ids, along u_ref.
- *Deadlock*: two vehicles heading straight at each other stop when the filter takes all
  of u_ref (so do four meeting at a crossing). When |u| falls below ``sidestep`` |u_ref|,
  the reference is turned to starboard about the vertical, by up to ``SIDESTEP_ANGLE``
  in proportion to how far |u| fell, and the QP solved again: everyone turns right, as
  boats do head-on, and a blocked crossing turns into a roundabout. The constraints
  still hold; only the reference changed.
- *Speed bound* (optional): u is scaled radially to |u| ≤ ``speed``. Scaling towards 0
  keeps every constraint with β ≤ 0 (all contacts outside R), since u = 0 satisfies them.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from typing import Sequence

import numpy as np
import quadprog

from cdus.core.paths import Vec

SOLVER = "quadprog (Goldfarb-Idnani dual active set)"
# Inside R the required separation speed uses |d| ≥ ESCAPE_FLOOR · R.
ESCAPE_FLOOR = 0.1
# Penalty on the slack of an infeasible problem (per (m/s)²); the distance to u_ref costs 1.
SLACK_WEIGHT = 1.0e4
# A fully blocked reference is turned this far to starboard (rad): past 90°, so that
# backing away to the right is possible when the way to the right is also blocked.
SIDESTEP_ANGLE = math.radians(135.0)
# |q_i - q_k| below this (m) counts as coincident: no direction to separate along.
COINCIDENT = 1e-9


@dataclass(frozen=True)
class SafetyParams:
    """The filter's parameters.

    radius: R, the smallest allowed distance between two vehicles (m).
    gamma: γ of ḣ ≥ -γ h (1/s): how fast the filter lets vehicles close in on R.
    speed: optional bound on |u| (m/s), applied last.
    sidestep: κ in [0, 1): below |u| < κ |u_ref| the reference is turned to starboard; 0 disables.
    tolerance: |u - u_ref| above this (m/s) counts as an intervention.
    """

    radius: float
    gamma: float = 1.0
    speed: float = math.inf
    sidestep: float = 0.3
    tolerance: float = 1e-6

    def __post_init__(self) -> None:
        for name in ("radius", "gamma", "speed", "tolerance"):
            x = getattr(self, name)
            if not (isinstance(x, (int, float)) and x > 0 and not math.isnan(x)):
                raise ValueError(f"safety.{name}: must be a number > 0, got {x!r}")
        if not (isinstance(self.sidestep, (int, float)) and 0.0 <= self.sidestep < 1.0):
            raise ValueError(f"safety.sidestep: must be in [0, 1) (0 disables it), got {self.sidestep!r}")


@dataclass(frozen=True, slots=True)
class Contact:
    """A sensed vehicle: its position, its id (if known) and the share w of the pair
    constraint this vehicle takes (1/2 when both avoid each other, 1 when only this one does)."""

    q: Vec
    id: str | None = None
    share: float = 0.5


@dataclass(frozen=True)
class FilterInfo:
    """What the filter did.

    intervened: |u - u_ref| > tolerance.
    active: indices of the contacts whose constraint binds (or is violated) at u.
    satisfied: every constraint holds at u (False: inside R and unable to leave at the
        rate γ asks, or held back by the speed bound).
    method: "pass" (u_ref was safe), "projection" (one constraint, closed form), "qp",
        "relaxed" (infeasible: least worst violation).
    slack: δ of the relaxed problem (m/s along the normal), 0 otherwise.
    sidestep: weight in [0, 1] of the starboard turn against a deadlock.
    min_h: the smallest h_ik = |q_i - q_k|² - R² (m²; negative: inside R); inf without contacts.
    """

    intervened: bool
    active: tuple[int, ...]
    satisfied: bool
    method: str
    slack: float = 0.0
    sidestep: float = 0.0
    min_h: float = math.inf


PASS = FilterInfo(False, (), True, "pass")


def barrier(q: Vec, qk: Vec, radius: float) -> float:
    """h = |q - q_k|² - R²."""
    return sum((a - b) ** 2 for a, b in zip(q, qk)) - radius * radius


def _pair_direction(me: str, other: str, dim: int) -> Vec:
    """A unit horizontal direction fixed by the pair of ids, opposite for the two vehicles."""
    lo, hi = sorted((me, other))
    angle = 2.0 * math.pi * zlib.crc32(f"{lo}|{hi}".encode()) / 2.0 ** 32
    sign = 1.0 if me == lo else -1.0
    d = (sign * math.cos(angle), sign * math.sin(angle))
    return d if dim == 2 else d + (0.0,) * (dim - 2)


def _rows(u_ref: Vec, q: Vec, contacts: Sequence[Contact | Vec], params: SafetyParams,
          me: str | None) -> tuple[list[Vec], list[float], float]:
    """Unit normals n̂_k, required speeds β_k (n̂_kᵀu ≥ β_k), and min h."""
    dim = len(q)
    R = params.radius
    normals: list[Vec] = []
    betas: list[float] = []
    min_h = math.inf
    for c in contacts:
        if isinstance(c, Contact):
            qk, cid, share = c.q, c.id, c.share
        else:
            qk, cid, share = c, None, 0.5
        if len(qk) != dim:
            raise ValueError(f"safety: a contact has {len(qk)} coordinates, the vehicle {dim}")
        if not 0.0 < share <= 1.0:
            raise ValueError(f"safety: contact share must be in (0, 1], got {share!r}")
        d = tuple(a - b for a, b in zip(q, qk))
        dist = math.sqrt(sum(x * x for x in d))
        if not math.isfinite(dist):
            normals.append((0.0,) * dim)  # a sensor glitch constrains nothing
            betas.append(-math.inf)
            continue
        h = dist * dist - R * R
        min_h = min(min_h, h)
        if dist > COINCIDENT:
            n = tuple(x / dist for x in d)
        elif me is not None and cid is not None and cid != me:
            n = _pair_direction(me, cid, dim)
        else:
            nu = math.sqrt(sum(x * x for x in u_ref))
            n = tuple(x / nu for x in u_ref) if nu > 0.0 else (1.0,) + (0.0,) * (dim - 1)
        eff = dist if h >= 0.0 else max(dist, ESCAPE_FLOOR * R)
        normals.append(n)
        betas.append(-share * params.gamma * h / (2.0 * eff))
    return normals, betas, min_h


def _dot(a: Vec, b: Vec) -> float:
    return sum(x * y for x, y in zip(a, b))


def _solve(u_ref: Vec, normals: list[Vec], betas: list[float], tol: float) -> tuple[Vec, str, float]:
    """min |u - u_ref|² s.t. n̂ᵀu ≥ β, cheapest first; never raises."""
    viol = [b - _dot(n, u_ref) for n, b in zip(normals, betas)]
    worst = max(range(len(viol)), key=viol.__getitem__)
    if viol[worst] <= tol:
        return u_ref, "pass", 0.0
    n = normals[worst]
    u = tuple(x + viol[worst] * y for x, y in zip(u_ref, n))
    if all(_dot(nk, u) >= bk - tol for nk, bk in zip(normals, betas)):
        return u, "projection", 0.0
    rows = [k for k, b in enumerate(betas) if b > -math.inf]
    N = np.array([normals[k] for k in rows], dtype=float)
    B = np.array([betas[k] for k in rows], dtype=float)
    dim = len(u_ref)
    try:
        x = quadprog.solve_qp(np.eye(dim), np.array(u_ref, dtype=float), np.ascontiguousarray(N.T), B, 0)[0]
        return tuple(float(v) for v in x), "qp", 0.0
    except ValueError:
        pass  # infeasible: relax below
    m = len(rows)
    G = np.eye(dim + 1)
    G[dim, dim] = SLACK_WEIGHT
    a = np.zeros(dim + 1)
    a[:dim] = u_ref
    C = np.zeros((dim + 1, m + 1))
    C[:dim, :m] = N.T
    C[dim, :] = 1.0
    b = np.zeros(m + 1)
    b[:m] = B
    try:
        x = quadprog.solve_qp(G, a, C, b, 0)[0]
        return tuple(float(v) for v in x[:dim]), "relaxed", float(x[dim])
    except ValueError:  # numerically degenerate: the most violated constraint alone
        return u, "relaxed", max(0.0, max(b - _dot(nk, u) for nk, b in zip(normals, betas)))


def _turn_starboard(u: Vec, angle: float) -> Vec:
    """u turned clockwise (seen from above) by ``angle`` rad about the vertical."""
    c, s = math.cos(angle), math.sin(angle)
    return (c * u[0] + s * u[1], -s * u[0] + c * u[1]) + tuple(u[2:])


def safety_filter(u_ref: Vec, q: Vec, contacts: Sequence[Contact | Vec], params: SafetyParams,
                  me: str | None = None) -> tuple[Vec, FilterInfo]:
    """The safe velocity nearest ``u_ref`` for a vehicle at ``q`` among ``contacts``.

    ``contacts``: :class:`Contact`s (or bare positions, taken with share 1/2), in the
    vehicle's dimension (2 for a USV, 3 for a UAV); ``me``: this vehicle's id, used only
    to separate from a contact at exactly the same position. Returns (u, info).
    """
    u_ref = tuple(float(x) for x in u_ref)
    if len(u_ref) != len(q):
        raise ValueError(f"safety: u_ref has {len(u_ref)} components, q has {len(q)}")
    if not all(math.isfinite(x) for x in u_ref + tuple(q)):
        raise ValueError(f"safety: u_ref and q must be finite, got u_ref={u_ref}, q={tuple(q)}")
    if not contacts:
        return _bound(u_ref, u_ref, params, PASS, [], [])
    normals, betas, min_h = _rows(u_ref, q, contacts, params, me)
    tol = params.tolerance
    u, method, slack = _solve(u_ref, normals, betas, tol)
    weight = 0.0
    nref = math.sqrt(_dot(u_ref, u_ref))
    if params.sidestep > 0.0 and method != "pass" and nref > tol:
        nu = math.sqrt(_dot(u, u))
        if nu < params.sidestep * nref:
            weight = 1.0 - nu / (params.sidestep * nref)
            u, method, slack = _solve(_turn_starboard(u_ref, weight * SIDESTEP_ANGLE), normals, betas, tol)
    info = FilterInfo(False, (), True, method, slack, weight, min_h)
    return _bound(u_ref, u, params, info, normals, betas)


def _bound(u_ref: Vec, u: Vec, params: SafetyParams, info: FilterInfo, normals: list[Vec],
           betas: list[float]) -> tuple[Vec, FilterInfo]:
    """Apply the speed bound, then fill in intervened / active / satisfied."""
    if params.speed != math.inf:
        n = math.sqrt(_dot(u, u))
        if n > params.speed:
            u = tuple(x * params.speed / n for x in u)
    tol = params.tolerance
    margins = [_dot(n, u) - b for n, b in zip(normals, betas)]
    active = tuple(k for k, m in enumerate(margins) if m <= tol)
    satisfied = all(m >= -tol for m in margins)
    intervened = math.sqrt(sum((a - b) ** 2 for a, b in zip(u, u_ref))) > tol
    return u, FilterInfo(intervened, active, satisfied, info.method, info.slack, info.sidestep, info.min_h)

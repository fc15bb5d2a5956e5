"""What velocity keeps a vehicle clear of the others it senses? Collision avoidance: a minimally
invasive control-barrier-function filter (docs/safety.md).

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
- *Obstacles* (``params.obstacles``, cdus.core.obstacles): one row each, n̂ᵀu ≥ -γ (d - margin),
  taken whole. A vehicle an obstacle blocks (its row binds, u_ref points into it, |u| fell below
  ``sidestep`` |u_ref|) commits to a way round it along its surface (``FilterInfo.way``, passed
  back in by the caller) until it no longer blocks: a starboard turn stalled there.
- *Speed bound* (optional): u is scaled radially to |u| ≤ ``speed``. Scaling towards 0
  keeps every constraint with β ≤ 0 (all contacts outside R), since u = 0 satisfies them.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

# numpy and quadprog are imported where a QP is solved, not here: a vehicle process whose filter
# never needs one (or that has none) does not load them (numpy is ~14 MB of RSS per process)
from cdus.core.obstacles import Obstacle, clearance
from cdus.core.paths import Vec
from cdus.core.points import (  # noqa: F401  (what the dynamic filter sees of a vehicle: importable from here too)
    UAV_BRAKING_SHARE, UAV_NOMINAL_ACCEL, USV_BRAKING, USV_MARGIN, USV_NOMINAL_ACCEL, Point, uav_point, usv_point,
)

if TYPE_CHECKING:
    import numpy as np

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
    obstacles: the [[obstacle]]s this vehicle avoids (cdus.core.obstacles), each a row
        n̂ᵀu ≥ -γ (d - margin - obstacle_pad) (d: signed distance, n̂: outward normal).
    """

    radius: float
    gamma: float = 1.0
    speed: float = math.inf
    sidestep: float = 0.3
    tolerance: float = 1e-6
    obstacles: tuple[Obstacle, ...] = ()
    obstacle_pad: float = 0.0  # m added to every obstacle's margin (the reference shaper's, cdus.core.vehicle)

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
    by_obstacle: an obstacle's row binds (or is violated) at u and the filter changed the reference.
    """

    intervened: bool
    active: tuple[int, ...]
    satisfied: bool
    method: str
    slack: float = 0.0
    sidestep: float = 0.0
    min_h: float = math.inf
    by_obstacle: bool = False
    way: int = 0  # round a blocking obstacle: +1 anticlockwise, -1 clockwise (seen from above), 0 not


PASS = FilterInfo(False, (), True, "pass")


def barrier(q: Vec, qk: Vec, radius: float) -> float:
    """h = |q - q_k|² - R²."""
    return sum((a - b) * (a - b) for a, b in zip(q, qk)) - radius * radius  # x * x: inf, not OverflowError


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
        eff = eff if eff > 0.0 else COINCIDENT  # R² underflowed (R < 1e-154 m): h = 0 at |d| = 0
        normals.append(n)
        betas.append(-share * params.gamma * h / (2.0 * eff))
    for o in params.obstacles:  # last: rows past the contacts' are the obstacles' (FilterInfo.by_obstacle)
        cl = clearance(o, q)
        normals.append(cl.normal)
        betas.append(-params.gamma * (cl.distance - o.margin - params.obstacle_pad))
    return normals, betas, min_h


def _dot(a: Vec, b: Vec) -> float:
    return sum(x * y for x, y in zip(a, b))


def _solve_qp(G: np.ndarray, a: np.ndarray, C: np.ndarray, b: np.ndarray) -> np.ndarray:
    """quadprog's min ½xᵀGx - aᵀx s.t. Cᵀx ≥ b, solved on the problem scaled to O(1): x = s x'
    with s = max(1, |a|∞, |b|∞), so a' = a/s, b' = b/s and the minimiser is s x'. Unscaled,
    the dual active-set iterations never ended on rows of 1e33 (found by Hypothesis: a freeze
    inside the compiled solver, which no timeout can stop). ValueError for non-finite data
    (as quadprog's own for an infeasible problem: the callers relax or fall back)."""
    import numpy as np
    import quadprog
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)) and np.all(np.isfinite(C))):
        raise ValueError("safety: non-finite QP data")
    s = max(1.0, float(np.max(np.abs(a), initial=0.0)), float(np.max(np.abs(b), initial=0.0)))
    return quadprog.solve_qp(G, a / s, C, b / s, 0)[0] * s


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
    import numpy as np

    rows = [k for k, b in enumerate(betas) if b > -math.inf]
    N = np.array([normals[k] for k in rows], dtype=float)
    B = np.array([betas[k] for k in rows], dtype=float)
    dim = len(u_ref)
    try:
        x = _solve_qp(np.eye(dim), np.array(u_ref, dtype=float), np.ascontiguousarray(N.T), B)
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
        x = _solve_qp(G, a, C, b)
        return tuple(float(v) for v in x[:dim]), "relaxed", float(x[dim])
    except ValueError:  # numerically degenerate: the most violated constraint alone
        return u, "relaxed", max(0.0, max(b - _dot(nk, u) for nk, b in zip(normals, betas)))


def _blocking(u_ref: Vec, u: Vec, normals: list[Vec], betas: list[float], n_obstacles: int, tol: float
              ) -> tuple[float, float] | None:
    """The horizontal unit normal of the obstacle the vehicle pushes into (its row binds at ``u``
    and u_ref points into it; the most squarely of such), or None (also when it blocks from
    straight above or below: no way round about the vertical)."""
    first = len(normals) - n_obstacles
    rows = [(_dot(n, u_ref), n) for n, b in zip(normals[first:], betas[first:]) if _dot(n, u) - b <= tol]
    into = min(rows, default=None, key=lambda r: r[0])
    if into is None or into[0] >= 0.0:
        return None
    n = into[1]
    h = math.hypot(n[0], n[1])
    return None if h < 1e-6 else (n[0] / h, n[1] / h)


def _turn_starboard(u: Vec, angle: float) -> Vec:
    """u turned clockwise (seen from above) by ``angle`` rad about the vertical."""
    c, s = math.cos(angle), math.sin(angle)
    return (c * u[0] + s * u[1], -s * u[0] + c * u[1]) + tuple(u[2:])


def safety_filter(u_ref: Vec, q: Vec, contacts: Sequence[Contact | Vec], params: SafetyParams,
                  me: str | None = None, way: int = 0) -> tuple[Vec, FilterInfo]:
    """The safe velocity nearest ``u_ref`` for a vehicle at ``q`` among ``contacts``.

    ``contacts``: :class:`Contact`s (or bare positions, taken with share 1/2), in the
    vehicle's dimension (2 for a USV, 3 for a UAV); ``me``: this vehicle's id, used only
    to separate from a contact at exactly the same position; ``way``: the way round an obstacle
    this vehicle took at its last call (``info.way``: +1 anticlockwise, -1 clockwise, 0 none).
    Returns (u, info).
    """
    u_ref = tuple(float(x) for x in u_ref)
    if len(u_ref) != len(q):
        raise ValueError(f"safety: u_ref has {len(u_ref)} components, q has {len(q)}")
    if not all(math.isfinite(x) for x in u_ref + tuple(q)):
        raise ValueError(f"safety: u_ref and q must be finite, got u_ref={u_ref}, q={tuple(q)}")
    if not contacts and not params.obstacles:
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
    n = _blocking(u_ref, u, normals, betas, len(params.obstacles), tol) if params.obstacles and nref > tol else None
    if n is None:
        way = 0
    elif way == 0 and weight > 0.0:  # stalled against it: commit to the way the filter slides it
        way = -1 if n[0] * u[1] - n[1] * u[0] < -tol else 1  # none: anticlockwise, a turn to starboard
    if way and n is not None:  # round the obstacle that way at u_ref's horizontal speed (docs/safety.md)
        speed = math.hypot(u_ref[0], u_ref[1])
        u, method, slack = _solve((-way * n[1] * speed, way * n[0] * speed) + tuple(u_ref[2:]), normals, betas, tol)
    elif weight > 0.0:
        u, method, slack = _solve(_turn_starboard(u_ref, weight * SIDESTEP_ANGLE), normals, betas, tol)
    info = FilterInfo(False, (), True, method, slack, weight, min_h, way=way)
    return _bound(u_ref, u, params, info, normals, betas, len(params.obstacles))


def _bound(u_ref: Vec, u: Vec, params: SafetyParams, info: FilterInfo, normals: list[Vec],
           betas: list[float], n_obstacles: int = 0) -> tuple[Vec, FilterInfo]:
    """Apply the speed bound, then fill in intervened / active / satisfied."""
    if params.speed != math.inf:
        n = math.sqrt(_dot(u, u))
        if n > params.speed:
            u = tuple(x * params.speed / n for x in u)
    tol = params.tolerance
    margins = [_dot(n, u) - b for n, b in zip(normals, betas)]
    active = tuple(k for k, m in enumerate(margins) if m <= tol)
    satisfied = all(m >= -tol for m in margins)
    intervened = math.dist(u, u_ref) > tol  # (a - b) ** 2 raised OverflowError on a huge u
    obstacle = intervened and any(k >= len(normals) - n_obstacles for k in active)
    return u, FilterInfo(intervened, active, satisfied, info.method, info.slack, info.sidestep, info.min_h, obstacle,
                         info.way)


# =========================================================================== on the dynamics
#
# The filter above is exact only for a vehicle whose velocity is its reference (the ideal
# plant). For the others, :func:`dynamic_filter` acts on the inputs the plant takes (τ of a
# UAV, (τ_u, τ_r) of a USV) at the physics rate, inside the regulator's step. Each vehicle
# is a point p (its position) with p̈ = f + G τ (:class:`Point`). Between two of them, with
# braking A along the line of sight, the barrier of Wang, Ames and Egerstedt (2017),
#
#     h = sqrt(2 A (|Δp| - D)) + ḋ,    ḋ = n̂ᵀΔv,  n̂ = Δp/|Δp|,
#
# is ≥ 0 exactly when braking at A along n̂ stops the pair before |Δp| = D. Its derivative
# is ḣ = A ḋ / sqrt(2 A (|Δp| - D)) + n̂ᵀΔa + (|Δv|² - ḋ²)/|Δp|, and ḣ ≥ -γ h reads
# n̂ᵀ(a_i - a_k) ≥ rhs. Vehicle i, not knowing a_k, asks n̂ᵀ a_i ≥ max(rhs, w rhs) (its
# share w of a permission to close, the whole of a demand to brake): if both do, the pair
# condition holds; if the other cannot act along n̂ (a boat side-on) or does not react
# (w = 1), the demand is still met by this one. docs/safety.md derives it and says where it
# breaks.

# The slack of an infeasible dynamic problem costs this much per (m/s²)² (inputs per unit of full scale).
DYN_SLACK_WEIGHT = 1.0e4
# ||Δp| - D| is floored at this (m), so the requirement stays finite at D (where it cannot
# be met the QP takes the least worst violation: the strongest push the inputs allow).
DYN_GAP_FLOOR = 0.01
# A UAV's |τ| ≤ accel is a ball; the QP meets it by cutting planes, at most this many.
BALL_CUTS = 6


@dataclass(frozen=True, slots=True)
class Track:
    """A neighbour as estimated now: position and velocity extrapolated from the sensor's
    sample, its share, and the margins on position (``dp``, m) and velocity (``dv``, m/s)
    the estimate may be off by."""

    p: Vec
    v: Vec
    share: float = 0.5
    dp: float = 0.0
    dv: float = 0.0
    id: str | None = None


def pair_demand(dp: Vec, dv: Vec, radius: float, alpha: float, gamma: float, share: float,
                margin_p: float = 0.0, margin_v: float = 0.0) -> tuple[Vec, float, float]:
    """(n̂, b, h): vehicle i must keep n̂ᵀ a_i ≥ b for the pair with relative position
    ``dp`` = p_i - p_k and velocity ``dv``; h is the barrier's value (negative: the pair
    cannot stop before ``radius`` + ``margin_p`` braking at ``alpha``)."""
    dim = len(dp)
    dist = math.sqrt(sum(x * x for x in dp))
    n = tuple(x / dist for x in dp) if dist > COINCIDENT else (1.0,) + (0.0,) * (dim - 1)
    ddot = _dot(n, dv)
    vt2 = max(0.0, _dot(dv, dv) - ddot * ddot)
    rhs, h = braking(dist - (radius + margin_p), ddot, vt2 / max(dist, ESCAPE_FLOOR * radius), alpha, gamma, margin_v)
    return n, max(rhs, share * rhs), h


def braking(gap: float, ddot: float, bend: float, alpha: float, gamma: float, margin_v: float = 0.0
            ) -> tuple[float, float]:
    """(rhs, h) of the braking barrier at distance ``gap`` past D closing at -``ddot``: n̂ᵀa ≥ rhs
    (``bend``: |v_t|²/ρ, what moving across n̂ adds to ḋ's derivative, ρ the radius n̂ turns about).
    Inside D the same barrier with -sqrt(2 A (D - |Δp|)): h < 0, and ḣ ≥ -γ h drives the pair out,
    separating at up to sqrt(2 A (D - |Δp|)) (its derivative has the same form)."""
    root = math.sqrt(2.0 * alpha * max(abs(gap), DYN_GAP_FLOOR))
    h = (root if gap > 0.0 else -root) + ddot - margin_v
    return -gamma * h - alpha * ddot / root - bend, h


def _dyn_rows(me: Point, tracks: Sequence[Track], params: SafetyParams, mid: str | None
              ) -> tuple[list[Vec], list[float], float, int]:
    """Per track, then per obstacle, a row c and bound b (m/s²) of c·z ≥ b (z = τ / scale), the
    smallest |Δp|² - D² (m²; negative: inside D) and how many rows are the tracks'."""
    dim = len(me.p)
    demands: list[tuple[Vec, float]] = []
    min_h = math.inf
    for t in tracks:
        if len(t.p) != dim or len(t.v) != dim:
            raise ValueError(f"safety: a track has {len(t.p)} coordinates, the vehicle {dim}")
        if not 0.0 < t.share <= 1.0:
            raise ValueError(f"safety: track share must be in (0, 1], got {t.share!r}")
        dp = tuple(a - b for a, b in zip(me.p, t.p))
        dv = tuple(a - b for a, b in zip(me.v, t.v))
        if not all(math.isfinite(x) for x in dp + dv + (t.dp, t.dv)):
            continue  # a sensor glitch constrains nothing
        dist2 = _dot(dp, dp)
        D = params.radius + me.margin + t.dp
        min_h = min(min_h, dist2 - D * D)
        if dist2 <= COINCIDENT ** 2 and mid is not None and t.id is not None and t.id != mid:
            dp = _pair_direction(mid, t.id, dim)  # coincident: separate along a direction fixed by the ids
            dp = tuple(COINCIDENT * x for x in dp)
        n, b, _ = pair_demand(dp, dv, params.radius + me.margin, me.alpha / t.share, params.gamma, t.share, t.dp,
                              t.dv)
        demands.append((n, b))
    rows, bounds = _dyn_constraints(me, demands)
    n_tracks = len(rows)
    for o in params.obstacles:  # a static track that does not react (share 1); ρ: the surface's bend
        cl = clearance(o, me.p)
        ddot = _dot(cl.normal, me.v)
        bend = max(0.0, _dot(me.v, me.v) - ddot * ddot) / max(cl.distance + cl.bend, ESCAPE_FLOOR * params.radius)
        demands = [(cl.normal, braking(cl.distance - (o.margin + me.margin), ddot, bend, me.alpha, params.gamma)[0])]
        more = _dyn_constraints(me, demands)
        rows += more[0]
        bounds += more[1]
    return rows, bounds, min_h, n_tracks


def _dyn_constraints(me: Point, demands: list[tuple[Vec, float]]) -> tuple[list[Vec], list[float]]:
    """n̂ᵀ(f + G τ) ≥ b, in z: Σ_m (n̂ᵀG)_m scale_m z_m ≥ b - n̂ᵀf, per demand (n̂, b).
    Rows stay in m/s² (not normalised): the slack of a row then measures the missing
    acceleration, and a row the inputs can hardly act on (a boat side-on) cannot buy
    its slack down by giving up the rows they can act on."""
    dim, scale = len(me.p), me.scale
    rows: list[Vec] = []
    bounds: list[float] = []
    for n, b in demands:
        c = tuple(sum(n[j] * me.G[j][m] for j in range(dim)) * scale[m] for m in range(len(scale)))
        if math.sqrt(_dot(c, c)) < 1e-9:
            continue  # no authority along n̂ at all: the neighbour takes the demand
        b -= _dot(n, me.f)
        if math.isnan(b):
            continue  # huge margins (inf - inf): as a glitch
        rows.append(c)
        bounds.append(b)
    return rows, bounds


def dynamic_filter(tau_ref: Vec, me: Point, tracks: Sequence[Track], params: SafetyParams,
                   mid: str | None = None) -> tuple[Vec, FilterInfo]:
    """The inputs nearest ``tau_ref`` (each scaled by its full-scale value) that keep the
    barrier condition with every track, within the inputs' box and ball. Never raises on a
    situation: an impossible one (inside R, or closing too fast to stop) is solved with a
    slack on each barrier row, heavily weighted: the least worst violations within the
    inputs' bounds (one slack per row, so a row the inputs can hardly act on, a boat
    side-on, does not relax the others). Returns (τ, info); ``tau_ref`` itself, bit for bit, when it is safe."""
    tau_ref = tuple(float(x) for x in tau_ref)
    m = len(tau_ref)
    if m != len(me.lo) or m != len(me.hi) or m != len(me.scale):
        raise ValueError(f"safety: tau_ref has {m} inputs, the vehicle {len(me.lo)}")
    if not all(math.isfinite(x) for x in tau_ref + tuple(me.p) + tuple(me.v) + tuple(me.f)):
        raise ValueError(f"safety: tau_ref and the vehicle's state must be finite, got {tau_ref}, {me}")
    if not tracks and not params.obstacles:
        return tau_ref, PASS
    scale = me.scale
    rows, bounds, min_h, n_tracks = _dyn_rows(me, tracks, params, mid)
    z_ref = tuple(x / s for x, s in zip(tau_ref, scale))
    if all(_dot(c, z_ref) >= b - 1e-12 for c, b in zip(rows, bounds)):
        return tau_ref, FilterInfo(False, (), True, "pass", min_h=min_h)
    k = len(rows)
    nv = m + k  # z, then one slack per row: a row that cannot be met relaxes only itself
    import numpy as np

    G = np.eye(nv)
    for i in range(k):
        G[m + i, m + i] = DYN_SLACK_WEIGHT
    a = np.zeros(nv)
    a[:m] = z_ref
    cols: list[list[float]] = []
    rhs: list[float] = []
    for i, (c, b) in enumerate(zip(rows, bounds)):
        col = list(c) + [0.0] * k
        col[m + i] = 1.0
        cols.append(col)
        rhs.append(b)
        pos = [0.0] * nv  # δ_i ≥ 0
        pos[m + i] = 1.0
        cols.append(pos)
        rhs.append(0.0)
    for j in range(m):
        if math.isfinite(me.lo[j]):
            e = [0.0] * nv
            e[j] = 1.0
            cols.append(e)
            rhs.append(me.lo[j] / scale[j])
        if math.isfinite(me.hi[j]):
            e = [0.0] * nv
            e[j] = -1.0
            cols.append(e)
            rhs.append(-me.hi[j] / scale[j])
    x = None
    for _ in range(BALL_CUTS + 1):
        try:
            x = _solve_qp(G, a, np.array(cols, dtype=float).T, np.array(rhs, dtype=float))
        except ValueError:
            x = None
            break
        if not all(math.isfinite(v) for v in x):  # huge bounds (a margin of 1e304 m/s): as degenerate
            x = None
            break
        if not math.isfinite(me.ball):
            break
        tau = [float(x[j]) * scale[j] for j in range(m)]  # Python floats: inf past the range, no warning
        nt = math.sqrt(sum(v * v for v in tau))
        if not math.isfinite(nt):  # inputs past 1e154: no tangent plane to cut by
            x = None
            break
        if nt <= me.ball * (1.0 + 1e-6):
            break
        # the ball's tangent plane at the nearest point: ûᵀτ ≤ ball
        cols.append([-tau[j] / nt * scale[j] for j in range(m)] + [0.0] * k)
        rhs.append(-me.ball)
    if x is None:  # numerically degenerate: the strongest push along the worst row, in the box
        worst = max(range(k), key=lambda i: bounds[i] - _dot(rows[i], z_ref))
        z = tuple(zr + 1e6 * c for zr, c in zip(z_ref, rows[worst]))
        slack = math.inf
    else:
        z = tuple(float(v) for v in x[:m])
        slack = max(0.0, max(float(v) for v in x[m:]))
    tau = tuple(min(max(zj * s, lo), hi) for zj, s, lo, hi in zip(z, scale, me.lo, me.hi))
    tau = _clip_ball(tau, me.ball)
    zt = tuple(v / s for v, s in zip(tau, scale))
    margins = [_dot(c, zt) - b for c, b in zip(rows, bounds)]
    if me.yaw is not None:  # a boat the filter acts on turns slowly: its turns make sway, which τ_u cannot stop
        lo_r, hi_r = me.yaw
        tau = tau[:1] + (min(max(tau[1], lo_r), hi_r),) + tau[2:]
    method = "relaxed" if slack > 1e-9 else "qp"
    active = tuple(i for i, mg in enumerate(margins) if mg <= 1e-7)
    satisfied = all(mg >= -1e-7 for mg in margins)
    intervened = tau != tau_ref
    return tau, FilterInfo(intervened, active, satisfied, method, slack if math.isfinite(slack) else 0.0, 0.0, min_h,
                           intervened and any(i >= n_tracks for i in active))


def _clip_ball(v: Vec, bound: float) -> Vec:
    if not math.isfinite(bound):
        return v
    n = math.sqrt(sum(x * x for x in v))
    return v if n <= bound else tuple(x * bound / n for x in v)

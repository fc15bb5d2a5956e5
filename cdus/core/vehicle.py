"""What is one vehicle? Its plant, its regulator, its DGVF guidance and its ω, stepped in time.

The same object runs inside a vehicle_agent process and inside the in-process fleet
runner; it does no I/O and reads no clock. One control period is:

1. ``control(t, consensus)``: at a control instant, integrate ω over the period just
   ended with the measured position held (guidance.integrate_omega); ω̇ is reported as
   the mean over that period (docs/control.md §2: the instantaneous value means nothing).
2. the caller samples metrics and publishes ω (after the controller's update);
3. ``guard(contacts)`` (with a safety filter): the velocity reference at the control
   instant through the CBF filter (cdus.core.safety); its correction u - u_ref is held
   over the period and added to the reference the regulator tracks;
4. ``advance()``: move the plant to the next control instant at the physics rate, its
   regulator tracking the guidance with ω extrapolated at the held ω̇ (and, with an
   observer, the estimated disturbance d̂ cancelled: cdus.core.observer); with a safety
   filter and contacts, the regulator's inputs go through the dynamic filter at every
   physics step (cdus.core.safety.dynamic_filter), the contacts extrapolated over the
   sample's age (docs/safety.md).

The plant and its regulator are objects the vehicle is built with (cdus.core.plants.Plant,
cdus.core.regulators.Regulator; cdus.core.models names them): the loop calls them, it
compares no names.

With a speed limit the guidance itself is scaled (guidance.integrate_omega's σ), so ω
does not run ahead of a vehicle that cannot keep up (docs/safety.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

from cdus.core import regulators as reg
from cdus.core.disturbance import Disturbance
from cdus.core.guidance import Consensus, desired_velocity, integrate_omega, omega_law
from cdus.core.observer import ESO, known_velocity
from cdus.core.safety import (
    Contact, FilterInfo, Point, SafetyParams, Track, dynamic_filter, safety_filter,
)
from cdus.core.paths import Path, Vec, nearest_omega
from cdus.core.plants import Plant
from cdus.core.regulators import Regulator


@dataclass(frozen=True)
class Telemetry:
    """A vehicle's state at a control instant, after the controller's update."""

    id: str
    t: float
    q: Vec
    heading: float
    speed: float
    omega: float
    omega_rate: float
    path_error: float


# For a plant other than ideal, the velocity reference is shaped by the velocity-level filter
# with its radius this much larger (a fraction of R), so that it turns the vehicle away
# before the dynamic filter has to hold it at R (docs/safety.md).
SHAPER_MARGIN = 0.5
# A contact's velocity is estimated from two samples at most this far apart (s); otherwise
# (first sighting, or back in range after a while) it is taken at rest for one sample.
MAX_VELOCITY_BASE = 0.5


@dataclass
class Vehicle:
    id: str
    kind: str
    dim: int
    path: Path
    k: Vec
    c: float
    plant: Plant
    regulator: Regulator | None  # None: a velocity-level plant (the ideal one) takes the reference as is
    control_period: float
    physics_steps: int
    state: Any
    omega: float
    limits: reg.Limits = reg.NO_LIMITS
    disturbance: Disturbance | None = None
    safety: SafetyParams | None = None  # the collision-avoidance filter, None: off
    observer: float | None = None  # the ESO's bandwidth (rad/s), None: no observer
    # [guidance] scale_omega (docs/config.md): σ = min(1, v_max/|a|) scales ω's
    # path-following part too. Off by default: right for vehicles that fly σa, but in the
    # mixed fleet of lake_circle_dynamic it let seed 4's boats run away.
    scale_omega: bool = False
    tick: int = 0
    t: float = 0.0
    omega_rate: float = 0.0
    started: bool = False
    interventions: int = 0  # control steps at which the safety filter changed the reference
    deflected: int = 0  # of those, the steps at which an obstacle's row bound ([[obstacle]], docs/safety.md)
    last_filter: FilterInfo | None = field(default=None, repr=False)
    _shift: Vec | None = field(default=None, repr=False)  # the filter's u - u_ref, held over the period
    # The dynamic filter's view of the neighbours (docs/safety.md): the sample in use and the
    # one before it (tick, {id: point}), and the tracks built from them at guard().
    _sample: tuple[int, dict] | None = field(default=None, repr=False)
    _prev_sample: tuple[int, dict] | None = field(default=None, repr=False)
    _tracks: tuple | None = field(default=None, repr=False)
    _guarded: bool = field(default=False, repr=False)  # the velocity layer intervened this period
    _dyn_intervened: bool = field(default=False, repr=False)  # the dynamic layer did
    _by_obstacle: bool = field(default=False, repr=False)  # an obstacle's row bound in either layer this period
    _way: int = field(default=0, repr=False)  # the way round a blocking obstacle (cdus.core.safety.safety_filter)
    _eso: ESO | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.observer is not None:
            self._eso = ESO.start(self.q, self.observer)

    @property
    def d_hat(self) -> Vec | None:
        """The observer's estimate of the velocity disturbance (None without an observer)."""
        return self._eso.d_hat if self._eso is not None else None

    def rejoin(self, tick: int, q: Vec | None = None, heading: float | None = None,
               omega_hint: float | None = None) -> None:
        """Resume at control tick ``tick`` (a restarted process), at rest at ``q``.

        ω becomes the nearest point of the path to ``q`` within half a period of
        ``omega_hint`` (the vehicle's last known ω), so the unwrapped ω carries on where it
        was instead of jumping by a lap, which the consensus would have to undo.
        """
        self.tick = tick
        self.t = tick * self.control_period
        self.started = False
        if q is not None:
            self.state = self.plant.at_rest(self.state, tuple(q)[: self.dim], heading)
        hint = self.omega if omega_hint is None else omega_hint
        half = self.path.period / 2.0 if self.path.period else 0.0
        self.omega = nearest_omega(self.path, self.q, hint - half)
        self._shift = None
        self._sample = self._prev_sample = self._tracks = None
        if self.observer is not None:
            self._eso = ESO.start(self.q, self.observer)

    # ------------------------------------------------------------------ observation
    @property
    def q(self) -> Vec:
        return self.state.q

    @property
    def velocity(self) -> Vec:
        return self.plant.velocity(self.state)

    @property
    def heading(self) -> float:
        return self.plant.heading(self.state)

    def path_error(self) -> float:
        """|Φ| = |q - f(ω)|."""
        f, _, _ = self.path.eval(self.omega)
        return math.sqrt(sum((a - b) ** 2 for a, b in zip(self.q, f)))

    def telemetry(self) -> Telemetry:
        v = self.velocity
        return Telemetry(self.id, self.t, self.q, self.heading, math.sqrt(sum(x * x for x in v)),
                         self.omega, self.omega_rate, self.path_error())

    # ------------------------------------------------------------------ stepping
    def control(self, consensus: Consensus) -> None:
        """The controller's update at the control instant ``self.t``.

        ``consensus`` carries the neighbour values over the period that just ended. On
        the very first call there is no such period: ω keeps its initial value and ω̇
        reports the instantaneous law.
        """
        q = self.q
        vmax = self.limits.speed if self.scale_omega else math.inf
        if not self.started:
            self.started = True
            coupling = consensus.W * self.omega - consensus.B0
            self.omega_rate = omega_law(self.path, q, self.omega, self.k, self.c, coupling, vmax)
            return
        w_new = integrate_omega(self.path, q, self.omega, self.k, self.c, consensus, self.control_period, vmax)
        self.omega_rate = (w_new - self.omega) / self.control_period
        self.omega = w_new

    def guard(self, contacts: tuple[Contact, ...], sample_tick: int | None = None) -> FilterInfo | None:
        """Run the safety filter on the velocity reference at this control instant (after
        :meth:`control`): its correction is what :meth:`advance` adds over the period.
        ``sample_tick``: the control tick the sensor sampled ``contacts`` at (None: now).
        Without a filter, nothing. Returns what the filter did.

        For a plant that is not velocity-level this also prepares the dynamic filter
        (cdus.core.safety.dynamic_filter) that :meth:`advance` runs at every physics step on
        the regulator's inputs: each contact's velocity is estimated from the two newest
        samples this vehicle used (docs/safety.md, "robust to the sensor")."""
        self._shift = None
        self._tracks = None
        if self.safety is None:
            return None
        if not contacts and not self.safety.obstacles:
            self.last_filter = None
            self._track(contacts, self.tick if sample_tick is None else sample_tick)
            self._tracks = None
            return None
        raw = desired_velocity(self.path, self.q, self.omega, self.k)
        a = reg.clip_norm(raw, self.limits.speed)
        self._track(contacts, self.tick if sample_tick is None else sample_tick)
        params = self.safety
        velocity_level = self.plant.velocity_level
        if not velocity_level:  # the reference keeps clear of R, the dynamic filter holds R
            params = replace(params, radius=params.radius * (1.0 + SHAPER_MARGIN),
                             obstacle_pad=params.radius * SHAPER_MARGIN)
            seen = contacts
        else:  # where the contacts are now, at their estimated velocities (docs/safety.md)
            ts, tracks = self._tracks
            age = self.t - ts
            seen = tuple(c if v is None or age <= 0.0 else
                         Contact(tuple(x + y * age for x, y in zip(c.q, v)), c.id, c.share)
                         for c, v, _ in tracks)
            self._tracks = None
        u, info = safety_filter(a, self.q, seen, params, self.id, self._way)
        self._way = info.way
        self.last_filter = info
        self._guarded = info.intervened
        self._by_obstacle = info.by_obstacle
        if info.intervened:
            # The ideal plant flies clip(a) + shift; the regulators add the shift to the
            # unclipped reference and clip after (a - d̂ + shift), so for them it is taken from
            # the unclipped one: both then fly u (a boat far off its path, |a| above the speed
            # limit, otherwise tracked a reference still pointing into the contact and froze).
            base = a if velocity_level else raw
            self._shift = tuple(x - y for x, y in zip(u, base))
            self.interventions += 1
        return info

    def _track(self, contacts: tuple[Contact, ...], s: int) -> None:
        """The contacts of sample ``s`` with velocities estimated from the sample before."""
        if self._sample is None or self._sample[0] != s:
            if self._sample is not None and self._sample[0] < s:
                self._prev_sample = self._sample
            self._sample = (s, {c.id: c.q for c in contacts if c.id is not None})
        T = self.control_period
        prev = self._prev_sample
        out = []
        for c in contacts:
            v = None
            dt = 0.0
            if prev is not None and c.id is not None and c.id in prev[1] and len(prev[1][c.id]) == len(c.q) \
                    and (s - prev[0]) * T <= MAX_VELOCITY_BASE:
                dt = (s - prev[0]) * T
                v = tuple((a - b) / dt for a, b in zip(c.q, prev[1][c.id]))
            out.append((c, v, dt))
        self._tracks = (s * T, tuple(out))

    def _filtered(self, tau: Vec, t: float, d: Vec) -> Vec:
        """The regulator's inputs ``tau`` at physics time ``t`` through the dynamic filter."""
        ts, tracks = self._tracks
        me = self._me(d)
        age = max(0.0, t - ts)
        a = me.accel
        dim = len(me.p)
        tr = []
        for c, v, dt in tracks:
            q = tuple(c.q)
            if len(q) != dim:
                continue
            if v is None:
                v = (0.0,) * dim
            tr.append(Track(tuple(x + y * age for x, y in zip(q, v)), v, c.share,
                            a * (0.5 * dt * age + 0.5 * age * age), a * (0.5 * dt + age), c.id))
        out, info = dynamic_filter(tau, me, tr, self.safety, self.id)
        if info.intervened:
            self._dyn_intervened = True
            self._by_obstacle = self._by_obstacle or info.by_obstacle
            self.last_filter = info
        return out

    def _me(self, d: Vec) -> Point:
        return self.plant.point(self.state, d, self.limits)

    def advance(self) -> None:
        """Move the plant over one control period at the physics rate."""
        T = self.control_period
        n = self.physics_steps
        h = T / n
        dist = self.disturbance
        zero = (0.0,) * self.dim
        shift = self._shift
        eso = self._eso
        plant = self.plant
        if self.regulator is None:  # a velocity-level plant flies the reference held over the period
            a = reg.clip_norm(desired_velocity(self.path, self.q, self.omega, self.k), self.limits.speed)
            if shift is not None:
                a = tuple(x + y for x, y in zip(a, shift))
            if dist is None and eso is None and plant.exact_when_held:
                self.state = plant.step(self.state, a, zero, T)
            else:
                for _ in range(n):
                    cmd = a if eso is None else tuple(x - y for x, y in zip(a, eso.d_hat))
                    before = self.state
                    self.state = plant.step(before, cmd, dist.step(h) if dist is not None else zero, h)
                    if eso is not None:
                        eso = eso.update(self.state.q, known_velocity(before, self.state, cmd), h)
        else:
            w0, wd = self.omega, self.omega_rate
            guarded = self._tracks is not None and self.safety is not None
            self._dyn_intervened = False
            regulator, path, k, limits = self.regulator, self.path, self.k, self.limits
            for j in range(n):
                w = w0 + wd * j * h
                d = dist.step(h) if dist is not None else zero
                st = self.state
                d_hat = eso.d_hat if eso is not None else None
                u = regulator.command(st, path, w, wd, k, limits, d_hat, shift, h)
                if guarded:
                    u = self._filtered(u, self.t + j * h, d)
                self.state = plant.step(st, u, d, h)
                if not plant.finite(self.state):
                    raise DivergedError(f"vehicle {self.id}: its state is no longer finite at t = "
                                        f"{self.t + j * h:.2f} s (the vehicle diverged): {st}")
                if eso is not None:
                    eso = eso.update(self.state.q, known_velocity(st, self.state), h)
            if self._dyn_intervened and not self._guarded:
                self.interventions += 1  # counted once per control step, whichever layer acted
        if self._by_obstacle:
            self.deflected += 1
        self._by_obstacle = False
        self._eso = eso
        self._shift = None
        self._tracks = None
        self._guarded = False
        self.tick += 1
        self.t = self.tick * T


class DivergedError(ArithmeticError):
    """A vehicle's simulated state became non-finite: the run cannot go on; the message says
    which vehicle, when and from what state."""


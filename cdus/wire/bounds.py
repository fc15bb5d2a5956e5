"""Which numbers may a field take? The finite-number predicate, and every numeric field's bound.

A value enters cdus three ways: a scenario file (cdus.scenario), a run-time command (a ground
station's arguments, the world's handlers, the agent's decode of what the world relays) and a
wire message (cdus.wire). All three take a number through :func:`finite` and a field's range
through :data:`BOUNDS`, so a value one door refuses no other door accepts: a link delay of
1e308 s was refused nowhere, answered "applied" by the world and crashed every agent
(``OverflowError`` in cdus.core.schedule), and a path radius of 1e300 in a config crashed the
vehicle that took it. docs/config.md ("Bounds of the numbers") is the user's copy of the table.

The bounds are generous for the physics (a delay up to an hour, paths and positions within
±1,000 km, rates up to 100 kHz) and tight enough that every number derived from them stays
finite: a tick count, t / T, a squared distance, f''(ω) = r β², a sum of phases. This is the
lowest layer (cdus.wire, layer 0): cdus.core and cdus.scenario import it.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass


#: the largest finite float; an int beyond it is no finite number to cdus
MAX_FLOAT = sys.float_info.max


def finite(x: object) -> bool:
    """A finite real number: an int or a float, never a bool (True is an int to Python), never
    nan or ±inf, never an int too large for a float. With :func:`is_number`, the one place "a
    number, not a bool" is written (bench/shape.py finds any other)."""
    if not isinstance(x, (int, float)) or isinstance(x, bool):
        return False
    # an int is finite unless too large for a float (10**400: math.isfinite would raise)
    return math.isfinite(x) if isinstance(x, float) else abs(x) <= MAX_FLOAT


def is_number(x: object) -> bool:
    """A real number, finite or not: :func:`finite`, or a float (nan, ±inf; a bool is no number,
    nor an int too large for a float)."""
    return finite(x) or isinstance(x, float)


@dataclass(frozen=True)
class Bound:
    """A closed or half-open interval of numbers, and whether +inf is a value of the field
    (``inf_ok``: "until the end", "not correlated")."""

    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False  # x > lo (else x >= lo)
    hi_open: bool = False  # x < hi (else x <= hi)
    inf_ok: bool = False

    def holds(self, x: object) -> bool:
        """Is ``x`` a number this field takes?"""
        if not finite(x):
            return self.inf_ok and x == math.inf and isinstance(x, float)
        above = x > self.lo if self.lo_open else x >= self.lo  # type: ignore[operator]
        below = x < self.hi if self.hi_open else x <= self.hi  # type: ignore[operator]
        return above and below

    def text(self) -> str:
        """The range in words for a message: ``> 0 and <= 3600``, ``>= -1e+06 and <= 1e+06``."""
        parts = []
        if self.lo > -math.inf:
            parts.append(f"{'>' if self.lo_open else '>='} {self.lo:g}")
        if self.hi < math.inf:
            parts.append(f"{'<' if self.hi_open else '<='} {self.hi:g}")
        return " and ".join(parts)

    def problem(self, x: object, what: str = "") -> str | None:
        """None if ``x`` holds, else ``must be a finite number <text><what>, got <x>``."""
        if self.holds(x):
            return None
        kind = "a finite number" if not self.inf_ok else "a number"
        got = (f"{x:g}" if isinstance(x, float) else "an integer beyond a float's range"
               if type(x) is int and not finite(x) else _cut(repr(x)))  # an int as written, a bool or a string as Python spells it
        return f"must be {kind} {self.text()}{what}, got {got}"


def _cut(text: str, most: int = 60) -> str:
    """A value's text in a refusal, cut at ``most`` characters."""
    return text if len(text) <= most else text[:most - 3] + "..."


def within(limit: float) -> Bound:
    """±limit, both ends included."""
    return Bound(-limit, limit)


def positive(hi: float, *, hi_open: bool = False) -> Bound:
    """(0, hi]."""
    return Bound(0.0, hi, lo_open=True, hi_open=hi_open)


def nonnegative(hi: float) -> Bound:
    """[0, hi]."""
    return Bound(0.0, hi)


#: m: a coordinate of a path or a start, a path's size (radius, a, b, amplitude, scale, height,
#: offset d): 1,000 km. A squared distance of two such points (1e13) is far from overflow; a
#: circle of radius 1e300 overflowed the vehicle that took it (cdus.core.paths.nearest_omega).
MAX_METRES = 1e6
#: 1/s: a path's β, a Lissajous frequency, a path speed (m/s): their products with a size
#: (f''(ω) = r β² ≤ 1e18) and with a phase (βω ≤ 1e15) stay finite.
MAX_RATE = 1e6
#: β and the frequencies are bounded away from 0 too: a β of 1e-308 made a period of 2π/β = inf
MIN_RATE = 1e-6
#: ω units: a vehicle's phase θ, a formation offset Δ, ω0 (a lap is 2π/β). ω is a time-like
#: number (it runs at 1/s): no formation needs offsets beyond ~30 years of it
MAX_PHASE = 1e9
#: s: the latest time an event, a link window, or a run-time link or radio change may name
MAX_AT = 1e9
#: s: a link delay (base, jitter): an hour. 1e308 s crashed every agent (delay / T overflowed)
MAX_DELAY = 3600.0
#: Hz: a rate of the scenario ([rates], the safety sensor): 100 kHz; 1e15 Hz made a run of a
#: second take forever (a tick loop of 1e15)
MAX_HZ = 1e5
MIN_HZ = 1e-3
#: m/s: a current or wind, a gust's std: far past any weather a vehicle flies in
MAX_WIND = 1e3
#: vehicle limits (speed m/s, accel m/s², τ_u, τ_r, yaw rate rad/s) and gains that have no rate bound
MAX_LIMIT = 1e6
#: usv_3dof ε1..ε7 (cybership2's are within ±1.4): 1e15 overflowed the plant within 0.2 s
MAX_EPSILON = 1e3

#: field -> its bound. The field is named as docs/config.md names it (``vehicle.path.radius``
#: for the radius of any vehicle's path, of an ``[[event]]``'s path, of a ground station's).
BOUNDS: dict[str, Bound] = {
    # [scenario], [rates], [metrics], [supervision]
    "scenario.duration": positive(1e7),  # ~116 days; 1e308 s overflowed the tick count
    "rates.physics": Bound(MIN_HZ, MAX_HZ),
    "rates.control": Bound(MIN_HZ, MAX_HZ),
    "rates.broadcast": Bound(MIN_HZ, MAX_HZ),  # 1e-308 Hz: control / broadcast overflowed
    "metrics.path_tol": positive(MAX_METRES),
    "metrics.coord_tol": positive(MAX_PHASE),
    "supervision.backoff_s": positive(3600.0),
    # [gains], a vehicle's gains and regulator gains: > 0 here, and below what the discrete
    # controller takes at the scenario's rates (cdus.core.gain_bounds: k < 2 x rate, ...), which
    # the rates' own bound keeps finite
    "gains.k": Bound(0.0, math.inf, lo_open=True),
    "gains.c": Bound(0.0, math.inf, lo_open=True),
    "vehicle.regulator_gains": Bound(0.0, math.inf, lo_open=True),
    # [graph]
    "graph.weight": positive(MAX_LIMIT),
    "graph.edge.delta": within(MAX_PHASE),
    # a vehicle
    "vehicle.phase": within(MAX_PHASE),
    "vehicle.omega0": within(MAX_PHASE),
    "vehicle.epsilon": within(MAX_EPSILON),
    "vehicle.start.position": within(MAX_METRES),
    "vehicle.start.region": within(MAX_METRES),
    "vehicle.start.heading": within(MAX_PHASE),
    "vehicle.limits": positive(MAX_LIMIT),
    "disturbance.constant": within(MAX_WIND),
    "disturbance.gust": nonnegative(MAX_WIND),
    "disturbance.gust_tau": positive(MAX_AT),
    "observer.bandwidth": positive(MAX_LIMIT),
    # a path (a vehicle's, an [[event]]'s, a ground station's)
    "path.center": within(MAX_METRES),
    "path.origin": within(MAX_METRES),
    "path.waypoints": within(MAX_METRES),
    "path.heading": within(MAX_METRES),
    "path.radius": positive(MAX_METRES),
    "path.a": positive(MAX_METRES),
    "path.b": positive(MAX_METRES),
    "path.scale": positive(MAX_METRES),
    "path.height": positive(MAX_METRES),
    "path.amplitude": within(MAX_METRES),
    "path.d": within(MAX_METRES),
    "path.rotation": within(MAX_PHASE),
    "path.phase": within(MAX_PHASE),
    "path.frequency": within(MAX_RATE),
    "path.beta": within(MAX_RATE),  # and |β| >= MIN_RATE, also when speed sets it
    "path.speed": positive(MAX_RATE),
    # [safety]
    "safety.radius": positive(MAX_METRES),
    "safety.gamma": positive(1000.0),  # faster than any control loop can act on
    "safety.range": positive(MAX_METRES),
    "safety.rate": Bound(MIN_HZ, MAX_HZ),
    "safety.latency": nonnegative(MAX_AT),
    "safety.sidestep": Bound(0.0, 1.0, hi_open=True),
    # [link], its overrides, and a ground station's link command
    "link.timeout": positive(MAX_AT),
    "link.delay.base": nonnegative(MAX_DELAY),
    "link.delay.jitter": nonnegative(MAX_DELAY),
    "link.window.from": nonnegative(MAX_AT),
    "link.window.to": Bound(0.0, MAX_AT, lo_open=True, inf_ok=True),
    "link.at": Bound(-math.inf, MAX_AT),  # a run-time change's time; < 0: as soon as possible
    # [[event]]
    "event.at": nonnegative(MAX_AT),
    "event.duration": positive(MAX_AT),
    # [radio] (docs/radio.md) and a ground station's radio command
    "radio.relay_delay": nonnegative(10.0),
    "radio.sample_period": positive(60.0),
    "radio.frequency": Bound(1.0e6, 1.0e11),
    "radio.exponent": Bound(1.0, 8.0),
    "radio.d0": Bound(0.01, 1000.0),
    "radio.pl0": nonnegative(250.0),
    "radio.permittivity": Bound(1.0, 200.0),
    "radio.conductivity": nonnegative(100.0),
    "radio.shadowing_sigma": nonnegative(30.0),
    "radio.shadowing_distance": Bound(0.01, math.inf, inf_ok=True),
    "radio.shadowing_time": Bound(0.001, math.inf, inf_ok=True),
    "radio.rician_k": nonnegative(100.0),
    "radio.nakagami_m": Bound(0.5, 100.0),
    "radio.tx_power": Bound(-50.0, 50.0),
    "radio.noise_floor": Bound(-250.0, 0.0),
    "radio.bandwidth": Bound(1.0e3, 1.0e10),
    "radio.noise_figure": nonnegative(50.0),
    "radio.capacity": Bound(1.0e3, 1.0e11),
    "radio.preamble": nonnegative(1.0),
    "radio.slot": positive(1.0),
    "radio.station": within(1.0e7),
    "radio.antenna": nonnegative(1000.0),
}


def bound(field: str) -> Bound:
    """The bound of ``field`` (a key of :data:`BOUNDS`); a KeyError names a field nobody bounded."""
    return BOUNDS[field]

"""Does a message get through the radio? A channel model from the geometry (docs/radio.md).

Its parts have rooms of their own: the path loss between two antennas
(:mod:`cdus.core.propagation`), the packet error rate at an SNR and the airtime
(:mod:`cdus.core.reception`), the fading and the shadowing (:mod:`cdus.core.fading`). This
module holds the ``[radio]`` spec, the geometry, and the channel that puts them together
per message, with the shared medium and the counters.

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
from typing import Iterable, Sequence

from cdus.core.fading import ShadowField, _LOG10_GRID, fading_gain, fading_grid, fading_mean
from cdus.core.link import stream_key, uniform
from cdus.core.propagation import C_LIGHT, free_space_db, path_loss_db, two_ray_loss_db, water_permittivity
from cdus.core.reception import airtime, per_curve, per_from_snr
from cdus.core.vocabulary import KINDS, RADIO_CAUSES
from cdus.wire.messages import OmegaMsg, encode_omega

# the names' old home: `from cdus.core.radio import ...` keeps working for what moved to a room of its own
from cdus.core.fading import FEATURES, gamma_draw, normal_pair  # noqa: F401
from cdus.core.propagation import EPSILON_0, MIN_HEIGHT, reflection_coefficient  # noqa: F401
from cdus.core.reception import ber, erfc_vec, q_function  # noqa: F401

THERMAL_DBM_HZ = -174.0  # kT at 290 K, dBm/Hz
STATION = "station"  # the base station's name in the random streams and the counters
PROPAGATIONS = ("log_distance", "two_ray")
TOPOLOGIES = ("adhoc", "station")
FADINGS = ("none", "rician", "nakagami")
MODULATIONS = ("bpsk", "qpsk", "16qam", "64qam")
POLARIZATIONS = ("vertical", "horizontal")
ACCESSES = ("csma", "aloha")
DEFAULT_RATE = 50.0  # Hz: the default [rates] broadcast
MAX_CACHED = 8192  # legs (link x epoch x geometry) kept before the cache is emptied


def __getattr__(name: str):  # FADING_GRID, as it was a module constant (cdus.core.fading's now)
    if name == "FADING_GRID":
        return fading_grid()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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

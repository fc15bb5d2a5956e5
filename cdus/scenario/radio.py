"""Is a ``[radio]`` table valid? Its validation, into a :class:`cdus.core.radio.RadioSpec`.

:func:`radio_section` checks the scenario's optional ``[radio]`` table (docs/config.md lists
the fields, docs/radio.md the model) against the vehicle ids and builds the frozen spec that
``Scenario.radio`` carries (None when the table is absent: nothing changes).
:func:`validate_radio` does the same for a table given on its own, and
:func:`validate_radio_update` checks a run-time change (transmit power, station position);
both raise :class:`ConfigError` with every problem.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

from cdus.core.radio import (
    ACCESSES, FADINGS, KINDS, MODULATIONS, POLARIZATIONS, PROPAGATIONS, TOPOLOGIES, RadioChannel, RadioSpec,
)
from cdus.scenario.checks import IdList, Problems, describe, show
from cdus.scenario.errors import ConfigError
from cdus.wire.bounds import BOUNDS

#: key -> the unit and what it is, of every number of [radio]; its bound is cdus.wire.bounds.BOUNDS["radio.<key>"]
NUMBERS: dict[str, str] = {
    "relay_delay": " s (the station's relay adds it to every message)",
    "sample_period": " s (the world samples the positions this often)",
    "frequency": " Hz (the carrier, e.g. 5.18e9)",
    "exponent": " (log-distance path-loss exponent n; 2 = free space)",
    "d0": " m (reference distance of the log-distance model, the near-field bound)",
    "pl0": " dB (loss at d0; leave it out for the free-space loss at d0)",
    "permittivity": " (relative permittivity of the water: 80 fresh, 70 at 5 GHz sea)",
    "conductivity": " S/m (of the water: 0.01 fresh, 4 sea)",
    "shadowing_sigma": " dB (std of the log-normal shadowing; 0 = none)",
    "shadowing_distance": " m (decorrelation distance; inf = not correlated in space)",
    "shadowing_time": " s (decorrelation time; inf = the shadowing does not change with time)",
    "rician_k": " (Rician K factor, linear: line-of-sight power / scattered power)",
    "nakagami_m": " (Nakagami m; 1 = Rayleigh)",
    "tx_power": " dBm (transmit power)",
    "noise_floor": " dBm (leave it out for kTB + noise_figure)",
    "bandwidth": " Hz (the noise bandwidth)",
    "noise_figure": " dB (of the receiver)",
    "capacity": " bit/s (the channel's bit rate: airtime and Eb/N0)",
    "preamble": " s (per-message overhead on the air: preamble, inter-frame space)",
    "slot": " s (the CSMA vulnerable window)",
}
INTEGERS = {"seed": (0, " (leave it out to use link.seed or scenario.seed)"),
            "header": (0, " bytes (added to the ω message's wire size: MAC, IP, UDP, Zenoh headers)"),
            "queue": (1, " messages (per transmitter, before it drops)")}
MAX_HEADER = 65_535
MAX_QUEUE = 1_000_000
CHOICES = {"topology": (TOPOLOGIES, "radio topology"), "propagation": (PROPAGATIONS, "propagation model"),
           "polarization": (POLARIZATIONS, "polarization"), "fading": (FADINGS, "fading"),
           "modulation": (MODULATIONS, "modulation"), "access": (ACCESSES, "medium access")}
ANTENNA_KEYS = KINDS + ("station",)
MAX_HEIGHT = BOUNDS["radio.antenna"].hi  # m
MAX_COORDINATE = BOUNDS["radio.station"].hi  # m
RADIO_KEYS = tuple(CHOICES) + tuple(NUMBERS) + tuple(INTEGERS) + ("station", "antenna", "antenna_override")
UPDATE_KEYS = ("tx_power", "station")

Ids = Sequence[str] | None


def validate_radio(radio: Any, ids: Ids, source: str) -> RadioSpec:
    """Check a raw ``[radio]`` table and build its :class:`RadioSpec` (``ids`` None: vehicle
    references are not checked). Raises ``ConfigError(source, [(field, message), ...])``."""
    p = Problems()
    spec = radio_section(p, radio, None if ids is None else IdList(str(i) for i in ids))
    if p:
        raise ConfigError(source, p.items)
    assert spec is not None
    return spec


def validate_radio_update(change: Any, source: str) -> tuple[float | None, tuple[float, float, float] | None]:
    """A run-time change ``{tx_power = dBm, station = [x, y(, z)]}`` (either or both), checked:
    (tx_power, station), None for what it leaves alone."""
    p = Problems()
    t = p.table(change, "radio", "{ tx_power = 10.0, station = [0.0, -50.0, 0.0] }")
    tx = st = None
    if t is not None:
        mark = len(p)
        p.unknown_keys(t, UPDATE_KEYS, "radio")
        if not any(k in t for k in UPDATE_KEYS) and not p.since(mark):  # a misspelt key says so, once
            p.add("radio", "changes nothing; give tx_power (dBm) and/or station ([x, y] or [x, y, z] in m)")
        if "tx_power" in t:
            tx = _number(p, t["tx_power"], "tx_power")
        if "station" in t:
            st = _station(p, t["station"], "radio.station")
    if p:
        raise ConfigError(source, p.items)
    return tx, st


def radio_section(p: Problems, radio: Any, ids: Ids) -> RadioSpec | None:
    """The [radio] table as a :class:`RadioSpec`, or None after recording its problems."""
    t = p.table(radio, "radio", "a [radio] section with keys " + ", ".join(RADIO_KEYS))
    if t is None:
        return None
    mark = len(p)
    p.unknown_keys(t, RADIO_KEYS, "radio")
    out: dict[str, Any] = {}
    for key, (options, what) in CHOICES.items():
        if key in t:
            out[key] = p.choice(t[key], f"radio.{key}", options, what)
    for key in NUMBERS:
        if key in t:
            out[key] = _number(p, t[key], key)
    for key, (low, unit) in INTEGERS.items():
        if key in t:
            v = p.integer(t[key], f"radio.{key}", ge=low, unit=unit)
            top = MAX_HEADER if key == "header" else MAX_QUEUE if key == "queue" else None
            if v is not None and top is not None and v > top:
                p.add(f"radio.{key}", f"must be an integer >= {low} and <= {top}{unit}, got {v}")
                v = None
            out[key] = v
    if "station" in t:
        out["station"] = _station(p, t["station"], "radio.station")
    elif t.get("topology") == "station":
        p.missing("radio.station", 'topology "station" relays every message through a base station; give its '
                                   'position, station = [x, y] or [x, y, z] (m, z: the mast base above the water)')
    if "antenna" in t:
        out["antenna"] = _antenna(p, t["antenna"])
    if "antenna_override" in t:
        out["antenna_override"] = _overrides(p, t["antenna_override"], ids)
    if p.since(mark):
        return None
    return RadioSpec(**out)


def _number(p: Problems, v: Any, key: str) -> float | None:
    return p.number(v, f"radio.{key}", f"radio.{key}", unit=NUMBERS[key])


def _station(p: Problems, v: Any, field: str) -> tuple[float, float, float] | None:
    ok = isinstance(v, list) and len(v) in (2, 3) and all(BOUNDS["radio.station"].holds(x) for x in v)
    if not ok or (len(v) == 3 and v[2] < 0):
        p.add(field, f"must be the station's position [x, y] or [x, y, z] in m (finite, within ±{MAX_COORDINATE:g}; "
                     f"z >= 0: the base of its mast above the water, default 0), got {describe(v)}")
        return None
    return (float(v[0]), float(v[1]), float(v[2]) if len(v) == 3 else 0.0)


def _antenna(p: Problems, v: Any) -> tuple[float, float, float] | None:
    t = p.table(v, "radio.antenna", "{ usv = 1.0, uav = 0.1, station = 10.0 } (m above the vehicle's position)")
    if t is None:
        return None
    p.unknown_keys(t, ANTENNA_KEYS, "radio.antenna")
    default = RadioSpec().antenna
    out = list(default)
    for j, key in enumerate(ANTENNA_KEYS):
        if key in t:
            h = p.number(t[key], f"radio.antenna.{key}", "radio.antenna",
                         unit=" m (antenna height above the vehicle's position; a boat's is above the water)")
            out[j] = default[j] if h is None else h
    return (out[0], out[1], out[2])


def _overrides(p: Problems, v: Any, ids: Ids) -> tuple[tuple[str, float], ...]:
    if not isinstance(v, dict):
        p.add("radio.antenna_override", f"must be a table vehicle id -> antenna height (m), like "
                                        f"{{ usv1 = 2.5 }}, got {describe(v)}")
        return ()
    out = []
    for vid, h in v.items():
        where = f"radio.antenna_override.{vid}"
        got = p.vehicle(vid, where, ids)
        height = p.number(h, where, "radio.antenna", unit=f" m (the antenna height of {show(vid)})")
        if got is not None and height is not None:
            out.append((got, height))
    return tuple(sorted(out))


def channel_for(scenario: Any) -> RadioChannel | None:
    """The scenario's radio channel (None without [radio]): its vehicles and kinds, the radio
    seed, the broadcast rate, Geometry.tick counted in control ticks (tick_period = 1 / control)."""
    if scenario.radio is None:
        return None
    return RadioChannel(scenario.radio, scenario.ids, [v.kind for v in scenario.vehicles], scenario.radio_seed,
                        rate=scenario.rates.broadcast, tick_period=1.0 / scenario.rates.control)


def radio_table(raw: Mapping[str, Any]) -> dict | None:
    """The ``[radio]`` table as written, None if absent."""
    t = raw.get("radio")
    return dict(t) if isinstance(t, dict) else None

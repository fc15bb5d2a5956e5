"""The [radio] section: a raw table checked into a RadioSpec (docs/config.md, docs/radio.md)."""

from __future__ import annotations

import math
import pathlib
import re
import tomllib

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cdus.core.radio import Geometry, RadioChannel, RadioSpec
from cdus.scenario.config import ConfigError, parse_scenario
from cdus.wire.bounds import BOUNDS
from cdus.scenario.radio import (
    CHOICES, INTEGERS, NUMBERS, RADIO_KEYS, channel_for, validate_radio, validate_radio_update,
)
from tests.scenario.common import base, problems

IDS = ("usv1", "usv2", "uav1")
KINDS = ("usv", "usv", "uav")


def spec(table):
    return validate_radio(table, IDS, "test.toml")


def test_absent_radio_is_none_and_changes_nothing():
    s = parse_scenario(base())
    assert s.radio is None and channel_for(s) is None
    assert s.radio_seed == s.link_seed


def test_an_empty_table_is_the_defaults_and_the_full_example_is_valid():
    assert spec({}) == RadioSpec()
    text = """
    topology = "station"
    station = [0.0, -60.0, 2.0]
    relay_delay = 0.002
    sample_period = 0.1
    seed = 3
    propagation = "log_distance"
    frequency = 2.4e9
    exponent = 2.7
    d0 = 1.0
    pl0 = 40.0
    permittivity = 70.0
    conductivity = 4.0
    polarization = "horizontal"
    antenna = { usv = 1.5, uav = 0.2, station = 12.0 }
    antenna_override = { usv2 = 3.0 }
    shadowing_sigma = 6.0
    shadowing_distance = 30.0
    shadowing_time = 5.0
    fading = "nakagami"
    rician_k = 6.0
    nakagami_m = 2.0
    tx_power = 15.0
    noise_floor = -95.0
    bandwidth = 2.0e7
    noise_figure = 7.0
    modulation = "qpsk"
    header = 80
    capacity = 1.2e7
    preamble = 4.0e-5
    access = "aloha"
    slot = 2.0e-5
    queue = 16
    """
    s = spec(tomllib.loads(text))
    assert s.topology == "station" and s.station == (0.0, -60.0, 2.0) and s.antenna == (1.5, 0.2, 12.0)
    assert s.antenna_override == (("usv2", 3.0),) and s.seed == 3 and s.queue == 16 and s.header == 80
    assert s.noise_dbm == -95.0 and s.loss_d0 == 40.0 and s.fading == "nakagami" and s.access == "aloha"
    assert set(tomllib.loads(text)) == set(RADIO_KEYS)  # the example sets every key


def test_in_a_scenario_with_seed_and_channel():
    data = base()
    data["radio"] = {"topology": "station", "station": [0, -50]}
    data["link"] = {"seed": 11}
    s = parse_scenario(data)
    assert s.radio == RadioSpec(topology="station", station=(0.0, -50.0, 0.0))
    assert s.radio_seed == 11
    data["radio"]["seed"] = 4
    assert parse_scenario(data).radio_seed == 4
    ch = channel_for(parse_scenario(data))
    assert ch.kinds == ("usv", "usv", "uav") and ch.rate == 50.0 and ch.tick_period == pytest.approx(0.02)
    geo = Geometry.of(0, [(0.0, 0.0), (10.0, 0.0), (0.0, 10.0, 20.0)])
    assert 0.9 < ch.delivery_probability(0, 2, geo) <= 1.0


BAD = [
    ({"topolgy": "adhoc"}, "radio.topolgy", 'unknown key; did you mean "topology"?'),
    ({"topology": "mesh"}, "radio.topology", "choose one of adhoc, station"),
    ({"topology": "station"}, "radio.station", "missing; topology \"station\" relays every message"),
    ({"station": [1.0]}, "radio.station", "must be the station's position [x, y] or [x, y, z]"),
    ({"station": [0.0, float("nan")]}, "radio.station", "must be the station's position"),
    ({"station": [0.0, 1e9]}, "radio.station", "within ±1e+07"),
    ({"propagation": "okumura"}, "radio.propagation", "choose one of log_distance, two_ray"),
    ({"frequency": 0}, "radio.frequency", "must be a number >= 1e+06 and <= 1e+11 Hz"),
    ({"exponent": 0.5}, "radio.exponent", "must be a number >= 1 and <= 8"),
    ({"d0": 0}, "radio.d0", "must be a number >= 0.01 and <= 1000 m"),
    ({"pl0": -3}, "radio.pl0", "must be a number >= 0 and <= 250 dB"),
    ({"permittivity": 0.5}, "radio.permittivity", "must be a number >= 1"),
    ({"conductivity": -1}, "radio.conductivity", "must be a number >= 0"),
    ({"polarization": "circular"}, "radio.polarization", "choose one of vertical, horizontal"),
    ({"antenna": 1.0}, "radio.antenna", "must be a table, e.g. { usv = 1.0"),
    ({"antenna": {"boat": 1.0}}, "radio.antenna.boat", "valid keys here: usv, uav, station"),
    ({"antenna": {"usv": -1.0}}, "radio.antenna.usv", "must be a number >= 0 and <= 1000 m"),
    ({"antenna_override": {"usv9": 1.0}}, "radio.antenna_override.usv9", '"usv9" is not a vehicle'),
    ({"antenna_override": {"usv1": "high"}}, "radio.antenna_override.usv1", 'got the string "high"'),
    ({"antenna_override": [1]}, "radio.antenna_override", "must be a table vehicle id -> antenna height"),
    ({"shadowing_sigma": 31}, "radio.shadowing_sigma", "must be a number >= 0 and <= 30 dB"),
    ({"shadowing_distance": 0}, "radio.shadowing_distance", "must be a number >= 0.01 m"),
    ({"shadowing_time": -1}, "radio.shadowing_time", "must be a number >= 0.001 s"),
    ({"fading": "rayleigh"}, "radio.fading", "choose one of none, rician, nakagami"),
    ({"rician_k": 1000}, "radio.rician_k", "must be a number >= 0 and <= 100"),
    ({"nakagami_m": 0.2}, "radio.nakagami_m", "must be a number >= 0.5"),
    ({"tx_power": 100}, "radio.tx_power", "must be a number >= -50 and <= 50 dBm"),
    ({"tx_power": "max"}, "radio.tx_power", 'got the string "max"'),
    ({"noise_floor": 10}, "radio.noise_floor", "must be a number >= -250 and <= 0 dBm"),
    ({"bandwidth": 10}, "radio.bandwidth", "must be a number >= 1000"),
    ({"noise_figure": -1}, "radio.noise_figure", "must be a number >= 0"),
    ({"modulation": "8psk"}, "radio.modulation", "choose one of bpsk, qpsk, 16qam, 64qam"),
    ({"header": -1}, "radio.header", "must be an integer >= 0"),
    ({"header": 1e9}, "radio.header", "must be an integer >= 0"),
    ({"header": 100000}, "radio.header", "must be an integer >= 0 and <= 65535"),
    ({"capacity": 0}, "radio.capacity", "must be a number >= 1000"),
    ({"preamble": 2}, "radio.preamble", "must be a number >= 0 and <= 1 s"),
    ({"access": "tdma"}, "radio.access", "choose one of csma, aloha"),
    ({"slot": 0}, "radio.slot", "must be a number > 0 and <= 1 s"),
    ({"queue": 0}, "radio.queue", "must be an integer >= 1 messages"),
    ({"seed": -2}, "radio.seed", "must be an integer >= 0"),
    ({"sample_period": 0}, "radio.sample_period", "must be a number > 0 and <= 60 s"),
    ({"relay_delay": float("inf")}, "radio.relay_delay", "must be a finite number >= 0"),
]


@pytest.mark.parametrize("table,field,message", BAD)
def test_a_bad_field_is_named_with_the_fix(table, field, message):
    with pytest.raises(ConfigError) as info:
        spec(table)
    assert any(f == field and message in m for f, m in info.value.problems), info.value.problems


def test_every_field_has_a_bad_case():
    named = {f.split(".")[1] for _, f, _ in BAD}
    assert named >= set(RADIO_KEYS)


def test_in_a_scenario_problems_name_the_file_and_the_table_must_be_a_table():
    data = base()
    data["radio"] = {"tx_power": 99, "fading": "x"}
    text = problems(data)
    assert "x.toml: radio.tx_power: must be a number" in text and "x.toml: radio.fading: unknown fading" in text
    data["radio"] = 3
    assert "x.toml: radio: must be a table" in problems(data)
    text = problems(base(), {"radio.shadowing_sigma": -1})  # --set reaches it
    assert "radio.shadowing_sigma: must be a number >= 0" in text


def test_infinite_correlation_scales_are_allowed():
    s = spec({"shadowing_distance": float("inf"), "shadowing_time": float("inf")})
    assert math.isinf(s.shadowing_distance) and math.isinf(s.shadowing_time)


def test_run_time_update_checks():
    assert validate_radio_update({"tx_power": 5}, "gs") == (5.0, None)
    assert validate_radio_update({"station": [1, 2]}, "gs") == (None, (1.0, 2.0, 0.0))
    for bad, field in [({}, "radio"), ({"tx_power": 99}, "radio.tx_power"), ({"power": 1}, "radio.power"),
                       ({"station": "here"}, "radio.station"), (7, "radio")]:
        with pytest.raises(ConfigError) as info:
            validate_radio_update(bad, "gs")
        assert info.value.problems[0][0] == field
    with pytest.raises(ConfigError) as info:  # a misspelt key: that problem only, not also "changes nothing"
        validate_radio_update({"txpower": 3}, "gs")
    assert [f for f, _ in info.value.problems] == ["radio.txpower"]
    assert 'did you mean "tx_power"' in info.value.problems[0][1]


# --------------------------------------------------------------------------- Hypothesis: ConfigError or a spec

VALUES = st.one_of(
    st.none(), st.booleans(), st.integers(-10**12, 10**12), st.text(max_size=8),
    st.floats(allow_nan=True, allow_infinity=True), st.lists(st.floats(-1e8, 1e8), max_size=4),
    st.dictionaries(st.sampled_from(["usv", "uav", "station", "usv1", "uav1", "boat"]),
                    st.one_of(st.floats(-10, 2000), st.text(max_size=3)), max_size=3),
)


def plausible(key):
    """A value of the right kind for ``key`` most of the time, anything otherwise."""
    if key in CHOICES:
        return st.one_of(st.sampled_from(CHOICES[key][0]), VALUES)
    if key in NUMBERS:
        b = BOUNDS[f"radio.{key}"]
        return st.one_of(st.floats(b.lo, min(b.hi, 1e6)), VALUES)
    if key in INTEGERS:
        return st.one_of(st.integers(0, 100), VALUES)
    if key == "station":
        return st.one_of(st.lists(st.floats(-1e4, 1e4), min_size=2, max_size=3), VALUES)
    return VALUES


TABLES = st.dictionaries(st.sampled_from(RADIO_KEYS + ("bogus",)), st.none(), max_size=10).flatmap(
    lambda d: st.fixed_dictionaries({k: plausible(k) for k in d}))


COORD = st.one_of(st.floats(-3000, 3000), st.floats(-1e7, 1e7), st.sampled_from([0.0, 1e-300, -1e7, 1e7]))


@given(TABLES, st.lists(st.one_of(st.none(), st.tuples(COORD, COORD, st.one_of(st.floats(0, 200), COORD))),
                        min_size=3, max_size=3))
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
def test_any_table_gives_a_config_error_or_a_working_spec(table, positions):
    table = {k: v for k, v in table.items() if v is not None}
    try:
        s = spec(table)
    except ConfigError as e:
        assert e.problems and all(f.startswith("radio") for f, _ in e.problems)
        return
    assert isinstance(s, RadioSpec)
    ch = RadioChannel(s, IDS, KINDS, 1, rate=50.0, tick_period=0.02)
    geo = Geometry.of(7, positions)
    for src, dst in ((0, 1), (2, 0)):
        p = ch.delivery_probability(src, dst, geo)
        assert 0.0 <= p <= 1.0  # never nan
        d = ch.decide(src, dst, 3, 0.1, geo)
        assert d.p == p and (d.delivered or d.cause in ("range", "fading", "collision", "queue"))
        assert d.delay >= 0.0 and math.isfinite(d.delay)
    assert ch.utilisation(geo) >= 0.0


def test_the_documented_examples_and_keys():
    docs = pathlib.Path(__file__).resolve().parents[2] / "docs"
    for name in ("radio.md", "config.md"):
        text = (docs / name).read_text()
        blocks = [b for b in re.findall(r"```toml\n(.*?)```", text, re.S) if b.lstrip().startswith("[radio]")]
        assert blocks, name
        for b in blocks:
            data = base()
            data["radio"] = tomllib.loads(re.sub(r"#.*", "", b))["radio"]
            assert parse_scenario(data).radio.topology == "station"
    table = (docs / "config.md").read_text().split("### `[radio]`")[1].split("###")[0]
    assert {k for k in re.findall(r"^\| `(\w+)` \|", table, re.M)} == set(RADIO_KEYS)


def test_infinite_scales_survive_the_json_a_fleet_of_processes_is_given(tmp_path):
    """`cdus launch` hands the resolved scenario (Scenario.raw) to the world and the agents as
    JSON: with radio.shadowing_distance = inf (valid) it raised 'Out of range float values are not
    JSON compliant' (a traceback, nothing started). Written as the launcher writes it, it loads back
    the same scenario."""
    from cdus.files import write_json
    from cdus.scenario.config import load_scenario

    s = load_scenario("configs/range_out.toml", {"radio.shadowing_distance": math.inf,
                                                  "radio.shadowing_time": math.inf})
    path = tmp_path / "scenario.json"
    write_json(path, s.raw, allow_inf=True)
    back = load_scenario(str(path))
    assert back.radio == s.radio and math.isinf(back.radio.shadowing_distance)


@pytest.mark.parametrize("event", [{"action": "radio", "tx_power": 5.0}, {"action": "kill", "vehicle": "usv1"},
                                   {"action": "formation", "phases": {"usv1": 1.0}},
                                   {"action": "pause", "vehicle": "usv1", "at": 1.0, "duration": 1e308}])
def test_an_event_time_too_large_to_be_a_tick_is_a_config_error(event):
    """at = 1e308 is a finite number >= 0, so it passed, and every runner crashed building its
    schedule (OverflowError: 1e308 × the control rate is inf, no tick): `cdus sim` printed a
    traceback. Events are at most 1e9 s (the latest time a run-time change takes)."""
    data = base()
    data["radio"] = {}
    data["event"] = [{"at": 1e308, **event}]
    text = problems(data)
    field = "duration" if "duration" in event else "at"
    assert f"event[0].{field}: must be a number " in text and "<= 1e+09" in text, text
    data["event"] = [{"at": 1e9, **event, **({"duration": 1e9} if "duration" in event else {})}]
    s = parse_scenario(data)  # past the end: never applies, harmless
    from cdus.sim.fleet import InProcessFleet
    InProcessFleet(s).run(0.1)


@pytest.mark.parametrize("where", ["table", "update", "event"])
def test_a_station_below_the_water_is_refused_with_the_fix(where):
    """station = [x, y, -50]: the base of the mast 50 m under the water, its antenna (10 m up) 40 m
    under it; two-ray took the antenna 1 cm above the water without a word. Refused in the table,
    a run-time change and a scheduled one, naming the field."""
    st = [0.0, -60.0, -50.0]
    if where == "table":
        with pytest.raises(ConfigError) as info:
            spec({"topology": "station", "station": st})
        problems_ = info.value.problems
    elif where == "update":
        with pytest.raises(ConfigError) as info:
            validate_radio_update({"station": st}, "gs")
        problems_ = info.value.problems
    else:
        data = base()
        data["radio"] = {"topology": "station", "station": [0.0, 0.0]}
        data["event"] = [{"at": 1.0, "action": "radio", "station": st}]
        text = problems(data)
        assert "event[0].station: " in text and "z >= 0" in text, text
        return
    assert problems_[0][0] == "radio.station" and "z >= 0" in problems_[0][1] and "-50" in problems_[0][1]
    assert spec({"topology": "station", "station": [0.0, -60.0, 0.0]}).station == (0.0, -60.0, 0.0)

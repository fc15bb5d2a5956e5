"""Every numeric field of the scenario schema at its extremes: a refusal naming the field, or a
run that finishes (issue 27: a link delay of 1e308 s, a path radius of 1e300 or a start box of
1e308 m crashed the run; the rates of 1e15 Hz never ended it).

FULL sets every key the schema knows (checked against the schema's own key lists below, so a
key added to the schema and not here fails :func:`test_the_walk_covers_every_key_of_the_schema`);
the walk puts each extreme into each of its numbers, one at a time, parses the scenario and, if
it is accepted, runs it in process for its 1 s (at 10 Hz), events and faults included."""

from __future__ import annotations

import copy
import math

import pytest

from cdus.core.paths import REGISTRY
from cdus.scenario import events, graph, link, radio, safety, sections, vehicles
from cdus.scenario.config import ConfigError, parse_scenario
from cdus.scenario.model import DEFAULT_SAFETY
from cdus.scenario.paths import COMMON
from cdus.sim.fleet import InProcessFleet

FULL = {
    "scenario": {"name": "full", "description": "every numeric key", "duration": 1.0, "seed": 1},
    "rates": {"physics": 20.0, "control": 10.0, "broadcast": 10.0},
    "metrics": {"path_tol": 0.1, "coord_tol": 0.05},
    "gains": {"k": 1.5, "c": 2.0},
    "guidance": {"scale_omega": False},
    "supervision": {"restart": "never", "max_restarts": 2, "backoff_s": 0.5},
    "safety": {"enabled": True, "radius": 2.0, "gamma": 1.0, "range": 20.0, "rate": 10.0, "latency": 0.1,
               "cross_domain": True, "sidestep": 0.3},
    "disturbance": {"current": {"constant": [0.1, 0.0], "gust": 0.05, "gust_tau": 2.0},
                    "wind": {"constant": [0.5, 0.1, 0.0], "gust": 0.1, "gust_tau": 2.0}},
    "observer": {"enabled": True, "bandwidth": 2.0},
    "graph": {"topology": "chain", "weight": 1.0, "edge": [{"i": "usv2", "k": "usv1", "weight": 1.0, "delta": 1.0}]},
    "link": {"policy": "timeout", "timeout": 0.5, "seed": 3,
             "delay": {"base": 0.05, "jitter": 0.01, "distribution": "normal", "reorder": True},
             "loss": 0.1, "burst": {"p": 0.05, "r": 0.5, "bad_loss": 1.0, "good_loss": 0.0}, "duplicate": 0.05,
             "override": [{"src": "usv1", "dst": "*", "delay": {"base": 0.02, "jitter": 0.01}, "loss": 0.1,
                           "burst": {"p": 0.1, "r": 0.5}, "duplicate": 0.1}],
             "down": [{"src": "usv1", "dst": "uav1", "from": 0.2, "to": 0.4}],
             "partition": [{"from": 0.5, "to": 0.7, "groups": [["usv1"], ["usv2", "uav1"]]}]},
    "radio": {"topology": "station", "station": [0.0, -50.0, 0.0], "relay_delay": 0.001, "sample_period": 0.2,
              "seed": 2, "propagation": "log_distance", "frequency": 5.18e9, "exponent": 2.0, "d0": 1.0,
              "pl0": 47.0, "permittivity": 80.0, "conductivity": 0.01, "antenna": {"usv": 1.0, "uav": 0.1,
              "station": 10.0}, "antenna_override": {"usv1": 2.0}, "shadowing_sigma": 4.0,
              "shadowing_distance": 50.0, "shadowing_time": 10.0, "fading": "rician", "polarization": "vertical", "modulation": "qpsk", "access": "csma", "rician_k": 10.0,
              "nakagami_m": 1.0, "tx_power": 20.0, "noise_floor": -90.0, "bandwidth": 2.0e7, "noise_figure": 10.0,
              "header": 64, "capacity": 6.0e6, "preamble": 5.0e-5, "slot": 9.0e-6, "queue": 8},
    "vehicle": [
        {"id": "usv1", "kind": "usv", "plant": "usv_3dof", "epsilon": [-0.465, 1.310, 0.0388, -0.181, 0.362, -0.503, -0.763],
         "regulator": "heading", "regulator_gains": {"b_u": 1.0, "b_r": 2.0, "k_psi": 1.0}, "phase": 0.0,
         "path": {"family": "circle", "center": [0.0, 0.0], "radius": 10.0, "speed": 1.0, "direction": -1},
         "start": {"position": [5.0, 0.0], "heading": 0.5}, "omega0": 0.0, "gains": {"k": [1.5, 1.5], "c": 2.0},
         "limits": {"speed": 2.0, "tau_u": 30.0, "tau_r": 3.0, "yaw_rate": 0.5},
         "disturbance": {"constant": [0.1, 0.0], "gust": 0.05, "gust_tau": 2.0}},
        {"id": "usv2", "kind": "usv", "plant": "usv_3dof", "regulator": "paper",
         "regulator_gains": {"b1": 1.0, "b2": 1.0, "b3": 1.0}, "phase": 1.0,
         "path": {"family": "ellipse", "center": [0.0, 0.0], "a": 10.0, "b": 6.0, "rotation": 0.2, "beta": 0.2},
         "start": {"region_min": [-5.0, -5.0], "region_max": [5.0, 5.0]}},
        {"id": "uav1", "kind": "uav", "plant": "uav_double_integrator", "regulator_gains": {"b": 1.0},
         "phase": 2.0, "path": {"family": "lissajous", "center": [0.0, 0.0, 20.0], "amplitude": [10.0, 5.0, 1.0],
                                "frequency": [1.0, 2.0, 1.0], "phase": [0.0, 1.5708, 0.0], "beta": 0.2},
         "start": {"region_min": [-5.0, -5.0, 10.0], "region_max": [5.0, 5.0, 30.0]},
         "limits": {"speed": 5.0, "accel": 3.0}},
        {"id": "uav2", "kind": "uav", "phase": 3.0, "path": {"family": "trefoil", "center": [0.0, 0.0, 20.0],
                                                             "scale": 3.0, "height": 1.0, "beta": 0.2}},
        {"id": "uav3", "kind": "uav", "phase": 4.0, "path": {"family": "self_intersecting", "d": 7.0,
                                                             "center": [0.0, 0.0, 15.0], "beta": 0.2}},
        {"id": "usv3", "kind": "usv", "phase": 5.0, "path": {"family": "line", "origin": [0.0, 0.0],
                                                             "heading": [1.0, 0.5], "speed": 1.0}},
        {"id": "usv4", "kind": "usv", "phase": 6.0, "path": {"family": "spline", "closed": False,
                                                             "waypoints": [[0.0, 0.0], [10.0, 0.0], [20.0, 5.0]],
                                                             "speed": 1.0}},
        {"id": "usv5", "kind": "usv", "plant": "ros2", "ros2": {"timeout": 0.5}, "phase": 7.0,
         "path": {"family": "circle", "center": [0.0, 0.0], "radius": 10.0}},
    ],
    "event": [
        {"at": 0.3, "action": "pause", "vehicle": "usv3", "duration": 0.2},
        {"at": 0.4, "action": "kill", "vehicle": "uav3"},
        {"at": 0.6, "action": "restart", "vehicle": "uav3"},
        {"at": 0.5, "action": "formation", "phases": {"usv2": 1.5}},
        {"at": 0.55, "action": "formation", "offsets": [{"i": "usv2", "k": "usv1", "delta": 1.2}]},
        {"at": 0.6, "action": "path", "vehicle": "uav2",
         "path": {"family": "circle", "center": [0.0, 0.0, 20.0], "radius": 5.0, "speed": 1.0}},
        {"at": 0.7, "action": "radio", "tx_power": 10.0, "station": [0.0, -40.0, 0.0]},
    ],
}


#: huge, tiny, ±inf, nan, negative zero, negative
EXTREMES = (1e308, -1e308, 1e-308, math.inf, -math.inf, math.nan, -0.0, -1.0)


def schema_keys() -> set[str]:
    """Every key name the scenario's checks know, from their own lists."""
    keys = set(sections.SCENARIO_KEYS) | set(sections.DEFAULT_RATES) | set(sections.DEFAULT_METRICS) \
        | set(sections.DEFAULT_GAINS) | set(sections.SUPERVISION_KEYS) | set(sections.GUIDANCE_KEYS)
    keys |= set(DEFAULT_SAFETY) | set(safety.DISTURBANCE_KINDS) | set(safety.DISTURBANCE_FIELDS) \
        | set(safety.OBSERVER_KEYS)
    keys |= set(graph.GRAPH_KEYS) - {"hub", "edges", "directed"} | set(graph.EDGE_KEYS)
    keys |= set(link.LINK_KEYS) | set(link.DELAY_KEYS) | set(link.BURST_KEYS) | set(link.OVERRIDE_KEYS) \
        | set(link.DOWN_KEYS) | set(link.PARTITION_KEYS) - {"drops"}
    keys |= set(radio.RADIO_KEYS) | set(radio.ANTENNA_KEYS)
    keys |= set(vehicles.VEHICLE_KEYS) - {"preset"} | set(vehicles.START_KEYS) | set(vehicles.LIMIT_KEYS) \
        | set(vehicles.DISTURBANCE_KEYS)
    keys |= {g for regs in vehicles.REGULATORS.values() for gains in regs.values() for g in gains}
    keys |= {k for family in REGISTRY.values() for k in family.keys} | set(COMMON)
    keys |= set(events.EVENT_KEYS) | set(events.OFFSET_KEYS) | set(events.RADIO_EVENT_KEYS)
    return keys


def keys_of(x) -> set[str]:
    if isinstance(x, dict):
        return set(x) | {k for v in x.values() for k in keys_of(v)}
    if isinstance(x, list):
        return {k for v in x for k in keys_of(v)}
    return set()


def numbers(x, path=()):
    """The paths of every number in ``x`` (dict keys and list indices)."""
    if isinstance(x, dict):
        for k, v in x.items():
            yield from numbers(v, path + (k,))
    elif isinstance(x, list):
        for j, v in enumerate(x):
            yield from numbers(v, path + (j,))
    elif isinstance(x, (int, float)) and not isinstance(x, bool):
        yield path


def test_the_walk_covers_every_key_of_the_schema():
    # left out above, with why: graph.hub/edges/directed (a star's hub and explicit pairs are ids;
    # directed a boolean), partition.drops (ids), preset (a name; epsilon is walked instead)
    missing = schema_keys() - keys_of(FULL)
    assert not missing, f"the walk sets no value for {sorted(missing)}: add them to FULL"
    assert parse_scenario(FULL) and InProcessFleet(parse_scenario(FULL)).run().metrics.completed


FIELDS = [p for p in numbers(FULL)]


def names(path: tuple, field: str, message: str) -> bool:
    """Does a refusal name the number at ``path``: its key (a list's own key for an element) in the
    field or the message, or the field is the table holding it (a rule across its keys: a
    Lissajous that retraces itself, the sensor's rate against scenario.duration)?"""
    strings = [str(k) for k in path if isinstance(k, str)]
    key, table = strings[-1], (strings[-2] if len(strings) > 1 else None)
    return key in field or key in message or (table is not None and f".{table}." in field + ".")


def with_value(path: tuple, value) -> dict:
    """A copy of FULL with the number at ``path`` replaced by ``value``."""
    data = copy.deepcopy(FULL)
    node = data
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return data


@pytest.mark.parametrize("path", FIELDS, ids=[".".join(map(str, p)) for p in FIELDS])
def test_every_number_at_its_extremes_is_refused_by_name_or_runs_to_the_end(path):
    for value in EXTREMES:
        try:
            scenario = parse_scenario(with_value(path, value), "walk.toml")
        except ConfigError as e:
            assert any(names(path, field, message) for field, message in e.problems), (value, e.problems)
            continue
        metrics = InProcessFleet(scenario).run().metrics  # no exception, no DivergedError
        assert metrics.completed and metrics.duration_s == pytest.approx(1.0, abs=0.06), (value, metrics)


#: an integer beyond a float's range (TOML and a ground station's KEY=VALUE read 1 followed by
#: 400 zeros as an int): math.isfinite raised OverflowError on it, a traceback from `cdus sim`
HUGE_INT = 10**400


@pytest.mark.parametrize("path", FIELDS, ids=[".".join(map(str, p)) for p in FIELDS])
def test_every_number_as_an_integer_beyond_a_float_is_refused_by_name_or_runs_to_the_end(path):
    try:
        scenario = parse_scenario(with_value(path, HUGE_INT), "walk.toml")
    except ConfigError as e:
        assert any(names(path, field, message) for field, message in e.problems), e.problems
        return
    metrics = InProcessFleet(scenario).run().metrics
    assert metrics.completed and metrics.duration_s == pytest.approx(1.0, abs=0.06), metrics

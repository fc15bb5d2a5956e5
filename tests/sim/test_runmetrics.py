"""cdus.sim.runmetrics: the typed metrics a run builds (cdus.sim.summary) write the JSON they
wrote when the builder made a dict, and any record reads back from its JSON equal."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.runmetrics import (ClosestPair, DroppedBy, Event, FaultCounters, Integrity, LinkFaults, LinkMetrics,
                                 LinkStateChange, Metrics, RadioMetrics, RejectedByReason, SafetyInfo, Utilisation,
                                 WorldLost)
from cdus.wire.rejected import Rejected
from tests.jsontree import JSON, paths

GOLDEN = Path(__file__).parent / "golden"
WALL = ("wall_s", "realtime_factor")  # wall-clock figures: they differ from run to run

#: name: (scenario, overrides). The golden JSON is what `cdus sim` wrote at e6d3fd5, before the
#: builder was typed; made again (after a change that is meant to change the results) with
#: `python -m cdus sim CONFIG --duration D --rerun off -q --metrics-out tests/sim/golden/NAME.json`
CASES = {
    "faults": (GOLDEN / "faults.toml", {}),  # link faults (per-link counters, state changes), a kill, a restart
    "lake_radio": ("configs/lake_radio.toml", {"scenario.duration": 5.0}),  # the radio block
    "crossing": ("configs/crossing.toml", {"scenario.duration": 6.0}),  # the safety filter, closest pairs
}


def _without_wall(d: dict) -> dict:
    return {k: v for k, v in d.items() if k not in WALL}


@pytest.mark.parametrize("name", list(CASES))
def test_the_json_written_is_the_one_written_before_the_builder_was_typed(name):
    config, overrides = CASES[name]
    built = InProcessFleet(load_scenario(config, overrides)).run().metrics
    want = json.loads((GOLDEN / f"{name}.json").read_text())
    got = json.loads(json.dumps(built.to_dict()))  # through the text, as the file is
    # the same keys in the same order at every level, the same values: the file, byte for byte
    assert json.dumps(_without_wall(got)) == json.dumps(_without_wall(want))
    assert list(got) == list(want)


def test_a_built_record_reads_back_from_its_json_equal():
    config, overrides = CASES["faults"]
    built = InProcessFleet(load_scenario(config, overrides)).run().metrics
    assert built.link.faults is not None and built.events and built.closest_pairs
    assert Metrics.from_json(json.loads(json.dumps(built.to_dict()))) == built


# ----------------------------------------------------------------- any record, generated

ids = st.text("abcuv12", min_size=1, max_size=5)
finite = st.floats(-1e6, 1e6, allow_nan=False)
maybe = st.none() | finite
counts = st.dictionaries(ids, st.integers(0, 10**9), max_size=3)
n = st.integers(0, 10**9)

fault_counters = st.builds(FaultCounters, n, n, st.builds(DroppedBy, n, n, n, n), n, n)
link_faults = st.builds(LinkFaults, fault_counters, st.dictionaries(ids, fault_counters, max_size=2),
                        st.lists(st.builds(LinkStateChange, finite, ids, st.sampled_from(["up", "lossy", "down"])),
                                 max_size=2).map(tuple))
link = st.builds(LinkMetrics, n, n, n, n, n, maybe, maybe, st.none() | n, st.none() | link_faults,
                 st.just({}) | st.fixed_dictionaries({"extra_key": st.integers()}))
event = st.builds(Event, finite, ids, st.text(max_size=8), st.sampled_from(["info", "warn", "error"]),
                  st.none() | ids, st.none() | ids, st.none() | ids)
pair = st.builds(ClosestPair, st.sampled_from(["usv", "uav", "uav-usv"]), ids, ids, finite, finite, st.booleans(),
                 st.booleans(), st.booleans())
radio = st.builds(RadioMetrics, n, n, n, counts, n, st.builds(Utilisation, maybe, maybe, n), n)
lost = st.builds(WorldLost, st.integers(-64, 255), maybe,
                 st.none() | st.fixed_dictionaries({"alive": st.lists(ids, max_size=2), "path_error_max": maybe,
                                                    "coord_error_max": maybe, "paused": st.booleans()}),
                 st.lists(ids, max_size=3).map(tuple), counts, counts)


@st.composite
def metrics(draw) -> Metrics:
    pairs = draw(st.none() | st.dictionaries(st.sampled_from(["usv", "uav", "uav-usv"]), pair, max_size=3))
    return Metrics(
        scenario=draw(ids), mode=draw(st.sampled_from(["inproc", "lockstep", "realtime"])), seed=draw(n),
        duration_s=draw(finite), path_tol=draw(finite), coord_tol=draw(finite), path_settle_s=draw(maybe),
        coord_settle_s=draw(maybe), final_path_error_max=draw(maybe), final_coord_error_max=draw(maybe),
        omega_rate_final=draw(st.dictionaries(ids, maybe, max_size=3)),
        final_path_error=draw(st.dictionaries(ids, maybe, max_size=3)),
        live_final=tuple(draw(st.lists(ids, max_size=3))), link=draw(st.none() | link), wall_s=draw(finite),
        realtime_factor=draw(maybe), policy=draw(st.sampled_from(["hold", "timeout", "extrapolate"])),
        events=tuple(draw(st.lists(event, max_size=3))), completed=draw(st.booleans()), completion=draw(ids),
        min_separation_m=draw(maybe), closest_pairs=pairs,
        closest_pair=None if pairs is None else draw(st.none() | pair),
        near_collision=None if pairs is None else draw(st.booleans()), interventions=draw(n),
        safety=SafetyInfo(draw(st.booleans()), draw(maybe)),
        integrity=draw(st.none() | st.builds(Integrity, st.booleans(), counts, st.lists(st.text(max_size=5),
                                                                                         max_size=2).map(tuple))),
        rejected_by_reason=draw(st.none() | st.builds(RejectedByReason, counts, counts)),
        never_up=draw(st.none() | st.lists(ids, max_size=2).map(tuple)), radio=draw(st.none() | radio),
        interrupted=draw(st.none() | st.just(True)), written_by=draw(st.none() | st.just("launcher")),
        world_lost=draw(st.none() | lost),
        extra=draw(st.just({}) | st.fixed_dictionaries({"from_a_later_version": st.integers()})))


@settings(max_examples=300, deadline=None)
@given(metrics())
def test_any_record_reads_back_from_its_json_equal(m):
    d = m.to_dict()
    assert Metrics.from_json(json.loads(json.dumps(d))) == m
    assert Metrics.from_json(d).to_dict() == d


@settings(max_examples=300, deadline=None)
@given(metrics(), st.data())
def test_any_field_spoiled_reads_as_a_record_or_a_rejected_naming_a_field_never_an_exception(m, data):
    """The decoders of every part (WorldLost and Utilisation new among them): a file with any value
    anywhere, a part's key removed included, is the record or a Rejected, never a traceback."""
    d = json.loads(json.dumps(m.to_dict()))
    path = data.draw(st.sampled_from([p for p in paths(d) if p]))
    *up, last = path
    holder = d
    for k in up:
        holder = holder[k]
    if data.draw(st.booleans()) and isinstance(holder, dict):
        del holder[last]
    else:
        holder[last] = data.draw(JSON)
    got = Metrics.from_json(d)
    assert isinstance(got, Metrics) or (isinstance(got, Rejected) and got.field), got


LOST = {"world_exit": -9, "last_status_t": 12.5,
        "last_status": {"alive": ["usv1"], "path_error_max": 0.5, "coord_error_max": 0.1, "paused": False},
        "alive_tokens": ["usv1"], "restarts": {"usv2": 1}, "rejected_by_launcher": {"status unsigned": 3}}


@pytest.mark.parametrize("key", list(LOST))
def test_a_world_lost_block_missing_a_key_or_with_a_wrong_one_is_rejected_naming_it(key):
    d = json.loads((GOLDEN / "crossing.json").read_text())
    lost = Metrics.from_json({**d, "written_by": "launcher", "world_lost": LOST})
    assert lost.world_lost == WorldLost(-9, 12.5, LOST["last_status"], ("usv1",), {"usv2": 1}, {"status unsigned": 3})
    missing = Metrics.from_json({**d, "world_lost": {k: v for k, v in LOST.items() if k != key}})
    wrong = Metrics.from_json({**d, "world_lost": {**LOST, key: "x"}})
    assert isinstance(missing, Rejected) and missing.field == f"world_lost.{key}", missing
    assert isinstance(wrong, Rejected) and wrong.field == f"world_lost.{key}", wrong
    inf = Metrics.from_json({**d, "world_lost": {**LOST, "last_status_t": float("inf")}})
    assert isinstance(inf, Rejected) and inf.field == "world_lost.last_status_t"  # the summary prints it as a time

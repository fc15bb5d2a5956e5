"""cdus.commands.changes: a formation (phases or offsets) and a path."""

from __future__ import annotations

import math
from types import SimpleNamespace as NS

import pytest

from cdus.commands.base import Applied, Rejected
from cdus.commands.changes import MAX_ENTRIES, PATH_DEPTH, Formation, Path

from .common import RecordedNode

IDS = ["usv1", "usv2", "usv3"]
RING = [NS(i="usv2", k="usv1"), NS(i="usv3", k="usv2"), NS(i="usv1", k="usv3")]


@pytest.mark.parametrize("fields, out", [
    ({"phases": {"usv2": 2}}, Formation((("usv2", 2.0),), ())),
    ({"offsets": [{"i": "usv2", "k": "usv1", "delta": 1}], "phases": {}},
     Formation((), (("usv2", "usv1", 1.0),))),
    ({}, Rejected("give either phases (id = θ, ω units) or offsets (I listens to K: Δ), exactly one", "phases")),
    ({"phases": {"usv2": 1.0}, "offsets": [{"i": "a", "k": "b", "delta": 1.0}]},
     Rejected("give either phases (id = θ, ω units) or offsets (I listens to K: Δ), exactly one", "phases")),
    ({"phases": [1]}, Rejected("must be a table of vehicle = θ (ω units), e.g. { usv2 = 2.0944 }, got [1]", "phases")),
    ({"offsets": {"a": 1}}, Rejected('must be a list of { i = "usv2", k = "usv1", delta = ... }, got {\'a\': 1}',
                                     "offsets")),
    ({"phases": {"a b": 1.0}}, Rejected("must be a vehicle id (1-64 letters, digits, '_' or '-'), got 'a b'", "phases")),
    ({"phases": {"usv2": math.nan}}, Rejected("must be a finite number >= -1e+09 and <= 1e+09 (ω units), got nan",
                                              "phases.usv2")),
    ({"offsets": [{"i": "usv2", "k": "usv1"}]},
     Rejected('must be { i = "usv2", k = "usv1", delta = ... } (i listens to k)', "offsets[0]")),
    ({"offsets": [{"i": "usv2", "k": 3, "delta": 1.0}]}, Rejected("must be a vehicle id, got 3", "offsets[0].k")),
    ({"offsets": [{"i": "usv2", "k": "usv1", "delta": 2e9}]},
     Rejected("must be a finite number >= -1e+09 and <= 1e+09 (ω units), got 2e+09", "offsets.usv2.usv1")),
    ({"phases": {f"v{j}": 0.0 for j in range(MAX_ENTRIES + 1)}},
     Rejected(f"at most {MAX_ENTRIES} entries in one command", "phases")),
    ({"phases": {"usv1": 1.0}, "x": 1}, Rejected("unknown; this command takes phases, offsets", "x")),
])
def test_a_formation_parses_or_names_its_field(fields, out):
    assert Formation.parse(fields) == out


def test_a_formation_at_its_most_entries_and_its_fields():
    assert isinstance(Formation.parse({"phases": {f"v{j}": 0.0 for j in range(MAX_ENTRIES)}}), Formation)
    f = Formation((), (("usv2", "usv1", 1.5),))
    assert f.fields() == {"phases": {}, "offsets": [{"i": "usv2", "k": "usv1", "delta": 1.5}]}
    assert Formation((("usv2", 2.0),)).fields() == {"phases": {"usv2": 2.0}, "offsets": []}


def test_resolved_against_the_fleet():
    current = [0.0, -1.0, -2.0]
    assert Formation((("usv3", 4.0), ("usv1", 1.0))).resolve(IDS, current, RING, True) == \
        Formation((("usv1", 1.0), ("usv3", 4.0)))  # in the fleet's order
    assert Formation((("usv9", 1.0),)).resolve(IDS, current, RING, True).field == "phases"
    out = Formation((), (("usv2", "usv1", -1.0),)).resolve(IDS, current, RING, True)
    assert out == Formation()  # the Δ in force already: no phase changes
    broken = Formation((), (("usv2", "usv1", 5.0),)).resolve(IDS, current, RING, True)
    assert broken.field == "offsets" and "inconsistent formation offsets" in broken.reason
    assert Formation((), (("usv1", "usv2", 1.0),)).resolve(IDS, current, RING, True).field == "offsets[0]"


def test_a_formation_applied_to_a_node():
    n = RecordedNode()
    assert Formation((("usv2", 3.0),)).apply(n, 9, IDS) == Applied(9) and n.calls == [("formation", {1: 3.0}, 9)]
    assert Formation((), (("usv2", "usv1", 3.0),)).apply(n, 9, IDS) == Rejected(
        "offsets are resolved into phases first (Formation.resolve)", "offsets")
    assert Formation((("usv9", 3.0),)).apply(n, 9, IDS).field == "phases" and len(n.calls) == 1


CIRCLE = {"family": "circle", "center": [0, 0], "radius": 5}


def test_a_path_parses_for_any_dimension_and_applies_for_the_vehicles():
    p = Path.parse({"vehicle": "usv1", "path": CIRCLE})
    assert p.vehicle == "usv1" and p.path_table() == CIRCLE and p.fields() == {"vehicle": "usv1", "path": CIRCLE}
    p3 = Path.parse({"vehicle": "uav1", "path": {**CIRCLE, "center": [0, 0, 20]}})
    assert isinstance(p3, Path)
    assert Path.parse({"vehicle": "usv1", "path": {**CIRCLE, "radius": -1}}).field == "path.radius"
    assert Path.parse({"vehicle": "usv1", "path": {"family": "cirle"}}).field == "path.family"
    assert Path.parse({"vehicle": "a b", "path": CIRCLE}).field == "vehicle"
    assert Path.parse({"vehicle": "usv1"}).field == "path" and Path.parse({"path": CIRCLE}).field == "vehicle"
    assert Path.parse({"vehicle": "usv1", "path": {**CIRCLE, "center": [[[0]]]}}) == Rejected("nested too deep", "path")
    assert PATH_DEPTH == 2
    n = RecordedNode(dim=2)
    assert p.apply(n, 10, IDS) == Applied(10) and n.calls == [("path", 2, 10)]
    assert p.apply(RecordedNode(index=1), 10, IDS) == Rejected("this path is for usv1, not usv2", "vehicle")
    assert p.apply(RecordedNode(index=1), 10) == Applied(10)  # no ids: not checked
    assert p3.checked_for(3).dim == 3 and p3.checked_for(2).dim == 2  # as the world's check_path: a boat takes x, y
    lissajous = Path.parse({"vehicle": "uav1", "path": {"family": "lissajous", "center": [0, 0, 20], "a": 5, "b": 5,
                                                         "frequency": [1, 1, 2], "phase": [0, 0, 0]}})
    if isinstance(lissajous, Path):  # fit for 3-D only: a boat refuses it, naming itself
        wrong = lissajous.checked_for(2)
        assert not isinstance(wrong, Rejected) or wrong.reason.endswith("(vehicle uav1 is 2-D)")

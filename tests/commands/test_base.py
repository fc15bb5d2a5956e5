"""cdus.commands.base and cdus.wire.rejected: the refusal, the shared field readers, freeze/thaw."""

from __future__ import annotations

import math

from hypothesis import given, strategies as st

from cdus.commands.base import (
    _shown, config_rejected, freeze, keyed_table, table, thaw, unknown_keys, vehicle_id, when,
)
from cdus.scenario.errors import ConfigError
from cdus.wire.rejected import Rejected


def test_a_refusal_says_its_field_and_nests_under_a_prefix():
    assert str(Rejected("must be > 0", "k")) == "k: must be > 0" and str(Rejected("no")) == "no"
    assert Rejected("bad", "delta").under("offsets[0]") == Rejected("bad", "offsets[0].delta")
    assert Rejected("bad", "[2]").under("k") == Rejected("bad", "k[2]")
    assert Rejected("bad").under("phases") == Rejected("bad", "phases")


def test_vehicle_ids_as_the_keys_spell_them():
    assert vehicle_id({"vehicle": "usv_2-a"}) == "usv_2-a"
    assert vehicle_id({}) == Rejected("missing: name the vehicle, e.g. usv2", "vehicle")
    assert vehicle_id({"i": 3}, "i") == Rejected("must be a vehicle id, got 3", "i")
    assert vehicle_id({"vehicle": "a b"}).reason == "must be a vehicle id (1-64 letters, digits, '_' or '-'), got 'a b'"
    assert vehicle_id({"vehicle": ""}).field == "vehicle" and vehicle_id({"vehicle": ""}, empty_ok=True) == ""
    assert vehicle_id({"vehicle": "x" * 64}) == "x" * 64 and isinstance(vehicle_id({"vehicle": "x" * 65}), Rejected)


def test_times_tables_and_keys():
    assert when({}) is None and when({"at": -1.0}) is None and when({"at": 0}) == 0.0 and when({"at": 5}) == 5.0
    assert when({"at": math.nan}).field == "at" and when({"at": 2e9}).field == "at" and when({"at": True}).field == "at"
    assert when({"at": 1e9}) == 1e9
    assert table({"t": {"a": 1}}, "t", "{}") == {"a": 1}
    assert table({"t": {1: 1}}, "t", "{ a = 1 }") == Rejected("must be a table, e.g. { a = 1 }, got {1: 1}", "t")
    assert table({}, "t", "{}").reason == "must be a table, e.g. {}, got None"
    assert unknown_keys({"a": 1, "z": 2, "y": 3}, ("a",)) == Rejected("unknown; this command takes a", "y")
    assert unknown_keys({"z": 1}, ()) == Rejected("unknown; this command takes nothing", "z")
    assert unknown_keys({"a": 1}, ("a",)) is None
    assert keyed_table({"t": {}, "x": 1}, ("t",), "t", "{}").field == "x" and keyed_table({"t": {}}, ("t",), "t", "{}") == {}


def test_values_are_shown_short_and_as_written():
    assert _shown(2.5) == "2.5" and _shown(math.inf) == "inf" and _shown(3) == "3" and _shown(True) == "True"
    assert _shown("s") == "'s'" and _shown("x" * 100) == repr("x" * 100)[:57] + "..." and len(_shown("x" * 100)) == 60
    assert _shown("x" * 58) == repr("x" * 58)  # 60 characters with its quotes: kept whole


def test_a_config_error_becomes_its_first_problem():
    e = ConfigError("link command", [("link.loss", "must be a probability"), ("link.x", "other")])
    assert config_rejected(e, "link") == Rejected("must be a probability", "loss")
    assert config_rejected(e) == Rejected("must be a probability", "link.loss")
    assert config_rejected(ConfigError("s", [("", "whole")])) == Rejected("whole", None)
    assert config_rejected(ConfigError("s", [("linked.x", "m")]), "link") == Rejected("m", "linked.x")


_tables = st.recursive(st.one_of(st.integers(), st.floats(allow_nan=False), st.text(max_size=4), st.booleans()),
                       lambda inner: st.one_of(st.lists(inner, max_size=3),
                                               st.dictionaries(st.text(max_size=4), inner, max_size=3)), max_leaves=10)


@given(st.dictionaries(st.text(max_size=4), _tables, max_size=4))
def test_freeze_keeps_a_table_hashable_and_thaw_gives_it_back(t):
    f = freeze(t)
    hash(f)
    assert thaw(f) == t and freeze(thaw(f)) == f

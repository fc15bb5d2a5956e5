"""The validation toolkit: one wording for each kind of mistake, wherever it is made."""

from __future__ import annotations

import math

import pytest

from cdus.scenario.checks import Problems, describe, did_you_mean, quote, show


def one(check) -> tuple[object, list[tuple[str, str]]]:
    """Run ``check(p)`` on fresh problems: (its result, the problems)."""
    p = Problems()
    result = check(p)
    return result, p.items


def message(check) -> str:
    result, items = one(check)
    assert result is None and len(items) == 1, items
    return items[0][1]


# --------------------------------------------------------------------------- spelling


@pytest.mark.parametrize("value, toml", [
    (True, "true"), ('a "b"', r'"a \"b\""'), (1, "1"), (0.5, "0.5"), (math.inf, "inf"), (math.nan, "nan"),
    ([1, "x"], '[1, "x"]'), ((1, 2), "[1, 2]"), ({"a": 1, "b": [False]}, "{a = 1, b = [false]}"),
])
def test_values_are_shown_in_toml_spelling(value, toml):
    assert show(value) == toml


@pytest.mark.parametrize("value, text", [
    (False, "the boolean false"), ("x", 'the string "x"'), (3, "the number 3"), (2.5, "the number 2.5"),
    ([1], "the list [1]"), ({"k": 1}, "the table {k = 1}"), (None, "None"),
])
def test_describe_names_the_toml_type(value, text):
    assert describe(value) == text


def test_quote_and_did_you_mean():
    assert quote("usv1") == '"usv1"'
    assert did_you_mean("rign", ["ring", "chain"]) == ' (did you mean "ring"?)'
    assert did_you_mean("zzz", ["ring", "chain"]) == ""


# --------------------------------------------------------------------------- the problems


def test_problems_are_kept_once_in_order_and_since_tells_what_is_new():
    p = Problems()
    p.add("a", "x")
    mark = len(p)
    assert not p.since(mark) and p
    p.add("b", "y")
    p.add("a", "x")
    assert p.items == [("a", "x"), ("b", "y")] and list(p) == p.items and p.since(mark)
    assert not Problems()


# --------------------------------------------------------------------------- numbers


def test_a_good_number_comes_back_as_a_float_with_no_problem():
    assert one(lambda p: p.number(3, "f", gt=0)) == (3.0, [])
    assert one(lambda p: p.number(math.inf, "f", gt=0, allow_inf=True)) == (math.inf, [])
    assert one(lambda p: p.number(-2.5, "f")) == (-2.5, [])


@pytest.mark.parametrize("value, kw, text", [
    (-1, {"gt": 0, "unit": " Hz"}, "must be a number > 0 Hz, got -1"),
    ("fast", {"gt": 0, "unit": " Hz"}, 'must be a number > 0 Hz, got the string "fast"'),
    (True, {"gt": 0, "unit": " s"}, "must be a number > 0 s, got the boolean true"),
    (math.inf, {"gt": 0}, "must be a finite number > 0, got inf"),
    (math.nan, {}, "must be a finite number, got nan"),
    (1.5, {"ge": 0, "le": 1}, "must be a number >= 0 and <= 1, got 1.5"),
    (-0.1, {"ge": 0, "unit": " m/s (std)", "note": " (set in [defaults])"},
     "must be a number >= 0 m/s (std), got -0.1 (set in [defaults])"),
])
def test_number_wording(value, kw, text):
    assert message(lambda p: p.number(value, "f", **kw)) == text


def test_probability_integer_boolean_string():
    assert message(lambda p: p.probability(2, "f", "Bernoulli loss")) == \
        "must be a probability in [0, 1] (Bernoulli loss), got 2"
    assert message(lambda p: p.probability("x", "f", "loss")) == \
        'must be a probability in [0, 1] (loss), got the string "x"'
    assert message(lambda p: p.probability(math.nan, "f", "loss")) == "must be a probability in [0, 1] (loss), got nan"
    assert one(lambda p: p.probability(0, "f", "loss")) == (0.0, [])
    assert message(lambda p: p.integer(-1, "f", ge=0)) == "must be an integer >= 0, got -1"
    assert message(lambda p: p.integer(1.0, "f", ge=0)) == "must be an integer >= 0, got the number 1.0"
    assert message(lambda p: p.integer(True, "f")) == "must be an integer, got the boolean true"
    assert one(lambda p: p.integer(0, "f", ge=0)) == (0, [])
    assert message(lambda p: p.boolean(1, "f", false=" (FIFO)")) == "must be true or false (FIFO), got the number 1"
    assert one(lambda p: p.boolean(False, "f")) == (False, [])
    assert message(lambda p: p.string(" ", "f", nonempty=True)) == 'must be a non-empty string, got the string " "'
    assert message(lambda p: p.string(3, "f")) == "must be a string, got the number 3"
    assert one(lambda p: p.string("", "f")) == ("", [])


# --------------------------------------------------------------------------- choices and references


def test_choice_suggests_the_closest_and_lists_every_option():
    opts = ("ring", "chain", "star")
    assert message(lambda p: p.choice("rign", "f", opts, "topology")) == \
        'unknown topology "rign" (did you mean "ring"?); choose one of ring, chain, star'
    assert message(lambda p: p.choice(3, "f", opts, "topology", note=" (set in [defaults])", extra=" (or x)")) == \
        "unknown topology 3 (set in [defaults]); choose one of ring, chain, star (or x)"
    assert one(lambda p: p.choice("star", "f", opts, "topology")) == ("star", [])


def test_vehicle_references():
    ids = ["usv1", "usv2"]
    assert message(lambda p: p.vehicle("usb1", "f", ids)) == \
        '"usb1" is not a vehicle (did you mean "usv1"?); ids are usv1, usv2'
    assert message(lambda p: p.vehicle("x", "f", ids, wildcard=True)) == \
        '"x" is not a vehicle; ids are usv1, usv2 or "*" (any vehicle)'
    assert message(lambda p: p.vehicle(3, "f", ids, wildcard=True)) == \
        'must be a vehicle id or "*" (any vehicle), got the number 3'
    assert message(lambda p: p.vehicle("*", "f", ids)) == '"*" is not a vehicle; ids are usv1, usv2'
    assert one(lambda p: p.vehicle("*", "f", ids, wildcard=True)) == ("*", [])
    assert one(lambda p: p.vehicle("anything", "f", None)) == ("anything", [])  # ids unknown: type only
    assert message(lambda p: p.vehicle("a", "f", [])) == '"a" is not a vehicle; ids are (none)'


# --------------------------------------------------------------------------- shapes


def test_vector_table_tables():
    assert one(lambda p: p.vector([1, 2], "f", 2, "a position")) == ((1.0, 2.0), [])
    assert message(lambda p: p.vector([1, 2, 3], "f", 2, "a position [x, y]")) == \
        "must be a list of 2 numbers (a position [x, y]), got 3 numbers [1, 2, 3]"
    assert message(lambda p: p.vector("x", "f", 2, "a position", " (set in [defaults])")) == \
        'must be a list of 2 numbers (a position), got the string "x" (set in [defaults])'
    assert message(lambda p: p.vector([1, math.inf], "f", 2, "a position")) == \
        "must be a list of 2 numbers (a position), got 2 numbers [1, inf]"
    assert message(lambda p: p.table(3, "rates", "a [rates] section")) == \
        "must be a table, e.g. a [rates] section, got the number 3"
    assert one(lambda p: p.table({}, "f", "x")) == ({}, [])
    assert one(lambda p: p.tables({"a": 1}, "event", "event")) == ([], [
        ("event", "must be an array of tables ([[event]] sections), got the table {a = 1}")])
    assert one(lambda p: p.tables([{}], "event", "event")) == ([{}], [])


def test_unknown_keys_suggest_and_list_the_valid_ones():
    p = Problems()
    p.unknown_keys({"durration": 1, "name": "x", "zzz": 2, "id": 1}, ("name", "duration"), "scenario", skip=("id",))
    assert p.items == [
        ("scenario.durration", 'unknown key; did you mean "duration"? valid keys here: name, duration'),
        ("scenario.zzz", "unknown key; valid keys here: name, duration"),
    ]
    p = Problems()
    p.unknown_keys({"vehicles": []}, ("vehicle",), "", what="section")
    assert p.items == [("vehicles", 'unknown section; did you mean "vehicle"? valid sections here: vehicle')]
    p = Problems()
    p.unknown_keys({"b1": 1}, ("b_u",), "g", what="regulator gain", valid="the heading regulator takes")
    assert p.items == [("g.b1", "unknown regulator gain; the heading regulator takes: b_u")]
    p.missing("scenario.name", "every scenario needs a name")
    assert p.items[-1] == ("scenario.name", "missing; every scenario needs a name")

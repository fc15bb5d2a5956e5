"""The addressed key space: a process's one subscription takes exactly what is addressed to it."""

from __future__ import annotations

import pytest
import zenoh

from cdus.wire import keys

IDS = ["usv1", "usv2", "usv11", "uav1", "world"]


def hears(me: str, key: str) -> bool:
    return zenoh.KeyExpr(keys.inbox("f", me)).intersects(zenoh.KeyExpr(key))


@pytest.mark.parametrize("me", IDS)
def test_an_inbox_takes_every_message_addressed_to_it_and_nothing_else(me):
    addressed = {
        keys.omega("f", "uav1", ["usv1", "usv11"]): {"usv1", "usv11"},
        keys.ctl("f", ["usv1", "usv2", "usv11", "uav1"]): {"usv1", "usv2", "usv11", "uav1"},
        keys.ctl("f", ["usv2"]): {"usv2"},
        keys.state("f", "usv1"): {"world"},
        keys.stats("f", "usv2"): {"world"},
        keys.world_cmd("f", "gs"): {"world"},
        keys.wake("f", "usv11"): {"usv11"},
        keys.ping("f", "usv1"): {"usv1"},
    }
    for key, receivers in addressed.items():
        assert hears(me, key) == (me in receivers), (me, key)


def test_other_fleets_and_the_worlds_own_keys_are_not_in_an_inbox():
    assert not hears("usv1", keys.omega("g", "usv2", ["usv1"]))  # another fleet
    assert not hears("world", keys.world_status("f")) and not hears("world", keys.alive("f", "usv1", "a1"))


def test_fleet_names_are_checked():
    assert keys.check_fleet("lake_1-a") == "lake_1-a"
    for bad in ("", "a/b", "a+b", "a*", "x" * 65):
        with pytest.raises(ValueError, match="fleet name"):
            keys.check_fleet(bad)


def test_leaf_and_alive_name_parse_what_the_builders_make():
    assert keys.leaf(keys.state("f", "usv1")) == ("state", "usv1")
    assert keys.leaf(keys.omega("f", "usv1", ["usv2"])) == ("omega", "usv1")
    assert keys.alive_name(keys.alive("f", "uav3", "9f0a")) == "uav3"
    assert keys.alive_token(keys.alive("f", "world", "0123456789abcdef0123456789abcdef")) == (
        "world", "0123456789abcdef0123456789abcdef")


def test_a_token_key_is_exactly_a_process_name_and_a_session_id():
    """What a liveliness watch of ``alive/*/*`` can deliver besides a process's own token: a token
    declared on a key expression (it intersects every watch, and arrives with its own key), a bare
    name (the key before session ids: anyone's token on it hid that process's loss), junk."""
    for key in ("cdus/f/alive/**", "cdus/f/alive/*/*", "cdus/f/alive/usv2/*", "cdus/f/alive/usv2/**",
                "cdus/f/alive/usv2", "cdus/f/alive/$*/a1", "cdus/f/alive/usv2/a1/x", "cdus/f/alive/usv2/A1",
                "cdus/f/alive/usv2/" + "a" * 33, "cdus/f/alive//a1", "cdus/f/alive/u v/a1", "cdus/f/to/usv2/a1",
                "cdus/bad name/alive/usv2/a1", "other/f/alive/usv2/a1", ""):
        assert keys.alive_token(key) is None and keys.alive_name(key) is None, key
    held: dict[str, set[str]] = {}
    assert keys.hold_token(held, "cdus/f/alive/**", True) is None and held == {}
    assert keys.hold_token(held, keys.alive("f", "usv2", "a1"), True) == ("usv2", True)
    assert keys.hold_token(held, keys.alive("f", "usv2", "b2"), True) == ("usv2", True)
    assert keys.hold_token(held, keys.alive("f", "usv2", "a1"), False) == ("usv2", True)  # b2's is up
    assert keys.hold_token(held, keys.alive("f", "usv2", "b2"), False) == ("usv2", False) and held == {}


def test_fleet_of_names_the_fleet_of_a_key_in_a_fleets_space_only():
    assert keys.fleet_of("cdus/lake_demo/alive/world") == "lake_demo"
    assert keys.fleet_of("cdus/f/x") == "f"
    for key in ("cdus/f", "cdus", "other/f/alive/world", "cdus/bad name/alive/world", "cdus//alive/world"):
        assert keys.fleet_of(key) is None, key


def test_leaf_and_recipients_at_their_edges():
    """mutmut on keys.py: leaf and recipients had no test of their own (12 survivors)."""
    assert keys.leaf("cdus/f/to/+w+/ctl") == ("ctl", "")
    assert keys.leaf("cdus/f/to/+w+/omega/usv1") == ("omega", "usv1")
    assert keys.leaf("cdus/f/to/+w+") == ("", "") and keys.leaf("cdus/f/alive/usv1/ab") == ("", "")
    assert keys.recipients([]) == "+" and keys.recipients(["a"]) == "+a+" and keys.recipients("ab") == "+a+b+"


def test_inbox_leaves_takes_the_one_chunk_keys_addressed_to_me_and_no_omega():
    """A realtime agent's FIFO (its neighbours' ω have rings of their own)."""
    leaves = zenoh.KeyExpr(keys.inbox_leaves("f", "usv1"))
    for key in (keys.ctl("f", ["usv2", "usv1"]), keys.contacts("f", "usv1"), keys.radio("f", ["usv1"]),
                keys.wake("f", "usv1")):
        assert leaves.intersects(zenoh.KeyExpr(key)), key
    for key in (keys.omega("f", "usv2", ["usv1"]), keys.ctl("f", ["usv11"]), keys.ctl("g", ["usv1"]),
                keys.state("f", "usv1")):
        assert not leaves.intersects(zenoh.KeyExpr(key)), key


def test_leaf_kind_is_the_kind_of_a_key_that_ends_with_it_and_nothing_else():
    assert keys.leaf_kind(keys.ctl("f", ["a", "b"])) == "ctl"
    assert keys.leaf_kind(keys.contacts("f", "a")) == "contacts"
    assert keys.leaf_kind(keys.radio("f", ["a"])) == "radio"
    assert keys.leaf_kind(keys.wake("f", "a")) == "wake"
    assert keys.leaf_kind(keys.ping("f", "a")) == "ping"
    for key in (keys.omega("f", "a", ["b"]), keys.state("f", "a"), keys.world_status("f"), "cdus/f/to/+a+/x/ctl",
                "cdus/f/to/+a+/ctl/", "x/f/to/+a+/ctl", "cdus/f/from/+a+/ctl", "ctl", "", "cdus/f/to/+a+"):
        assert keys.leaf_kind(key) == "", key


from hypothesis import given, strategies as hs  # noqa: E402

_chunk = hs.text(alphabet="ab+*$-_", max_size=4) | hs.sampled_from(["cdus", "to", "ctl", "omega", ""])
_keys = hs.tuples(hs.sampled_from(["cdus", "x", ""]), _chunk, hs.sampled_from(["to", "alive", "x"]),
                  hs.lists(_chunk, max_size=4)).map(lambda t: "/".join([t[0], t[1], t[2], *t[3]]))


@given(_keys | hs.text(max_size=30))
def test_leaf_kind_names_a_kind_only_for_a_key_of_exactly_that_shape(key):
    kind = keys.leaf_kind(key)
    parts = key.split("/")
    if kind:
        assert key == f"cdus/{parts[1]}/to/{parts[3]}/{kind}" and "/" not in kind
    else:
        assert len(parts) != 5 or parts[0] != "cdus" or parts[2] != "to" or parts[4] == ""

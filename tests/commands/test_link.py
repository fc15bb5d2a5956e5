"""cdus.commands.link: a [link] table merged over the one in force."""

from __future__ import annotations

import math

from cdus.commands.base import Applied, Rejected
from cdus.commands.link import LINK_DEPTH, Link
from cdus.core.changes import Refused

from .common import RecordedNode


def test_a_link_command_is_checked_as_the_scenarios_link():
    assert Link.parse({"link": {"loss": 0.3}, "at": -1.0}) == Link((("loss", 0.3),), None)
    assert Link.parse({"link": {"loss": 0.3}}).at is None and Link.parse({"link": {"loss": 0.3}, "at": 2}).at == 2.0
    assert Link.parse({"link": {"loss": 3}}).field == "loss"
    assert Link.parse({"link": {"delay": {"base": 1e308}}}).field == "delay.base"
    assert Link.parse({"link": {"loss": 0.1}, "at": math.inf}).field == "at"
    assert Link.parse({"link": [1]}).field == "link" and Link.parse({"x": 1}).field == "x"
    deep: dict = {"loss": 0.1}
    for _ in range(LINK_DEPTH + 1):
        deep = {"override": deep}
    assert Link.parse({"link": deep}) == Rejected("nested too deep", "link")
    c = Link.parse({"link": {"delay": {"base": 0.1}, "loss": 0.3}, "at": 4.0})
    assert c.link_table() == {"delay": {"base": 0.1}, "loss": 0.3}
    assert c.fields() == {"link": {"delay": {"base": 0.1}, "loss": 0.3}, "at": 4.0}
    assert Link.parse({"link": {"loss": 0.3}}).fields()["at"] == -1.0


def test_merged_over_the_table_in_force_and_applied():
    c = Link.parse({"link": {"delay": {"jitter": 0.01}}})
    assert c.merged({"delay": {"base": 0.1}}, None) == {"delay": {"base": 0.1, "jitter": 0.01}}
    bad = Link.parse({"link": {"down": [{"from": 1.0, "to": 2.0, "links": [["usv1", "usv9"]]}]}})
    if not isinstance(bad, Rejected):  # a reference to an unknown vehicle is known only with the ids
        assert isinstance(bad.merged({}, ["usv1", "usv2"]), Rejected)
    n = RecordedNode()
    out = Link.parse({"link": {"loss": 0.2, "policy": "hold"}}).apply(n, 0.5, ({}, ["usv1", "usv2"]))
    assert out == Applied(10, 1.0)  # the node took it from t = 1.0 s (its newest change)
    assert [c[0] for c in n.calls] == ["link", "policy"] and n.calls[1][3] == 10
    n = RecordedNode()
    assert Link.parse({"link": {"loss": 0.2}}).apply(n, 2.0) == Applied(20, 2.0) and len(n.calls) == 1


def test_a_vehicle_the_fleet_lacks_is_refused_once_the_ids_are_known_and_the_policy_applied_as_given():
    c = Link.parse({"link": {"override": [{"src": "usv9", "loss": 0.5}]}})
    assert isinstance(c, Link)  # no ids yet: any name
    assert c.merged({}, ["usv1", "usv2"]).field == "override[0].src"
    assert c.apply(RecordedNode(), 2.0, ({}, ["usv1", "usv2"])).field == "override[0].src"
    assert c.apply(RecordedNode(), 2.0) == Applied(20, 2.0)  # no ids: not checked
    n = RecordedNode()
    assert Link.parse({"link": {"timeout": 3.0}}).apply(n, 2.0, ({"policy": "extrapolate"}, ["usv1"])) == Applied(20, 2.0)
    assert n.calls[1] == ("policy", "extrapolate", 3.0, 20)
    n = RecordedNode()
    n.set_link = lambda spec, at: Refused("cannot change at run time")  # the node's own refusal, passed on
    assert Link.parse({"link": {"loss": 0.1}}).apply(n, 1.0) == Rejected("cannot change at run time")

"""cdus.commands.radio: a transmit power and a station's place."""

from __future__ import annotations

from cdus.commands.base import Applied, Rejected
from cdus.commands.radio import ADHOC, Radio

from .common import RecordedNode


class _Channel:
    def __init__(self, fail=False):
        self.fail, self.calls = fail, []

    def update(self, at, tx_power_dbm=None, station=None):
        if self.fail:
            raise ValueError("later change in force")
        self.calls.append((at, tx_power_dbm, station))


def test_a_radio_command_is_checked_as_the_scenarios():
    assert Radio.parse({"radio": {"tx_power": 5}}) == Radio(5.0, None, None)
    assert Radio.parse({"radio": {"station": [0, -60]}, "at": 3}) == Radio(None, (0.0, -60.0, 0.0), 3.0)
    assert Radio.parse({"radio": {"tx_power": 1e308}}).field == "tx_power"
    assert Radio.parse({"radio": {}}).field is None or Radio.parse({"radio": {}}).field == "radio"
    assert Radio.parse({"radio": {"tx_power": 5}, "at": "now"}).field == "at"
    assert Radio.parse({"radio": 5}).field == "radio" and Radio.parse({"y": 1}).field == "y"
    c = Radio(5.0, (1.0, 2.0, 3.0), None)
    assert c.change() == {"tx_power": 5.0, "station": [1.0, 2.0, 3.0]} and Radio(None, None).change() == {}
    assert c.fields() == {"radio": {"tx_power": 5.0, "station": [1.0, 2.0, 3.0]}, "at": -1.0}
    assert Radio(5.0, None, 2.0).fields()["at"] == 2.0
    assert c.topology_problem("adhoc") == Rejected(ADHOC, "station")
    assert c.topology_problem("station") is None and Radio(5.0, None).topology_problem("adhoc") is None


def test_applied_to_a_nodes_channel():
    assert Radio(5.0, None).apply(RecordedNode(), 1.0) == Rejected("this scenario has no [radio] table")
    ch = _Channel()
    n = RecordedNode(radio=type("R", (), {"channel": ch})())
    assert Radio(5.0, None).apply(n, 1.25) == Applied(13, 1.25) and ch.calls == [(1.25, 5.0, None)]
    n = RecordedNode(radio=type("R", (), {"channel": _Channel(fail=True)})())
    assert Radio(5.0, None).apply(n, 1.0) == Rejected("later change in force")

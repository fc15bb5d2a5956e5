"""The agent's formation and path ctl (issue 18): applied from their tick, hostile fields counted
by reason and dropped, never raised."""

from __future__ import annotations

import math

from hypothesis import HealthCheck, given, settings, strategies as st

from cdus.wire import keys
from cdus.wire.messages import encode_control
from tests.vehicle_agent.fake_session import FLEET, ME, ctl

REASONS = {"formation_range", "path_range", "path_vehicle", "bad_formation_command", "bad_path_command", "type",
           "malformed", "oversized", "unknown_op", "version", "non_finite"}


def test_formation_and_path_commands_apply_from_their_tick(fake):
    a, s, lines = fake()
    ctl(s, "formation", phases={"usv2": 1.5, "uav3": -2.0}, tick=3)
    ctl(s, "path", vehicle=ME, path={"family": "circle", "center": [1.0, 2.0], "radius": 4.0}, tick=2)
    a.drain()
    assert not a.rejected
    node = a.node
    now = node.formation.phases_at(3)
    assert (now[a.ids.index("usv2")], now[a.ids.index("uav3")]) == (1.5, -2.0)
    assert node.formation.phases_at(2)[a.ids.index("usv2")] != 1.5
    assert node._paths and node._paths[0][0] == 2 and node._paths[0][1].center == (1.0, 2.0)
    assert any("formation phases" in ln and "from tick 3" in ln for ln in lines)


def test_bad_formation_and_path_commands_are_counted_by_reason(fake):
    a, s, lines = fake()
    ctl(s, "formation", phases={"nobody": 1.0}, tick=3)
    ctl(s, "formation", phases={"usv2": 1e300}, tick=3)
    ctl(s, "formation", phases={"usv2": 1.0}, tick=-1)
    ctl(s, "path", vehicle="usv2", path={"family": "circle", "center": [0, 0], "radius": 1}, tick=1)
    ctl(s, "path", vehicle=ME, path={"family": "line", "origin": [0, 0], "heading": [0, 0]}, tick=1)
    ctl(s, "path", vehicle=ME, path={"family": "circle", "center": {"a": {"b": {"c": 1}}}, "radius": 1}, tick=1)
    ctl(s, "path", vehicle=ME, path={"family": 7}, tick=1)
    a.drain()
    assert dict(a.rejected) == {"bad_formation_command": 2, "formation_range": 1, "path_vehicle": 1,
                                "bad_path_command": 2, "path_range": 1}
    assert a.node.formation.ticks == () and not a.node._paths
    ctl(s, "path", vehicle=ME, path={"family": "circle", "center": [0, 0, 3], "radius": 1}, tick=1)
    a.drain()
    assert len(a.node._paths) == 1  # a boat on a 3-D path follows its x, y, as in the config


_FIXTURE = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
_VALUES = st.one_of(st.floats(), st.integers(-2**63, 2**64 - 1), st.booleans(), st.text(max_size=4), st.none(),
                    st.lists(st.floats(), max_size=3), st.dictionaries(st.text(max_size=3), st.floats(), max_size=2))


@_FIXTURE
@given(data=st.data())
def test_hostile_formation_and_path_fields_never_raise_and_every_reject_is_counted(fake, data):
    a, s, lines = fake()
    applied = 0
    for _ in range(data.draw(st.integers(1, 8))):
        if data.draw(st.booleans()):
            phases = data.draw(st.dictionaries(st.sampled_from(["usv1", "usv2", "uav3", "x", "\x1b[31m"]), _VALUES,
                                               max_size=4))
            fields = {"phases": phases, "tick": data.draw(st.one_of(st.integers(-5, 2**33), _VALUES))}
            op = "formation"
        else:
            table = data.draw(st.dictionaries(st.sampled_from(["family", "center", "radius", "speed", "beta", "zz"]),
                                              st.one_of(_VALUES, st.sampled_from(["circle", "line"])), max_size=5))
            fields = {"vehicle": data.draw(st.sampled_from([ME, "usv2", ""])), "path": table,
                      "tick": data.draw(st.one_of(st.integers(-5, 2**33), _VALUES))}
            op = "path"
        before = sum(a.rejected.values())
        n_paths, n_formation = len(a.node._paths), len(a.node.formation.ticks)
        try:
            payload = encode_control(op, **fields)
        except (OverflowError, TypeError, ValueError):
            continue
        a.feed(keys.ctl(FLEET, [ME]), payload, None)
        took = len(a.node._paths) > n_paths or len(a.node.formation.ticks) > n_formation
        assert took != (sum(a.rejected.values()) == before + 1)  # taken, or counted once
        applied += took
        if took and op == "formation":
            assert all(math.isfinite(x) for x in a.node.formation.phases_at(2**31))
    assert set(a.rejected) <= REASONS, a.rejected
    assert all("\x1b" not in ln for ln in lines)

"""Attacks on the world's command handling as a ground station can make them (rev-gs): faults
put without a query, fuzzed formation/path/radio commands, forged replies. No network: the
world's fakes of tests/world_sim."""

from __future__ import annotations

from cdus.wire import keys
from cdus.wire.messages import LAUNCHER_OPS, decode_control, encode_control
from tests.world_sim.test_world import FLEET, world
from tests.world_sim.test_commands import ask, launcher_done


def _put(w, op: str, **fields) -> None:
    """A command put on to/+world+/cmd/gs (the ground role may: older clients put without asking)."""
    w.feed(keys.world_cmd(FLEET, keys.GROUND), encode_control(op, **fields))


def test_realtime_a_put_faults_word_from_the_launcher_does_not_answer_a_later_query():
    """A ground station's kill of usv2 put (no answer asked) then another's restart of usv2 asked:
    the launcher's fault_done for the kill answered the restart 'applied' before the launcher
    had restarted anything (the put fault held no place in the per-vehicle queue)."""
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    _put(w, "kill", vehicle="usv2")
    q = ask(w, "restart", vehicle="usv2")
    assert [decode_control(p, LAUNCHER_OPS).op for p in w.pub_launcher.puts] == ["kill", "restart"]
    launcher_done(w, "usv2")  # the kill
    assert q.answer is None
    launcher_done(w, "usv2")  # the restart
    assert q.answer is not None and q.answer.applied and q.answer.op == "restart"
    assert not any(w.clock.asked.values())


import math  # noqa: E402

import msgpack  # noqa: E402
from hypothesis import given, settings, strategies as hs  # noqa: E402

from tests.world_sim.test_world import started  # noqa: E402

_atoms = (hs.none() | hs.booleans() | hs.integers(-2**63, 2**64 - 1) | hs.floats() | hs.text(max_size=12)
          | hs.sampled_from(["usv1", "usv2", "usv3", "uav1", "uav2", "uav3", "circle", "lissajous", "ellipse",
                             "line", "figure8"]))
_values = hs.recursive(_atoms, lambda c: hs.lists(c, max_size=4) | hs.dictionaries(
    hs.sampled_from(["usv1", "usv2", "uav1", "i", "k", "delta", "family", "center", "radius", "speed", "a", "b",
                     "x", "y", "z", "freq", "phase", "tx_power", "station"]) | hs.text(max_size=6), c, max_size=5),
                       max_leaves=16)
_fields = hs.dictionaries(hs.sampled_from(["phases", "offsets", "vehicle", "path", "radio", "at", "gains", "link"]),
                          _values, max_size=4)


@settings(max_examples=400, deadline=None)
@given(op=hs.sampled_from(["formation", "path", "radio", "set_gains", "link"]), fields=_fields,
       clock=hs.sampled_from(["lockstep", "realtime"]))
def test_fuzzed_changes_are_answered_once_and_never_an_internal_error(op, fields, clock):
    """Every formation, path, radio, gains or link command, whatever its fields, is answered
    once, applied or rejected with a reason, and none is a bug of the world's (``internal``)."""
    w = world(clock=clock)
    if clock == "lockstep":
        started(w)
    else:
        for vid in w.ids:
            w.alive(vid, True)
    q = w.ask(keys.world_command(FLEET, keys.GROUND), msgpack.packb({"v": 1, "op": op, **fields}))
    r = q.answer
    assert r is not None
    assert w.st.rejects["internal"] == 0, r.reason
    if r.applied:
        assert r.tick is not None and r.tick >= 0 and r.t is not None and math.isfinite(r.t)
    else:
        assert r.reason


_ids = hs.sampled_from(["usv1", "usv2", "usv3", "uav1", "uav2", "uav3", "usv9", ""])
_num = hs.floats() | hs.integers(-2**63, 2**63 - 1) | hs.sampled_from([0.0, -0.0, 1e-300, 1e300, 1e9, -1e9])
_vec = hs.lists(_num, min_size=0, max_size=4)
_path = hs.fixed_dictionaries({"family": hs.sampled_from(["circle", "lissajous", "ellipse", "line", "figure8",
                                                           "spiral", ""])},
                              optional={"center": _vec | _num, "radius": _num, "speed": _num, "a": _num | _vec,
                                        "b": _num | _vec, "freq": _vec | _num, "phase": _vec | _num,
                                        "direction": _num, "axis": _vec, "amplitude": _vec | _num,
                                        "frequency": _vec | _num, "start": _vec, "end": _vec, "extra": _values})
_typed = hs.one_of(
    hs.tuples(hs.just("formation"), hs.fixed_dictionaries({
        "phases": hs.dictionaries(_ids, _num | _values, max_size=7),
        "offsets": hs.lists(hs.fixed_dictionaries({"i": _ids | _values, "k": _ids | _values, "delta": _num | _values}),
                            max_size=8)})),
    hs.tuples(hs.just("path"), hs.fixed_dictionaries({"vehicle": _ids, "path": _path})),
    hs.tuples(hs.just("radio"), hs.fixed_dictionaries({"radio": hs.dictionaries(
        hs.sampled_from(["tx_power", "station", "x"]), _num | _vec | _values, max_size=3), "at": _num})),
    hs.tuples(hs.just("set_gains"), hs.fixed_dictionaries({"vehicle": _ids, "gains": hs.dictionaries(
        hs.sampled_from(["k", "c", "x"]), _num | _vec, max_size=3)})),
)


@settings(max_examples=500, deadline=None)
@given(cmd=_typed, clock=hs.sampled_from(["lockstep", "realtime"]))
def test_well_typed_fuzzed_changes_are_answered_and_never_an_internal_error(cmd, clock):
    test_fuzzed_changes_are_answered_once_and_never_an_internal_error.hypothesis.inner_test(cmd[0], cmd[1], clock)


def test_a_change_asked_when_the_run_has_no_tick_left_for_it_is_rejected_not_applied():
    """In the run's last 0.25 s the grant has reached its last tick (lockstep; realtime: the last
    0.5 s): a formation, path, gains or link command was answered 'applied from tick 12501 (t =
    250.02 s)' in a run whose last tick is 12500, and never applied (`cdus gs` exited 0)."""
    w = started(world())
    w.lockstep.granted = w.last_tick
    before = (len(w.session.puts), len(w.pub_ctl.puts), len(w._commands), dict(w._link_table))
    for op, fields in [("formation", {"phases": {"usv2": 1.0}, "offsets": []}),
                       ("path", {"vehicle": "usv1", "path": {"family": "circle", "center": [0, 0], "radius": 5}}),
                       ("set_gains", {"gains": {"c": 2.0}, "vehicle": ""}),
                       ("link", {"link": {"loss": 0.1}, "at": -1.0})]:
        r = ask(w, op, **fields).answer
        assert r.status == "rejected" and "would never apply" in r.reason and str(w.last_tick) in r.reason, (op, r)
    assert (len(w.session.puts), len(w.pub_ctl.puts), len(w._commands), dict(w._link_table)) == before
    assert w.st.rejects["formation"] == w.st.rejects["path"] == w.st.rejects["gains"] == w.st.rejects["link"] == 1
    assert not w.recorder.formation.ticks
    # one tick before the end still applies
    w2 = started(world())
    w2.lockstep.granted = w2.last_tick - 1
    r = ask(w2, "formation", phases={"usv2": 1.0}, offsets=[]).answer
    assert r.applied and r.tick == w2.last_tick


def test_realtime_a_change_past_the_last_tick_is_rejected():
    w = world(clock="realtime")
    for vid in w.ids:
        w.alive(vid, True)
    w.clock.tick_now = lambda: w.last_tick - 2  # the wall clock's tick, the run's last 0.04 s
    for op, fields in [("formation", {"phases": {"usv2": 1.0}, "offsets": []}),
                       ("path", {"vehicle": "usv1", "path": {"family": "circle", "center": [0, 0], "radius": 5}}),
                       ("link", {"link": {"loss": 0.1}, "at": -1.0}),
                       ("set_gains", {"gains": {"c": 2.0}, "vehicle": ""})]:  # one effect tick for all
        r = ask(w, op, **fields).answer
        assert r.status == "rejected" and "would never apply" in r.reason, (op, r)

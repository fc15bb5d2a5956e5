"""The console's alarms (ground_station.alarms), from status sequences alone: no terminal."""

from __future__ import annotations

from hypothesis import given, settings, strategies as hs

from cdus.wire.status import StatusExtra, WorldStatus, decode_status, encode_status
from ground_station.alarms import NO_RADIUS, Alarms

IDS = ["usv1", "usv2", "usv3"]
RING = [("usv1", "usv2", 0.01), ("usv2", "usv3", 0.01), ("usv1", "usv3", 0.01)]


def status(t: float, states=("live",) * 3, edges=RING, path_errors=(0.01,) * 3, radius=2.0, closest=None,
           alive=None, directed=False) -> WorldStatus:
    """A status as the console gets it: encoded by the world's encoder, decoded by decode_status
    (``states`` None: a world whose status has no roster states)."""
    extra = StatusExtra(states=None if states is None else list(states), edges=list(edges),
                        path_errors=None if path_errors is None else list(path_errors), safety_radius=radius,
                        closest=closest, directed=directed)
    if alive is None:
        alive = [v for v, s in zip(IDS, states) if s != "gone"]
    st = decode_status(encode_status(t, 100.0, "lockstep", alive, IDS, None, None, [], False, extra=extra))
    assert isinstance(st, WorldStatus), st
    return st


def kinds(changes) -> list[tuple[bool, str, str]]:
    return [(c.raised, c.alarm.kind, c.alarm.subject) for c in changes]


def test_a_lost_vehicle_is_raised_once_with_its_time_and_cleared_when_it_is_back():
    a = Alarms()
    assert a.update(status(1.0)) == []
    ch = a.update(status(2.0, states=("live", "gone", "live")))
    assert kinds(ch) == [(True, "vehicle_lost", "usv2")] and ch[0].t == 2.0 and "usv2 lost" in ch[0].line()
    assert a.update(status(3.0, states=("live", "gone", "live"))) == []  # once
    ch = a.update(status(4.0))
    assert kinds(ch) == [(False, "vehicle_lost", "usv2")] and ch[0].t == 4.0 and "cleared" in ch[0].line()
    assert not a.active


def test_a_lost_vehicle_is_stamped_with_when_it_was_last_heard_of_when_that_is_known():
    a = Alarms()
    ch = a.update(status(9.0, states=("live", "gone", "live")), last_heard={"usv2": 7.25, "usv1": 9.0})
    assert kinds(ch) == [(True, "vehicle_lost", "usv2")] and ch[0].t == 7.25 and ch[0].alarm.t == 7.25
    assert ch[0].line().startswith("t = 7.25 s ALARM")
    b = Alarms()  # a time after the status's is not taken
    assert b.update(status(9.0, states=("live", "gone", "live")), last_heard={"usv2": 12.0})[0].t == 9.0


def test_without_roster_states_a_vehicle_not_alive_is_lost():
    a = Alarms()
    ch = a.update(status(1.0, states=None, alive=["usv1", "usv3"]))
    assert kinds(ch) == [(True, "vehicle_lost", "usv2")]


def test_a_graph_cut_in_two_has_no_spanning_tree_until_it_is_whole_again():
    a = Alarms()
    chain = [("usv1", "usv2", 0.0), ("usv2", "usv3", 0.0)]  # usv1 - usv2 - usv3
    ch = a.update(status(1.0, states=("live", "gone", "live"), edges=chain))
    assert kinds(ch) == [(True, "vehicle_lost", "usv2"), (True, "no_spanning_tree", "")]
    assert "usv3 cut off" in ch[1].alarm.text or "usv1 cut off" in ch[1].alarm.text
    ch = a.update(status(2.0, edges=chain))
    assert sorted(kinds(ch)) == [(False, "no_spanning_tree", ""), (False, "vehicle_lost", "usv2")]
    # the ring survives losing one vehicle
    b = Alarms()
    assert kinds(b.update(status(1.0, states=("live", "gone", "live")))) == [(True, "vehicle_lost", "usv2")]


def test_a_directed_graph_is_read_in_its_direction():
    a = Alarms()
    # usv2 and usv3 both listen to usv1 (pairs i listens to k: (usv2, usv1), (usv3, usv1)): a tree rooted at usv1
    star = [("usv2", "usv1", 0.0), ("usv3", "usv1", 0.0)]
    assert a.update(status(1.0, edges=star, directed=True)) == []
    # usv1 listens to nobody and nobody reaches usv2 from usv3: two roots, no spanning tree
    split = [("usv2", "usv1", 0.0), ("usv2", "usv3", 0.0)]
    assert kinds(a.update(status(2.0, edges=split, directed=True))) == [(True, "no_spanning_tree", "")]


def test_an_error_growing_for_several_seconds_is_raised_once_and_cleared_when_it_shrinks():
    a = Alarms(grow_s=3.0)
    out = []
    for t, e in [(0, 0.01), (1, 0.05), (2, 0.1), (3, 0.2), (4, 0.3), (5, 0.4), (6, 0.1)]:
        out += [(t, *k) for k in kinds(a.update(status(float(t), edges=[("usv1", "usv2", e), *RING[1:]])))]
    assert out == [(3, True, "error_growing", "edge usv1-usv2"), (6, False, "error_growing", "edge usv1-usv2")]


def test_growth_needs_time_a_real_rise_and_advancing_statuses():
    a = Alarms(grow_s=3.0)
    # grows for 2 s only, then falls: nothing
    for t, e in [(0, 0.1), (1, 0.5), (2, 1.0), (3, 0.2)]:
        assert a.update(status(float(t), path_errors=(e, 0.01, 0.01))) == []
    # a tiny wobble that grows for long is not an alarm (below the floor)
    b = Alarms(grow_s=3.0)
    for t in range(10):
        assert b.update(status(float(t), path_errors=(0.001 * (t + 1), 0.01, 0.01))) == []
    # the same status read again at later times (the console's clock ahead of the status) is no news
    e = Alarms(grow_s=3.0)
    out = []
    for t, x in [(0, 0.1), (0.5, 0.1), (1, 0.2), (1.5, 0.2), (2, 0.4), (2.5, 0.4), (3, 0.8), (3.5, 0.8)]:
        out += [(t, *k) for k in kinds(e.update(status(float(t), path_errors=(x, 0.01, 0.01))))]
    assert out == [(3, True, "error_growing", "|Φ| usv1")]
    # a paused fleet (time standing still) changes nothing, however often it is said
    c = Alarms(grow_s=3.0)
    for _ in range(10):
        assert c.update(status(5.0, path_errors=(1.0, 0.01, 0.01))) == []
    # a vehicle that is not live is not measured, and its growth starts over when it is back
    d = Alarms(grow_s=3.0)
    d.update(status(0.0, path_errors=(0.1, 0.01, 0.01)))
    d.update(status(1.0, path_errors=(0.2, 0.01, 0.01)))
    d.update(status(2.0, states=("paused", "live", "live"), path_errors=(None, 0.01, 0.01)))
    assert d.update(status(3.0, path_errors=(0.4, 0.01, 0.01))) == []
    assert d.update(status(4.0, path_errors=(0.8, 0.01, 0.01))) == []


def test_separation_below_the_safety_radius_and_a_status_that_cannot_say():
    a = Alarms()
    ch = a.update(status(1.0, closest=("usv1", "usv3", 1.5)))
    assert kinds(ch) == [(True, "separation", "")] and "usv1 and usv3 1.50 m apart" in ch[0].alarm.text
    assert kinds(a.update(status(2.0, closest=("usv1", "usv3", 2.5)))) == [(False, "separation", "")]
    assert a.notes == []
    b = Alarms()
    assert b.update(status(1.0, closest=("usv1", "usv3", 0.5), radius=None)) == []
    assert b.notes == [NO_RADIUS]


_state = hs.sampled_from(["live", "paused", "gone"])
_err = hs.one_of(hs.none(), hs.floats(min_value=0, max_value=1e9), hs.floats())
_status = hs.fixed_dictionaries({
    "t": hs.floats(min_value=0, max_value=100),
    "states": hs.lists(_state, min_size=3, max_size=3),
    "edges": hs.lists(hs.tuples(hs.sampled_from(IDS), hs.sampled_from(IDS), _err), max_size=4),
    "path_errors": hs.one_of(hs.lists(_err, min_size=3, max_size=3), hs.none()),
    "radius": hs.one_of(hs.none(), hs.floats(min_value=0.1, max_value=10)),
    "closest": hs.one_of(hs.none(), hs.tuples(hs.sampled_from(IDS), hs.sampled_from(IDS), _err)),
    "directed": hs.booleans(),
    # the console's newest telemetry times (finite floats: ground_station.tui.snapshot keeps no other)
    "last_heard": hs.dictionaries(hs.sampled_from(IDS), hs.floats(min_value=0, max_value=200)),
})


def _decoded(s: dict) -> WorldStatus | None:
    """The status the world would send with these values, as decode_status gives it to the
    console, or None where the decoder refuses it (a bad value never reaches the alarms)."""
    extra = StatusExtra(states=list(s["states"]), edges=list(s["edges"]), path_errors=s["path_errors"],
                        safety_radius=s["radius"], closest=s["closest"], directed=s["directed"])
    alive = [v for v, x in zip(IDS, s["states"]) if x != "gone"]
    st = decode_status(encode_status(s["t"], 100.0, "lockstep", alive, IDS, None, None, [], False, extra=extra))
    return st if isinstance(st, WorldStatus) else None


@settings(max_examples=300, deadline=None)
@given(hs.lists(_status, max_size=25))
def test_any_status_sequence_raises_and_clears_consistently(seq):
    a = Alarms(grow_s=2.0)
    active: set = set()
    for s in seq:
        st = _decoded(s)
        if st is None:
            continue
        for ch in a.update(st, s["last_heard"]):
            key = ch.alarm.key
            if ch.raised:
                assert key not in active  # raised once
                active.add(key)
            else:
                assert key in active  # only what was raised is cleared
                active.remove(key)
            assert ch.t == st.t or ch.raised and ch.alarm.kind == "vehicle_lost" and ch.t < st.t
        assert active == set(a.active)
        lost = {(k, v) for k, v in active if k == "vehicle_lost"}
        if isinstance(s["t"], float):
            assert lost == {("vehicle_lost", v) for v, x in zip(IDS, s["states"]) if x == "gone"}

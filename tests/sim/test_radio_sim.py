"""The radio in the runners without processes: the lockstep grants wait for the geometry
sample, the watch reports splits and rejoins, range_out splits and re-converges, and a run-time
radio change changes delivery from its time on."""

from __future__ import annotations

import numpy as np
import pytest

from cdus.core.radio import RadioChannel, RadioSpec
from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from cdus.sim.lockstep import Grant, Lockstep, RadioSample
from cdus.sim.radio import RadioWatch, radio_change_problem
from cdus.wire.messages import GeometryMsg

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_lockstep_grants_no_further_than_the_radio_sample_allows():
    ls = Lockstep(["a", "b"], 0.05, 100, radio_every=4, radio_lag=4)
    ls.start()
    assert [a for a in ls.poll() if isinstance(a, Grant)] == [Grant(0)]  # sample 0 is needed from tick 1
    ls.on_report(0, 0)
    assert not [a for a in ls.poll() if isinstance(a, RadioSample)]  # b has not reported tick 0
    ls.on_report(1, 0)
    out = ls.poll()
    assert RadioSample(0) in out and Grant(8) in out  # next sample 4, in force from 8: tick 9 needs it
    assert out.index(RadioSample(0)) < out.index(Grant(8))
    for n in range(1, 5):
        ls.on_report(0, n)
        ls.on_report(1, n)
    out = ls.poll()
    assert RadioSample(4) in out and ls.granted == 12
    # without [radio], nothing changes
    plain = Lockstep(["a", "b"], 0.05, 100)
    plain.start()
    assert [a for a in plain.poll() if isinstance(a, Grant)] == [Grant(99)]  # the horizon: the last tick


def _watch(hold=0.6):
    spec = RadioSpec(shadowing_sigma=0.0, tx_power=0.0, propagation="log_distance", exponent=3.0)
    ch = RadioChannel(spec, ["a", "b", "c"], ["uav"] * 3, 1, rate=10.0, tick_period=0.1)
    return RadioWatch(["a", "b", "c"], [("a", "b"), ("b", "c"), ("c", "a"), ("b", "a"), ("c", "b"), ("a", "c")],
                      ch, 0.1, hold=hold)


def _sample(tick, x_c):
    return GeometryMsg(tick, ((0.0, 0.0, 10.0), (10.0, 0.0, 10.0), (x_c, 0.0, 10.0)))


def test_the_watch_reports_a_split_and_a_rejoin_once_each_held():
    w = _watch()
    assert w.observe(_sample(0, 20.0)) == [] and w.whole
    assert w.links[("a", "b")] > 0.99
    far, near = 5000.0, 20.0
    assert w.observe(_sample(2, far)) == []  # not held 0.6 s yet
    assert w.observe(_sample(4, near)) == []  # back before: nothing to say
    assert [w.observe(_sample(k, far)) for k in (6, 8, 10)] == [[], [], []]  # 0.4 s < hold
    (split,) = w.observe(_sample(12, far))  # held 0.6 s: reported, stamped at its first sample
    assert split.kind == "radio_split" and split.t == pytest.approx(0.6) and "c cut off" in split.text
    assert w.splits == 1 and not w.whole
    events = [w.observe(_sample(k, near)) for k in (14, 16, 18, 20)]
    joined = [e for es in events for e in es]
    assert [e.kind for e in joined] == ["radio_joined"] and joined[0].t == pytest.approx(1.4)
    assert w.links[("c", "a")] > 0.99 and w.summary()["samples"] == 11


def test_a_fleet_split_from_the_start_says_so_at_once():
    w = _watch()
    (e,) = w.observe(_sample(0, 5000.0))
    assert e.kind == "radio_split" and e.t == 0.0 and "c cut off" in e.text


def test_range_out_reports_the_split_and_re_converges_after_the_return():
    """configs/range_out.toml in process: the drones leave the station's range at about 19 s
    and are back at about 84 s; meanwhile the wind pushes the formation far off (more than
    the tolerance), and after the return it settles within it to the end."""
    sc = load_scenario("configs/range_out.toml")
    r = InProcessFleet(sc).run()
    m = r.metrics
    radio = [(e.t, e.kind) for e in m.events if e.kind.startswith("radio_")]
    assert [k for _, k in radio] == ["radio_split", "radio_joined"]
    (t_split, _), (t_back, _) = radio
    assert 15.0 < t_split < 25.0 and 75.0 < t_back < 95.0
    assert m.radio.splits == 1 and m.radio.dropped_by["range"] > 1000
    _, coord = r.recorder.worst_errors()
    t = r.recorder.view("t")
    tol = sc.coord_tol
    assert coord[(t > t_split) & (t < t_back)].max() > 1.5 * tol  # the outage pushed it far off
    assert m.coord_settle_s is not None and t_split < m.coord_settle_s < t_back + 10.0
    assert coord[t > t_back + 10.0].max() < 0.7 * tol  # and it holds, with a margin, to the end
    assert m.final_coord_error_max < 0.7 * tol
    from cdus.app.report import summary_table
    from cdus.results import Metrics

    # the end-of-run summary says when it was split, not only how many times
    assert f"1 graph split(s): {t_split:.1f}-{t_back:.1f} s" in summary_table(m, sc.vehicles)


def test_the_summary_gives_each_split_interval_and_one_still_open_at_the_end():
    from cdus.app.report import MAX_SPANS, split_spans
    from cdus.results import Event

    def ev(t, kind):
        return Event(t, kind, "", "info")

    assert split_spans([]) == "" and split_spans([ev(3.0, "fleet")]) == ""
    assert split_spans([ev(1.0, "radio_split"), ev(2.5, "kill"), ev(4.04, "radio_joined"),
                        ev(9.0, "radio_split")]) == "1.0-4.0 s, from 9.0 s, still split at the end"
    many = [ev(t + dt, k) for t in range(0, 40, 2) for dt, k in ((0.0, "radio_split"), (1.0, "radio_joined"))]
    assert split_spans(many) == "0.0-1.0 s, 2.0-3.0 s, 4.0-5.0 s, 6.0-7.0 s, and 16 more" and MAX_SPANS == 4
    # a damaged file's events never reach it: the metrics are refused where they are read, naming the field
    from cdus.results import Metrics
    from cdus.wire.rejected import Rejected

    m = InProcessFleet(load_scenario("configs/lake_circle.toml", {"scenario.duration": 0.2})).run().metrics.to_dict()
    bad = Metrics.from_json({**m, "events": [{"t": "x", "kind": "radio_split", "text": "", "severity": "info"}]})
    assert isinstance(bad, Rejected) and bad.field == "events[0].t"


def test_a_radio_change_changes_delivery_from_its_time_on():
    """lake_radio at -30 dBm from t = 2 s: the shore station no longer hears the boats; every
    message sent before 2 s is decided as before (the run up to 2 s is the same to the bit)."""
    sc = load_scenario("configs/lake_radio.toml", {"scenario.duration": 4.0})
    base = InProcessFleet(sc)
    ref = base.run()
    weak = InProcessFleet(sc)
    weak.set_radio({"tx_power": -30.0}, 2.0)
    run = weak.run()
    n = round(2.0 * sc.rates.control)  # tick 100 decides what tick 99 sent (t < 2 s): unchanged
    for name in ("q", "omega"):
        assert np.array_equal(ref.recorder.view(name)[: n + 1], run.recorder.view(name)[: n + 1])
        assert not np.array_equal(ref.recorder.view(name), run.recorder.view(name))
    before, after = ref.metrics.radio, run.metrics.radio
    assert before.dropped_by["range"] == 0 and after.dropped_by["range"] > 0.4 * after.sent
    with pytest.raises(ValueError):
        weak.set_radio({"tx_power": "loud"}, 3.0)
    assert radio_change_problem({"station": [1.0, 2.0]}) is None
    assert radio_change_problem({"station": [1.0, 2.0]}, "station") is None
    assert "ad hoc" in radio_change_problem({"station": [1.0, 2.0]}, "adhoc")
    assert radio_change_problem({"tx_power": 3.0}, "adhoc") is None
    adhoc = InProcessFleet(load_scenario("configs/lake_radio.toml", {"scenario.duration": 1.0,
                                                                      "radio.topology": "adhoc"}))
    with pytest.raises(ValueError, match="ad hoc"):
        adhoc.set_radio({"station": [0.0, -500.0]}, 0.5)
    assert "tx_power" in radio_change_problem({"tx_power": 1e6})


def test_the_metrics_radio_block_is_typed_in_the_api_and_printed():
    """The run builds the radio block as RadioMetrics; its JSON reads back equal; the end-of-run
    table prints it."""
    from cdus.api import Metrics, RadioMetrics
    from cdus.app.report import summary_table

    sc = load_scenario("configs/lake_radio.toml", {"scenario.duration": 1.0})
    m = InProcessFleet(sc).run().metrics
    assert isinstance(m.radio, RadioMetrics) and "radio" not in m.extra
    assert m.radio.utilisation.samples == 6 and m.radio.dropped_by["collision"] >= 0
    d = m.to_dict()
    assert Metrics.from_dict(d) == m and "utilisation" in d["radio"]
    table = summary_table(m, sc.vehicles)
    assert "radio:" in table and "channel utilisation mean 0.107" in table
    with pytest.raises(ValueError, match="radio.utilisation"):
        Metrics.from_dict({**d, "radio": {**d["radio"], "utilisation": 3}})
    plain = InProcessFleet(load_scenario("configs/lake_circle.toml", {"scenario.duration": 0.2})).run().metrics
    assert "radio" not in plain.to_dict() and plain.radio is None
    assert "radio:" not in summary_table(plain, sc.vehicles)


RADIO_EVENT = """
[[event]]
at = 2.0
action = "radio"
tx_power = -30.0
"""


def test_a_scheduled_radio_event_is_the_same_change_as_a_ground_stations(tmp_path):
    """[[event]] action = "radio" at 2 s gives the run that set_radio (the path of a ground
    station's command) gives, to the bit; it is checked like the command."""
    from cdus.core.radiolink import RadioEvent
    from cdus.scenario.config import ConfigError

    base = (ROOT / "configs/lake_radio.toml").read_text()
    cfg = tmp_path / "ev.toml"
    cfg.write_text(base + RADIO_EVENT)
    sc = load_scenario(cfg, {"scenario.duration": 3.0})
    assert sc.radio_events == (RadioEvent(2.0, -30.0, None),) and sc.events == ()
    scheduled = InProcessFleet(sc).run()
    plain = load_scenario("configs/lake_radio.toml", {"scenario.duration": 3.0})
    commanded = InProcessFleet(plain)
    commanded.set_radio({"tx_power": -30.0}, 2.0)
    ref = commanded.run()
    assert np.array_equal(scheduled.recorder.view("q"), ref.recorder.view("q"))
    assert scheduled.metrics.radio == ref.metrics.radio and ref.metrics.radio.dropped_by["range"] > 0
    # the run says so, at the tick it applies from (a ground station's change is reported by the world)
    assert [(e.t, e.text) for e in scheduled.metrics.events if e.kind == "radio_changed"] == [
        (2.0, "radio: tx_power = -30 dBm from tick 100 (t = 2 s) (scheduled)")]
    for bad, field in [("tx_power = 900.0", "event[0].tx_power"), ('station = "x"', "event[0].station"),
                       ("vehicle = \"usv1\"", "event[0].vehicle")]:
        cfg.write_text(base + '\n[[event]]\nat = 2.0\naction = "radio"\n' + bad + "\n")
        with pytest.raises(ConfigError, match=field.replace("[", r"\[").replace("]", r"\]")):
            load_scenario(cfg)
    cfg.write_text(base.replace('topology = "station"', 'topology = "adhoc"')
                   + '\n[[event]]\nat = 2.0\naction = "radio"\nstation = [0.0, -500.0]\n')
    with pytest.raises(ConfigError, match=r"event\[0\]\.station: .*\"adhoc\": no station"):
        load_scenario(cfg)
    cfg.write_text((ROOT / "configs/lake_circle.toml").read_text() + RADIO_EVENT)
    with pytest.raises(ConfigError, match=r"event\[0\]\.action: a radio event needs a \[radio\] table"):
        load_scenario(cfg)


def test_the_sample_the_runners_send_is_one_every_vehicle_takes():
    """Whatever the positions (telemetry a vehicle sent about itself: not finite, beyond 10,000 km,
    of the wrong dimension), the world's sample decodes at every vehicle: a position they would
    refuse is sent as not live (None). A refused sample held a lockstep fleet at tick 1 forever
    (range_out with its circle's centre at 2e7 m: `radio_range` at every agent) while `cdus sim`
    dropped every sample and let every message through (`no_geometry`)."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from cdus.sim.radio import geometry_sample
    from cdus.wire.messages import MAX_COORDINATE, decode_geometry, encode_geometry

    dims = [2, 3, 3, 2]
    coord = st.floats(allow_nan=True, allow_infinity=True) | st.sampled_from([1e7, -1e7, 1.0000001e7, 1e308])

    @settings(max_examples=300, deadline=None)
    @given(rows=st.dictionaries(st.integers(0, 3), st.lists(coord, min_size=2, max_size=3)), tick=st.integers(0, 99))
    def check(rows, tick):
        msg = geometry_sample(tick, rows, 4, dims)
        back = decode_geometry(encode_geometry(msg), 4, dims)
        assert back == msg
        for j in range(4):
            q = rows.get(j)
            fits = q is not None and len(q) == dims[j] and all(abs(x) <= MAX_COORDINATE for x in q)  # nan: False
            assert (msg.positions[j] is not None) == fits

    check()


def test_a_fleet_beyond_the_geometry_bounds_is_out_of_range_not_unradioed():
    # a path is within ±1e6 m (cdus.wire.bounds), so the drones fly out past the geometry bound
    # (1e7 m): a line from 900 km out at 1,000 km/s, 12 s
    line = {"family": "line", "origin": [-9e5, 0.0, 30.0], "heading": [1.0, 0.0, 0.0], "speed": 1e6}
    sc = load_scenario("configs/range_out.toml", {"scenario.duration": 12.0, "rates.control": 10.0,
                                                  "rates.broadcast": 10.0, **{
        f"vehicle.{v}.{key}": value for v in ("uav1", "uav2", "uav3", "uav4")
        for key, value in (("path", line), ("phase", 0.0))}})
    run = InProcessFleet(sc).run()
    assert abs(run.recorder.q[:run.recorder._n]).max() > 1e7  # they got out there
    radio = run.metrics.radio
    assert radio.sent > 0 and radio.no_geometry == 0
    assert radio.dropped_by["range"] == radio.sent  # nobody is heard out there

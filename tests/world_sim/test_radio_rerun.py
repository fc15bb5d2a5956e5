"""The radio in Rerun: each link at each geometry sample, coloured by its delivery probability,
the station, the channel utilisation as a time series; nothing of it without [radio]."""

from __future__ import annotations

import numpy as np

from cdus.scenario.config import load_scenario
from cdus.sim.fleet import InProcessFleet
from world_sim import blueprint as bp
from world_sim.sinks import make_sink
from world_sim.rerun_sink import probability_colour

from .test_recording import ROOT, Recording


def _record(tmp_path, config, duration):
    path = tmp_path / "run.rrd"
    sc = load_scenario(ROOT / config, {"scenario.duration": duration})
    sink = make_sink(f"save:{path}")
    res = InProcessFleet(sc, sink=sink).run()
    sink.close()
    return sc, res, Recording(path)


def test_probability_colours_run_from_red_through_yellow_to_green():
    assert probability_colour(0.0) == (220, 0, 40)
    assert probability_colour(0.5) == (220, 200, 40)
    assert probability_colour(1.0) == (0, 200, 40)
    assert probability_colour(7.0) == probability_colour(1.0) and probability_colour(-1.0) == probability_colour(0.0)


def test_the_radio_is_drawn_at_every_geometry_sample(tmp_path):
    sc, res, rec = _record(tmp_path, "configs/lake_radio.toml", 2.0)
    samples = res.metrics.radio.utilisation.samples
    assert samples == 11  # every 0.2 s over 2 s
    times, strips = rec.column(bp.RADIO_LINKS, "LineStrips3D:strips")
    assert len(times) == samples and times[1] == 200_000_000
    assert all(len(s) == 12 for s in strips)  # the ring of six, both directions
    _, colours = rec.column(bp.RADIO_LINKS, "LineStrips3D:colors")
    assert all(len(c) == 12 for c in colours)
    _, station = rec.column(bp.RADIO_STATION, "Points3D:positions")
    assert np.allclose(station[0], [[0.0, 0.0, 0.0]])
    _, u = rec.column(bp.UTILISATION, "Scalars:scalars")
    assert np.allclose(np.ravel(u), res.metrics.radio.utilisation.mean)
    assert bp.UTILISATION in rec.static


def test_cdus_sim_printing_its_events_still_draws_the_radio(tmp_path, capsys):
    """`cdus sim` (events printed as they happen) wraps the Rerun sink in a printing one; the
    radio's samples must still reach the recording (they did only with -q)."""
    import cdus

    path = tmp_path / "run.rrd"
    sc = load_scenario(ROOT / "configs/lake_radio.toml", {"scenario.duration": 1.0})
    res = cdus.run(sc, rerun=f"save:{path}", events=True)
    samples = res.metrics.radio.utilisation.samples
    rec = Recording(path)
    times, _ = rec.column(bp.RADIO_LINKS, "LineStrips3D:strips")
    assert samples > 0 and len(times) == samples
    assert len(rec.column(bp.RADIO_STATION, "Points3D:positions")[0]) == samples
    assert len(rec.column(bp.UTILISATION, "Scalars:scalars")[0]) == samples


def test_nothing_of_the_radio_without_it(tmp_path):
    _, _, rec = _record(tmp_path, "configs/lake_circle.toml", 1.0)
    assert not rec.rows(bp.RADIO_LINKS) and not rec.rows(bp.UTILISATION) and bp.UTILISATION not in rec.static


def _radio_world(clock="lockstep"):
    from cdus.scenario.config import load_scenario as load
    from cdus.wire.transport import Transport
    from world_sim.world import World

    from .test_world import FLEET, Pub, Session

    w = World(load(ROOT / "configs/lake_radio.toml"), FLEET, Transport(), clock=clock, log=lambda s: None)
    w.session = Session()
    w.pub_ctl, w.pub_launcher, w.pub_status, w.pub_events, w.pub_radio = Pub(), Pub(), Pub(), Pub(), Pub()
    w._wake = lambda payload=b"": None
    return w


def test_the_world_samples_the_geometry_once_a_tick_is_reported_and_grants_no_further():
    from cdus.wire.messages import decode_geometry

    from .test_world import row, send_rows, started

    w = started(_radio_world())
    assert w.lockstep.granted == 0  # sample 0 is needed from tick 1
    for j, vid in enumerate(w.ids[:-1]):
        send_rows(w, vid, [row(j, 0)])
    w.clock.act(w.lockstep.poll())
    assert w.pub_radio.puts == [] and w.lockstep.granted == 0  # uav3 has not reported tick 0
    send_rows(w, w.ids[-1], [row(5, 0)])
    w.clock.act(w.lockstep.poll())
    (payload,) = w.pub_radio.puts
    msg = decode_geometry(payload, 6)
    assert msg.tick == 0 and msg.positions[0] == (0.0, 0.0) and msg.positions[5] == (0.0, 0.0, 20.0)
    assert w.lockstep.granted == 20  # the next sample, 10, is in force from 20
    assert w.radio_watch.utilisation == [(0.0, w.radio_watch.utilisation[0][1])]


def test_the_world_relays_a_radio_change_or_says_why_not():
    from cdus.wire.messages import CTL_OPS, decode_control

    from .test_world import started, world

    w = started(_radio_world())
    assert "tx_power" in w.carry_out("radio", {"radio": {"tx_power": "loud"}, "at": -1.0}, "gs")
    assert "power" in w.carry_out("radio", {"radio": {"power": 3}, "at": -1.0}, "gs")
    v = w.carry_out("radio", {"radio": {"tx_power": 3.0, "station": [1.0, 2.0]}, "at": -1.0}, "gs")
    # the answer says when it applies: the effect tick, the one past the grant (it was 0.5 s on in lockstep)
    assert w.lockstep.granted == 0 and v.applied and (v.tick, v.t) == (1, w.period)
    (c,) = [decode_control(p, CTL_OPS) for p in w.pub_ctl.puts if decode_control(p, CTL_OPS).op == "radio"]
    assert c.fields["radio"] == {"tx_power": 3.0, "station": [1.0, 2.0, 0.0]} and c.fields["at"] >= 0.02
    assert w.radio_watch.channel.epochs[-1][1:] == (3.0, (1.0, 2.0, 0.0))
    assert [e.kind for e in w.events][-1] == "radio_changed"
    plain = started(world())
    assert "no [radio]" in plain.carry_out("radio", {"radio": {"tx_power": 3.0}, "at": -1.0}, "gs")


def test_a_radio_change_asked_for_a_time_already_past_says_it_was_moved_as_a_link_change_does():
    """`cdus gs radio tx_power=10 --at 5` at t = 21 s answered 'applied from tick 1079 (t = 21.58 s)'
    with no word that the 5 s asked had passed (`gs link ... --at 5` says so)."""
    from .test_world import started

    w = started(_radio_world())
    w.lockstep.granted = 100
    v = w.carry_out("radio", {"radio": {"tx_power": 3.0}, "at": 0.5}, "gs")
    assert v.applied and v.t > 0.5 and v.reason.startswith("t = 0.5 s asked had passed"), v
    assert w.carry_out("radio", {"radio": {"tx_power": 4.0}, "at": -1.0}, "gs").reason == ""  # no --at: nothing moved
    assert w.carry_out("radio", {"radio": {"tx_power": 5.0}, "at": 10.0}, "gs").reason == ""  # in the future: as asked


def test_a_radio_change_past_the_runs_end_is_refused_and_locks_nobody_out():
    """A change from a time past the run's end never applies; taken, it would have been the newest
    epoch, and every later change (epochs go in time order) refused: one command with --at 2e9
    (the agents refuse it too: past MAX_LINK_AT) locked the operator out of the radio."""
    from .test_world import started

    w = started(_radio_world())
    end = w.last_tick * w.period
    for at in (2e9, end + 1.0):
        out = w.carry_out("radio", {"radio": {"tx_power": 3.0}, "at": at}, "gs")
        assert isinstance(out, str) and ("past the run's end" in out and "--at" in out
                                         or "at: must be a finite number <= 1e+09" in out), out
    assert len(w.radio_watch.channel.epochs) == 1
    assert w.carry_out("radio", {"radio": {"tx_power": 10.0}, "at": end}, "gs").applied  # the last moment is fine
    w = started(_radio_world())
    w.carry_out("radio", {"radio": {"tx_power": 3.0}, "at": 2e9}, "gs")
    v = w.carry_out("radio", {"radio": {"tx_power": 10.0}, "at": -1.0}, "gs")
    assert not isinstance(v, str) and v.applied, v


def test_moving_the_station_of_an_adhoc_fleet_is_refused_naming_why(tmp_path):
    """An ad hoc radio has no station: `gs radio station=[...]` would be 'applied' and change
    nothing; it is refused, saying so, and tx_power alone still goes."""
    from cdus.scenario.config import load_scenario as load
    from cdus.wire.transport import Transport
    from world_sim.world import World

    from .test_world import FLEET, Pub, Session, started

    cfg = tmp_path / "adhoc.toml"
    cfg.write_text((ROOT / "configs/lake_radio.toml").read_text().replace('topology = "station"', 'topology = "adhoc"'))
    w = World(load(cfg), FLEET, Transport(), clock="lockstep", log=lambda s: None)
    w.session = Session()
    w.pub_ctl, w.pub_launcher, w.pub_status, w.pub_events, w.pub_radio = Pub(), Pub(), Pub(), Pub(), Pub()
    w._wake = lambda payload=b"": None
    started(w)
    epochs, ctl = tuple(w.radio_watch.channel.epochs), len(w.pub_ctl.puts)
    why = w.carry_out("radio", {"radio": {"tx_power": 3.0, "station": [0.0, -500.0]}, "at": -1.0}, "gs")
    assert isinstance(why, str) and "ad hoc" in why and "tx_power only" in why
    assert tuple(w.radio_watch.channel.epochs) == epochs and len(w.pub_ctl.puts) == ctl  # nothing relayed
    assert w.carry_out("radio", {"radio": {"tx_power": 3.0}, "at": -1.0}, "gs").applied


def test_hostile_radio_commands_never_raise_and_are_refused_or_relayed():
    """Any radio command a ground station can send (decoded by COMMAND_OPS: a table and a time)
    is relayed or refused with a reason and a `rejected` event; nothing escapes, and the world's
    channel only ever takes what it relays."""
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from cdus.wire import keys
    from cdus.wire.messages import encode_control

    from .test_world import FLEET, started

    values = st.none() | st.booleans() | st.floats() | st.integers(-2**63, 2**63) | st.text(max_size=5) \
        | st.lists(st.floats() | st.integers(-10**6, 10**6), max_size=4)
    tables = st.dictionaries(st.sampled_from(["tx_power", "station", "x", ""]) | st.text(max_size=4), values,
                             max_size=3)

    @settings(max_examples=200, deadline=None)
    @given(table=tables, at=st.floats(allow_nan=False, allow_infinity=False, min_value=-1e12, max_value=1e12))
    def check(table, at):
        w = started(_radio_world())
        before = len(w.radio_watch.channel.epochs)
        w.feed(keys.world_cmd(FLEET, "gs"), encode_control("radio", radio=table, at=at))
        relayed = [e for e in w.events if e.kind == "radio_changed"]
        refused = [e for e in w.events if e.kind == "rejected"]
        assert len(relayed) + len(refused) == 1
        assert len(w.radio_watch.channel.epochs) == before + len(relayed)
        assert w.st.rejects.get("internal", 0) == 0
        assert w.st.rejects.get("radio", 0) == len(refused)

    check()


def test_a_command_before_a_scheduled_radio_change_is_refused(tmp_path):
    from cdus.scenario.config import load_scenario as load
    from cdus.wire.transport import Transport
    from world_sim.world import World

    from .test_world import FLEET, Pub, Session, started

    cfg = tmp_path / "ev.toml"
    cfg.write_text((ROOT / "configs/lake_radio.toml").read_text()
                   + '\n[[event]]\nat = 100.0\naction = "radio"\ntx_power = 5.0\n')
    w = World(load(cfg), FLEET, Transport(), clock="lockstep", log=lambda s: None)
    w.session = Session()
    w.pub_ctl, w.pub_launcher, w.pub_status, w.pub_events, w.pub_radio = Pub(), Pub(), Pub(), Pub(), Pub()
    w._wake = lambda payload=b"": None
    started(w)
    assert w.radio_watch.channel.epochs[-1][:2] == (100.0, 5.0)  # the world's channel knows it up front
    assert "--at 100 or later" in w.carry_out("radio", {"radio": {"tx_power": 3.0}, "at": -1.0}, "gs")
    v = w.carry_out("radio", {"radio": {"tx_power": 3.0}, "at": 150.0}, "gs")
    assert v.applied and v.t == 150.0
    assert "--at 150 or later" in w.carry_out("radio", {"radio": {"tx_power": 9.0}, "at": 120.0}, "gs")


def test_a_scheduled_radio_change_past_the_runs_end_does_not_lock_the_ground_station_out(tmp_path):
    """lake_radio with a change scheduled at 100 s, run with --duration 30: the change never
    applies, and it refused every radio command of the run ("already in force later; give --at
    100 or later", then "past the run's end"). Every runner builds its channel without it."""
    from cdus.scenario.config import load_scenario as load
    from cdus.sim.build import radio_channel_for
    from cdus.wire.transport import Transport
    from world_sim.world import World

    from .test_world import FLEET, Pub, Session, started

    cfg = tmp_path / "ev.toml"
    cfg.write_text((ROOT / "configs/lake_radio.toml").read_text()
                   + '\n[[event]]\nat = 10.0\naction = "radio"\ntx_power = 5.0\n'
                   + '\n[[event]]\nat = 100.0\naction = "radio"\ntx_power = 7.0\n')
    sc = load(cfg, {"scenario.duration": 30.0})
    assert [e[:2] for e in radio_channel_for(sc).epochs][1:] == [(10.0, 5.0)]  # the one in the run stays
    w = World(sc, FLEET, Transport(), clock="lockstep", log=lambda s: None)
    w.session = Session()
    w.pub_ctl, w.pub_launcher, w.pub_status, w.pub_events, w.pub_radio = Pub(), Pub(), Pub(), Pub(), Pub()
    w._wake = lambda payload=b"": None
    started(w)
    v = w.carry_out("radio", {"radio": {"tx_power": 3.0}, "at": 20.0}, "gs")
    assert not isinstance(v, str) and v.applied and v.t == 20.0, v


def test_realtime_samples_once_every_live_vehicle_has_reported_and_never_past_the_end():
    import time

    from cdus.wire.messages import decode_geometry

    from .test_world import row

    w = _radio_world("realtime")
    w.st.alive = set(w.ids)
    w.clock.t0 = time.time() - 1.01  # tick 50 at 50 Hz
    w.clock.radio()
    assert w.pub_radio.puts == []  # nobody heard from yet: all would look out of range
    for j in range(5):
        w.st.latest[j] = row(j, 49)
    w.clock.radio()
    assert w.pub_radio.puts == []  # uav3 not yet
    w.st.latest[5] = row(5, 49)
    w.clock.radio()
    (payload,) = w.pub_radio.puts
    msg = decode_geometry(payload, 6)
    assert msg.tick == 50 and all(q is not None for q in msg.positions)
    w.clock.radio()
    assert len(w.pub_radio.puts) == 1  # the next one at tick 60
    w.clock.t0 = time.time() - (w.last_tick + 5) * w.period
    w.clock.radio()
    assert len(w.pub_radio.puts) == 1  # past the run's end: the agents would refuse it (radio_range)


def test_any_radio_command_is_answered_and_a_relayed_one_is_what_every_vehicle_takes():
    """Hypothesis over the ground station's radio command (any table, any time, either clock):
    never an internal error; refused with nothing relayed, or relayed with a time and a change
    every vehicle's agent takes, leaving its channel's epochs equal to the world's."""
    import msgpack
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as hs

    from cdus.scenario.config import load_scenario as load
    from cdus.wire.messages import CTL_OPS, decode_control
    from cdus.wire.transport import Transport
    from vehicle_agent.agent import Agent

    from .test_world import FLEET, started

    sc = load(ROOT / "configs/lake_radio.toml")
    num = hs.floats() | hs.integers(-2**63, 2**64 - 1) | hs.booleans() | hs.text(max_size=3) | hs.none()
    value = num | hs.lists(num, max_size=4) | hs.dictionaries(hs.text(max_size=2), num, max_size=2)
    plausible = hs.fixed_dictionaries({}, optional={
        "tx_power": hs.floats(-60.0, 60.0), "station": hs.lists(hs.floats(-2e7, 2e7), min_size=2, max_size=3)})
    change = plausible | hs.dictionaries(hs.sampled_from(["tx_power", "station", "x"]), value, max_size=3) | num
    at = hs.floats(-10.0, 400.0) | num

    @settings(max_examples=150, deadline=None, suppress_health_check=list(HealthCheck))
    @given(change=change, at=at, clock=hs.sampled_from(["lockstep", "realtime"]))
    def check(change, at, clock):
        w = _radio_world(clock)
        if clock == "lockstep":
            started(w)
        q = w.ask(f"cdus/{FLEET}/world/cmd/gs", msgpack.packb({"v": 1, "op": "radio", "radio": change, "at": at}))
        assert w.st.rejects.get("internal", 0) == 0
        r = q.answer
        relayed = [p for p in w.pub_ctl.puts if decode_control(p, CTL_OPS).op == "radio"]
        if r.status == "rejected":
            assert not relayed and len(w.radio_watch.channel.epochs) == 1
            return
        a = Agent(sc, "usv1", "tunit", Transport(), clock=clock, log=lambda s: None)
        for p in relayed:
            a.feed(f"cdus/tunit/to/+usv1+/ctl", p)
        assert a.rejected == {} and a.node.radio.channel.epochs == w.radio_watch.channel.epochs

    check()


def test_realtime_a_vehicle_paused_by_a_fault_holds_no_geometry_sample_back():
    """Realtime: the world samples the geometry once every vehicle alive has reported. A vehicle
    paused from the start (SIGSTOPped: its token stays up for the lease) reports nothing, so no
    sample went out for the first second or so and every message meanwhile passed unjudged
    (no_geometry: 340 of lake_radio's in a 6 s run with usv2 paused at 0 s). A vehicle a fault
    paused or killed is not live in the sample (as in lockstep) and holds nothing back."""
    import time

    from cdus.wire.messages import decode_geometry

    from .test_world import row, send_rows

    w = _radio_world("realtime")
    for vid in w.ids:
        w.alive(vid, True)
    w.clock.t0 = time.time() - 1.0  # tick 50 or so
    j = w.ids.index("usv2")
    for k, vid in enumerate(w.ids):
        if vid != "usv2":
            send_rows(w, vid, [row(k, n) for n in range(3)])
    w.clock.radio()
    assert w.pub_radio.puts == []  # usv2, live, not heard from yet: waited for (the start)
    w._note_fault("usv2", "pause")
    w.clock.radio()
    (payload,) = w.pub_radio.puts
    msg = decode_geometry(payload, len(w.ids))
    assert msg.positions[j] is None and all(q is not None for k, q in enumerate(msg.positions) if k != j)

"""The radio path of a node: the hand-set link fault first, then the channel from the
geometry sample in force at the send tick; the sample schedule a runner waits for."""

from __future__ import annotations

import dataclasses

import pytest

from cdus.core.link import IdealLink, LinkEmulator
from cdus.core.linkspec import LinkSpec
from cdus.core.radio import RadioChannel, RadioSpec
from cdus.core.radiolink import RadioLink, sample_tick
from cdus.scenario.config import load_scenario
from cdus.scenario.link import validate_link
from cdus.sim.build import build_node, link_model_for

IDS = ("a", "b")
NEAR = ((0.0, 0.0, 0.0), (50.0, 0.0, 0.0))
FAR = ((0.0, 0.0, 0.0), (5000.0, 0.0, 0.0))


def radio_link(inner=None, every=5, lag=5, **spec):
    ch = RadioChannel(RadioSpec(shadowing_sigma=0.0, **spec), IDS, ("usv", "usv"), 7, rate=50.0, tick_period=0.02)
    return RadioLink(inner or IdealLink(), ch, period=0.02, every=every, lag=lag)


@pytest.mark.parametrize("m, every, lag, s", [
    (0, 5, 5, 0), (4, 5, 5, 0), (9, 5, 5, 0), (10, 5, 5, 5), (14, 5, 5, 5), (15, 5, 5, 10),
    (0, 10, 1, 0), (1, 10, 1, 0), (10, 10, 1, 0), (11, 10, 1, 10), (20, 10, 1, 10), (21, 10, 1, 20),
])
def test_the_sample_in_force_at_a_send_tick(m, every, lag, s):
    assert sample_tick(m, every, lag) == s


def test_a_runner_waits_only_for_the_sample_in_force():
    rl = radio_link()
    assert rl.missing(0)  # sample 0 is in force from the start
    assert not rl.on_geometry(3, NEAR)  # not a sample tick
    assert rl.on_geometry(0, NEAR)
    assert not rl.on_geometry(0, FAR)  # the first one stands
    assert not rl.missing(9) and rl.missing(10)
    rl.on_geometry(5, NEAR)
    assert not rl.missing(14) and rl.missing(15)


def test_the_channel_decides_from_the_geometry_in_force_at_the_send_tick():
    rl = radio_link()
    rl.on_geometry(0, NEAR)
    rl.on_geometry(5, FAR)
    assert rl.decide(0, 1, 0, 0.0) != ()  # sent at tick 0: sample 0, 50 m
    assert rl.decide(0, 1, 9, 9 * 0.02) != ()  # tick 9: still sample 0
    assert rl.decide(0, 1, 10, 10 * 0.02) == ()  # tick 10: sample 5, 5 km: out of range
    c = rl.counters
    assert (c.sent, c.delivered, c.range, c.fault) == (3, 2, 1, 0)


def test_the_hand_set_fault_decides_first_and_the_delays_add_up():
    spec = validate_link({"delay": {"base": 0.1}, "down": [{"src": "a", "from": 1.0, "to": 2.0}]}, IDS, "t")
    rl = radio_link(LinkEmulator(spec, IDS, 3))
    rl.on_geometry(0, FAR)
    rl.on_geometry(50, NEAR)
    assert rl.decide(0, 1, 60, 1.2) == ()  # link down: the radio is not asked
    assert rl.counters.fault == 1 and rl.channel.counters.sent == 0
    (d,) = rl.decide(0, 1, 120, 2.4)  # sample 50 (near) in force at tick 120
    radio = rl.channel.decide(0, 1, 120, 2.4, rl.geometry_at(120))
    assert radio.delivered and d == pytest.approx(0.1 + radio.delay, abs=1e-15) and radio.delay > 0
    assert rl.decide(0, 1, 10, 0.2) == ()  # sample 0 (far): the channel drops it
    assert (rl.counters.fault, rl.counters.range, rl.counters.delivered) == (1, 1, 1)


def test_a_scenario_without_radio_keeps_its_link_model():
    sc = load_scenario("configs/lake_circle.toml")
    assert isinstance(link_model_for(sc), IdealLink)
    node = build_node(sc, "usv1", link_model_for(sc))
    assert node.radio is None and not node.geometry_missing(100) and not node.on_geometry(0, NEAR)
    sc = load_scenario("configs/lake_radio.toml")
    link = link_model_for(sc)
    assert isinstance(link, RadioLink) and isinstance(link.inner, IdealLink)
    assert build_node(sc, "usv1", link).radio is link


def test_a_run_time_link_change_reaches_the_emulator_under_the_radio():
    sc = load_scenario("configs/lake_radio.toml", {"link.loss": 0.1})
    link = link_model_for(sc)
    node = build_node(sc, "usv1", link)
    at = node.set_link(dataclasses.replace(sc.link, loss=0.5), 3.0).at
    assert at == 3.0 and [s for s, _ in link.inner.epochs] == [float("-inf"), 3.0]
    assert isinstance(sc.link, LinkSpec)


def test_a_link_model_given_to_a_radio_fleet_goes_under_the_radio():
    from cdus.sim.fleet import InProcessFleet

    sc = load_scenario("configs/lake_radio.toml", {"scenario.duration": 0.5})
    emulator = LinkEmulator(validate_link({"loss": 0.5}, sc.ids, "t"), sc.ids, 1)
    fleet = InProcessFleet(sc, link=emulator)
    assert isinstance(fleet.link, RadioLink) and fleet.link.inner is emulator
    m = fleet.run().metrics
    assert m.radio.dropped_by["fault"] == m.link.faults.total.dropped > 0

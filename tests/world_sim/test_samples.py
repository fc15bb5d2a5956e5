"""world_sim.samples: the proximity contacts and the radio geometry the world sends the vehicles.
No network (tests/world_sim/test_world.py's fakes)."""

from __future__ import annotations

from cdus.scenario.config import load_scenario
from cdus.wire import keys
from cdus.wire.messages import StateMsg, decode_contacts, decode_geometry
from cdus.wire.transport import Transport
from world_sim.world import World

from .test_world import FLEET, Pub, Session, world


def at(j: int, q: tuple) -> StateMsg:
    return StateMsg(j, 0, 0.0, q, 0.0, 1.0, 0.0, 0.0, 0.5)


def test_each_sampled_vehicle_hears_its_contacts_and_one_not_sampled_stays_an_obstacle_where_last_seen(tmp_path):
    w = world(tmp_path, events="\n[safety]\nenabled = true\n")
    w.st.latest[2] = at(2, (0.0, 1.0))  # usv3: killed, last seen next to usv1
    positions = {0: (0.0, 0.0), 1: (1.0, 0.0), 3: (500.0, 0.0, 20.0), 4: (600.0, 0.0, 20.0), 5: (700.0, 0.0, 20.0)}
    w._send_contacts(0, positions)
    sent = {k: p for k, p in w.session.puts}
    assert keys.contacts(FLEET, "usv3") not in sent  # not sampled: told nothing
    mine = decode_contacts(sent[keys.contacts(FLEET, "usv1")], len(w.ids), 0, 2)
    assert mine.tick == 0 and sorted(c[0] for c in mine.contacts) == [1, 2]
    assert dict((c[0], c[2]) for c in mine.contacts) == {1: (1.0, 0.0), 2: (0.0, 1.0)}


def test_a_geometry_sample_goes_to_every_vehicle_with_the_positions_that_stepped_it_and_is_replayed_to_a_joiner():
    sc = load_scenario("configs/lake_radio.toml")
    w = World(sc, FLEET, Transport(), clock="lockstep", log=lambda s: None)
    w.session, w.pub_radio = Session(), Pub()
    positions = {j: (float(j), 0.0) if sc.vehicles[j].dim == 2 else (float(j), 0.0, 20.0)
                 for j in range(len(w.ids)) if j != 1}  # usv2 did not step tick 10
    w._send_geometry(10, positions)
    w._send_geometry(20, positions)
    assert len(w.pub_radio.puts) == 2
    g = decode_geometry(w.pub_radio.puts[0], len(w.ids))
    assert g.tick == 10 and g.positions[1] is None and g.positions[0] == (0.0, 0.0)
    w._replay_geometry("usv2")
    assert w.session.puts == [(keys.radio(FLEET, ["usv2"]), p) for p in w.pub_radio.puts]  # the newest, in order

"""The world's liveliness watch: whose token is whose (docs/security.md, "Liveliness"), and the
blocking puts of what the vehicles act on."""

from __future__ import annotations

import zenoh
from hypothesis import given, settings, strategies as hs

from cdus.core.events import RosterChange
from cdus.wire import keys
from cdus.wire.schemas import AgentStats
from tests.world_sim.test_world import FLEET, started, world

G = {vid: f"a{j}" for j, vid in enumerate(("usv1", "usv2", "usv3", "uav1", "uav2", "uav3"))}  # genuine session ids


class Token:
    """A liveliness sample as Zenoh hands it to the world's callback."""

    def __init__(self, key: str, up: bool = True):
        self.key_expr = key
        self.kind = zenoh.SampleKind.PUT if up else zenoh.SampleKind.DELETE


def hear(w, key: str, up: bool = True) -> None:
    w._on_alive_sample(Token(key, up))
    w._handle_alive_news()


def up_by_tokens(w):
    """A lockstep world whose vehicles came up by their own tokens, started."""
    for vid in w.ids:
        hear(w, keys.alive(FLEET, vid, G[vid]))
    assert w.st.alive == set(w.ids)
    return started(w)


def test_a_wildcard_token_is_nobodys_and_says_the_run_may_have_been_altered():
    w = up_by_tokens(world())
    puts = len(w.session.puts)
    for key in (f"cdus/{FLEET}/alive/**", f"cdus/{FLEET}/alive/*/*", f"cdus/{FLEET}/alive/usv2"):
        hear(w, key)
        hear(w, key, up=False)
    assert w.st.alive == set(w.ids) and w.lockstep.pending == set() and len(w.session.puts) == puts
    w.session = None
    w.next_tick = w.last_tick + 1
    m = w.finish()
    assert (m.completed, m.integrity.tampered) == (True, True)
    assert m.integrity.reasons == {"token_key": 3}
    assert "alive/**" in m.integrity.notes[0]
    assert [e.kind for e in w.events if e.kind == "suspect"] == ["suspect"]  # said once, when first seen


def test_a_second_token_of_a_vehicle_neither_hides_its_loss_nor_brings_it_back():
    w = up_by_tokens(world())
    forged = keys.alive(FLEET, "usv2", "f0")
    hear(w, forged)  # while usv2's own is up: Zenoh would have merged it with a bare alive/usv2
    hear(w, keys.alive(FLEET, "usv1", G["usv2"]))  # usv2's session as usv1
    hear(w, keys.alive(FLEET, "usv2", G["usv2"]), up=False)  # usv2 killed
    assert "usv2" not in w.st.alive and w.lockstep.pending == {1}
    hear(w, forged, up=False)
    hear(w, forged)  # the forger again, now that usv2 has no token: refused once, never taken
    assert "usv2" not in w.st.alive
    hear(w, keys.alive(FLEET, "usv2", "b7"))  # a restart: a new session
    assert "usv2" in w.st.alive and w._token_of["usv2"] == "b7"
    assert w.integrity == {"token_extra": 3}
    hear(w, keys.alive(FLEET, keys.WORLD, "e9"))  # another world
    hear(w, keys.alive(FLEET, "usv9", "e8"))  # no vehicle of the fleet
    assert w.integrity == {"token_extra": 4, "token_unknown": 1}


def test_the_worlds_own_token_and_a_session_back_after_an_outage_are_no_news():
    w = world()
    w.zid = "e1"
    hear(w, keys.alive(FLEET, keys.WORLD, "e1"))
    hear(w, keys.alive(FLEET, "usv1", G["usv1"]))
    hear(w, keys.alive(FLEET, "usv1", G["usv1"]))  # said twice
    hear(w, keys.alive(FLEET, "usv1", G["usv1"]), up=False)
    hear(w, keys.alive(FLEET, "usv1", G["usv1"]))  # its session reconnected (a router restart, a lapsed pause)
    assert "usv1" in w.st.alive and not w.integrity


def test_a_vehicle_watching_a_token_not_the_worlds_is_in_the_integrity_block():
    w = up_by_tokens(world())
    w.st.stats["usv1"] = AgentStats(id="usv1", tick=0, sent_to_me=0, delivered=0, dropped=0, duplicated=0, rejected=1,
                                    rejected_by_reason={"token_key": 2})
    assert w.integrity_block().reasons == {"vehicle_token_key": 2}


vids = hs.sampled_from(["usv1", "usv2", "uav3", "world", "ros2", "usv9", "", "*", "**", "$*"])
zids = hs.sampled_from(["a0", "a1", "f0", "f1", "*", "**", "A1", "x"])
keys_ = hs.one_of(hs.builds(lambda v, z: f"cdus/{FLEET}/alive/{v}/{z}", vids, zids),
                  hs.builds(lambda v: f"cdus/{FLEET}/alive/{v}", vids), hs.text(max_size=30))


@settings(max_examples=150, deadline=None)
@given(hs.lists(hs.tuples(keys_, hs.booleans()), max_size=30), hs.booleans())
def test_no_token_but_a_vehicles_own_changes_whether_it_is_alive(news, ros2):
    """usv1's own token (a0) up all along: whatever else comes and goes (forged, wildcard,
    junk, the ROS 2 bridge's with [ros2] on or off), usv1 stays alive and nothing raises; every
    vehicle alive holds the token taken for it; no session holds two names."""
    import dataclasses

    w = world()
    if ros2:
        w.scenario = dataclasses.replace(w.scenario, ros2=dataclasses.replace(w.scenario.ros2, enabled=True))
    hear(w, keys.alive(FLEET, "usv1", "a0"))
    for key, up in news:
        if key == keys.alive(FLEET, "usv1", "a0") and not up:
            continue
        hear(w, key, up)
    assert "usv1" in w.st.alive and w._token_of["usv1"] == "a0"
    assert w.st.alive == set(w._token_of) - {"ros2"}
    assert ros2 or "ros2" not in w._token_of
    assert len(set(w._token_of.values())) == len(w._token_of)


class Recording:
    """A session that keeps each put's congestion control."""

    def __init__(self) -> None:
        self.puts: list[tuple[str, object]] = []

    def put(self, key, payload, congestion_control=None, **kw) -> None:
        self.puts.append((key, congestion_control))


def test_roster_changes_joins_and_contacts_block_rather_than_drop_under_congestion(tmp_path):
    w = world(tmp_path, events="\n[safety]\nenabled = true\n")
    w.session = Recording()
    w._send_roster(RosterChange(10, 1, "gone"))
    w._send_command(["usv1"], "usv1", "gains", gains={"c": 1.0}, tick=5)
    w._replay_commands("usv1")
    w._send_contacts(0, {j: (0.0, 0.0) if j < 3 else (0.0, 0.0, 20.0) for j in range(6)})
    kinds = {keys.leaf(k)[0] for k, _ in w.session.puts}
    assert kinds == {"ctl", "contacts"}, w.session.puts
    assert all(cc == zenoh.CongestionControl.BLOCK for _, cc in w.session.puts), w.session.puts


def test_the_ros2_bridges_token_is_the_fleets_own_when_ros2_is_enabled():
    """`cdus launch --ros2`: the bridge's token alive/ros2/<zid> was 'a token of a name not in
    the fleet' (token_unknown), so every --ros2 run ended TAMPERED. With [ros2] enabled its first
    token is the bridge's; a second while it is up is counted as a vehicle's would be; without
    [ros2] it is still no process of the fleet."""
    import dataclasses

    w = up_by_tokens(world())
    w.scenario = dataclasses.replace(w.scenario, ros2=dataclasses.replace(w.scenario.ros2, enabled=True))
    hear(w, keys.alive(FLEET, "ros2", "b1"))
    hear(w, keys.alive(FLEET, "ros2", "b1"))  # said twice
    assert not w.integrity and w.st.alive == set(w.ids)
    hear(w, keys.alive(FLEET, "ros2", "f1"))  # a second bridge while the first is up
    hear(w, keys.alive(FLEET, "ros2", G["usv1"]))  # usv1's session as the bridge
    assert w.integrity == {"token_extra": 2}
    hear(w, keys.alive(FLEET, "ros2", "b1"), up=False)
    hear(w, keys.alive(FLEET, "ros2", "f1"))  # refused once: never taken
    assert w.integrity == {"token_extra": 3}
    plain = up_by_tokens(world())
    hear(plain, keys.alive(FLEET, "ros2", "b1"))
    assert plain.integrity == {"token_unknown": 1}

"""plant = "ros2" without a network: the odometry decoder against rosbags' bytes, every malformed
payload counted by reason and dropped (Hypothesis), the Twist rosbags reads, the agent's hold
on missing or stale odometry and its return, its spells without odometry reported to the world
and shown there as fleet events (every hostile report counted and dropped), and the config's
refusals."""

from __future__ import annotations

import math
import random

import msgpack
import pytest
from hypothesis import given, settings, strategies as st

from cdus.ros2 import cdr
from cdus.ros2.robot import ODOM, ODOM_REASONS, TWIST, RobotPose, gap_events, read_odometry, twist
from cdus.ros2.types import TYPES
from cdus.scenario.config import ConfigError, load_scenario
from cdus.wire import keys
from cdus.wire.rejected import Rejected
from cdus.wire.schemas import MAX_ODOMETRY_GAPS, MAX_TIME, SCHEMA_VERSION, AgentStats, OdometryGap, decode_stats
from cdus.wire.schemas import encode_stats
from cdus.wire.transport import Transport
from tests.ros2.robots import odometry_bytes, read_twist
from tests.world_sim.test_world import Pub, Session

finite = st.floats(-1e6, 1e6, allow_nan=False)
CONFIG = "configs/ros2_robot.toml"


@settings(max_examples=80, deadline=None)
@given(q=st.tuples(finite, finite, finite), yaw=st.floats(-3.1, 3.1), v=st.tuples(finite, finite, finite),
       t=st.floats(0, 1e6), dim=st.sampled_from([2, 3]))
def test_odometry_from_rosbags_reads_as_its_pose(q, yaw, v, t, dim):
    p = read_odometry(odometry_bytes(q, yaw, v, t), dim)
    assert isinstance(p, RobotPose)
    assert p.q == q[:dim]
    assert p.heading == pytest.approx(yaw, abs=1e-9)
    c, s = math.cos(yaw), math.sin(yaw)  # the body-frame twist turned into the world frame
    assert p.v[:2] == (pytest.approx(v[0] * c - v[1] * s, rel=1e-9, abs=1e-6),
                       pytest.approx(v[0] * s + v[1] * c, rel=1e-9, abs=1e-6))
    assert p.stamp == pytest.approx(t, abs=1e-6)


def test_cdr_decode_reads_back_every_type_it_encodes():
    from cdus.ros2 import fleet
    for type_name, value in [(fleet.ODOM, fleet.odometry(2.5, "usv1", (1, 2, 3), 0.5, 1.5, "world")),
                             (fleet.PATH, fleet.path([(1, 2, 3), (4, 5, 6)], "world")),
                             (fleet.TF, fleet.transforms(1.0, [("a", (1, 2), 0.1)], "map"))]:
        data = cdr.encode(type_name, value)
        assert cdr.encode(type_name, cdr.decode(type_name, data)) == data


@settings(max_examples=300, deadline=None)
@given(data=st.binary(max_size=800))
def test_any_bytes_are_a_pose_or_a_counted_reason(data):
    p = read_odometry(data, 2)
    assert isinstance(p, RobotPose) or (isinstance(p, Rejected) and p.reason in ODOM_REASONS)


@settings(max_examples=300, deadline=None)
@given(cut=st.integers(0, 715), flips=st.lists(st.tuples(st.integers(0, 715), st.integers(0, 255)), max_size=6),
       type_name=st.sampled_from(sorted(TYPES)))
def test_a_mangled_odometry_is_a_pose_or_a_counted_reason_for_every_type(cut, flips, type_name):
    good = bytearray(odometry_bytes((1.0, 2.0, 0.0), 0.3, (1.0, 0.0, 0.0), 5.0))
    for i, b in flips:
        good[i % len(good)] = b
    data = bytes(good[:cut]) if cut < len(good) else bytes(good)
    p = read_odometry(data, 3)
    assert isinstance(p, RobotPose) or p.reason in ODOM_REASONS
    m = cdr.decode(type_name, data)
    assert isinstance(m, dict) or m.reason in cdr.DECODE_REASONS


def test_the_reasons():
    good = odometry_bytes((1.0, 2.0), 0.3)
    assert read_odometry(b"\x01\x00\x00\x00" + good[4:], 2) == Rejected("header")  # big-endian CDR
    assert read_odometry(good[:100], 2) == Rejected("truncated")
    assert read_odometry(good + b"\x00" * 16, 2) == Rejected("trailing")
    nan = cdr.encode(ODOM, {"pose": {"pose": {"position": {"x": math.nan}, "orientation": {"w": 1.0}}}})
    assert read_odometry(nan, 2) == Rejected("nonfinite")
    assert read_odometry(cdr.encode(ODOM, {}), 2) == Rejected("orientation")  # w = 0: no rotation at all
    bad_string = bytearray(good)
    bad_string[12:16] = (10 ** 6).to_bytes(4, "little")  # the frame id's length past the end
    assert read_odometry(bytes(bad_string), 2) == Rejected("string")
    huge = cdr.encode("nav_msgs/msg/Path", {})[:-4] + (cdr.MAX_SEQUENCE + 1).to_bytes(4, "little")
    assert cdr.decode("nav_msgs/msg/Path", huge) == Rejected("count")


@settings(max_examples=50, deadline=None)
@given(u=st.tuples(finite, finite) | st.tuples(finite, finite, finite))
def test_the_twist_rosbags_reads_is_the_world_frame_command(u):
    assert read_twist(cdr.encode(TWIST, twist(u))) == (*u, 0.0)[:3]
    assert read_twist(cdr.encode(TWIST, twist(None))) == (0.0, 0.0, 0.0)


# --------------------------------------------------------------------------- the agent, no network

def robot_agent():
    from vehicle_agent.robot import RobotAgent
    sc = load_scenario(CONFIG)
    lines = []
    a = RobotAgent(sc, "usv1", "t", Transport(), clock="realtime", log=lines.append)
    return a, lines


def test_the_agent_holds_without_odometry_follows_with_it_and_holds_again_when_it_goes_stale():
    a, lines = robot_agent()
    node = a.node
    a.step(0)  # no odometry yet: held, not stepped (no ω broadcast)
    assert a.holding and node.tick == 0 and a.ticks_done == 0
    a.feed_odometry(odometry_bytes((20.0, 0.0), math.pi / 2))
    a.step(1)
    assert not a.holding and a.ticks_done == 2 and node.vehicle.q == (20.0, 0.0)
    u = node.vehicle.plant.command
    assert u is not None and math.hypot(*u) == pytest.approx(4.0)  # far from its circle: the speed limit of the config
    assert any("following at tick 1" in ln for ln in lines)
    a.heard -= 10.0  # its odometry is now 10 s old
    a.step(2)
    assert a.holding and a.ticks_done == 2 and a.holds == 2
    stale = [ln for ln in lines if "odometry stale" in ln]
    assert len(stale) == 1 and "/usv1/odom" in stale[0] and "holding at tick 2" in stale[0]
    a.step(3)  # still stale: said once
    assert len([ln for ln in lines if "odometry stale" in ln]) == 1
    a.feed_odometry(odometry_bytes((0.0, 5.0), math.pi))
    a.step(4)
    assert not a.holding and node.vehicle.q == (0.0, 5.0) and a.ticks_done == 5


class Puts:
    def __init__(self):
        self.puts: list[bytes] = []

    def put(self, payload: bytes) -> None:
        self.puts.append(bytes(payload))


def test_each_spell_without_odometry_goes_to_the_world_when_it_begins_and_when_it_ends():
    a, _ = robot_agent()
    a.report.pub_stats = pub = Puts()
    a.step(0)  # waiting for the first odometry is a spell too, from the first tick
    assert decode_stats(pub.puts[-1]).odometry_gaps == (OdometryGap(0.0),)
    a.step(1)  # still waiting: nothing new to say (a holding vehicle sends no counters)
    assert len(pub.puts) == 1
    a.feed_odometry(odometry_bytes((5.0, 0.0), 0.0))
    a.step(2)
    assert decode_stats(pub.puts[-1]).odometry_gaps == (OdometryGap(0.0, 0.2),)
    a.heard -= 10.0
    a.step(30)
    assert decode_stats(pub.puts[-1]).odometry_gaps == (OdometryGap(0.0, 0.2), OdometryGap(3.0))
    a.step(31)
    a.feed_odometry(odometry_bytes((5.0, 0.0), 0.0))
    a.report._last_stats = 1e18  # no once-a-second report due: what goes is the end of the spell
    a.step(60)
    assert a.stats().odometry_gaps == decode_stats(pub.puts[-1]).odometry_gaps == (
        OdometryGap(0.0, 0.2), OdometryGap(3.0, 6.0))
    for n in range(100, 100 + 2 * 20, 2):  # many spells: the newest ODOM_GAPS go, within the decoder's bound
        a.heard -= 10.0
        a.step(n)
        a.feed_odometry(odometry_bytes((5.0, 0.0), 0.0))
        a.step(n + 1)
    gaps = decode_stats(pub.puts[-1]).odometry_gaps
    assert len(gaps) == 8 <= MAX_ODOMETRY_GAPS and gaps[-1] == OdometryGap(13.8, 13.9)


def robot_world():
    from world_sim.world import World
    w = World(load_scenario(CONFIG), "t", Transport(), clock="realtime", log=lambda s: None)
    w.session = Session()
    w.pub_ctl, w.pub_launcher, w.pub_status, w.pub_events = Pub(), Pub(), Pub(), Pub()
    return w


def test_the_world_shows_a_robots_spells_without_odometry_as_events_once_each():
    w = robot_world()
    send = lambda vid, *gaps: w.feed(keys.stats("t", vid), encode_stats(  # noqa: E731
        AgentStats(id=vid, tick=1, odometry_gaps=gaps)))
    send("usv1", OdometryGap(0.0))
    send("usv1", OdometryGap(0.0, 0.2))  # the same spell again, now ended: one new event
    send("usv1", OdometryGap(0.0, 0.2), OdometryGap(0.5))
    send("usv1", OdometryGap(0.0, 0.2), OdometryGap(0.5, 0.8))
    got = [(e.t, e.kind, e.severity, e.vehicle, e.origin) for e in w.events]
    assert got == [(0.0, "odometry_stale", "warn", "usv1", "usv1"), (0.2, "odometry_back", "info", "usv1", "usv1"),
                   (0.5, "odometry_stale", "warn", "usv1", "usv1"), (0.8, "odometry_back", "info", "usv1", "usv1")]
    assert "usv1: no odometry from /usv1/odom for 0.5 s (from t = 0.50 s)" in w.events[2].text
    assert "back at t = 0.80 s after 0.30 s without" in w.events[3].text
    assert w.st.rejects == {}
    send("usv2", OdometryGap(0.1))  # an emulated boat has no odometry to miss
    send("usv1", OdometryGap(1e6))  # past the newest tick a vehicle can have stepped
    assert len(w.events) == 4 and w.st.rejects == {"odometry_not_robot": 1, "odometry_future": 1}


def test_a_report_whose_spells_cannot_be_genuine_is_dropped_whole_not_only_its_spells():
    w = robot_world()
    send = lambda vid, n, *gaps: w.feed(keys.stats("t", vid), encode_stats(  # noqa: E731
        AgentStats(id=vid, tick=1, incarnation=5, interventions=n, odometry_gaps=gaps)))
    send("usv2", 3)
    send("usv1", 3)
    send("usv2", 999, OdometryGap(0.1))  # the genuine incarnation (read off an open fleet), spells of a boat
    send("usv1", 999, OdometryGap(1e6))  # a robot's spell from the future
    assert w.st.rejects == {"odometry_not_robot": 1, "odometry_future": 1}
    assert w.st.stats["usv2"].interventions == w.st.stats["usv1"].interventions == 3  # nothing of them taken
    assert w.events == []


_times = st.floats(0, 2e3) | st.sampled_from([0.0, MAX_TIME])


@settings(max_examples=150, deadline=None)
@given(vid=st.sampled_from(["usv1", "usv2", "uav1"]),
       spans=st.lists(st.tuples(_times, st.none() | st.floats(0, 50)), max_size=MAX_ODOMETRY_GAPS))
def test_any_report_of_spells_is_taken_whole_with_its_events_or_dropped_whole_by_reason(vid, spans):
    gaps, t = [], 0.0
    for start, length in spans:  # ordered, without overlap, only the newest open: what decodes
        t = min(t + start, MAX_TIME)
        gaps.append(OdometryGap(t, None if length is None else min(t + length, MAX_TIME)))
        if length is None:
            break
        t = gaps[-1].back
    w = robot_world()
    w.feed(keys.stats("t", vid), encode_stats(AgentStats(id=vid, tick=1, incarnation=5, interventions=3)))
    w.feed(keys.stats("t", vid), encode_stats(AgentStats(id=vid, tick=2, incarnation=5, interventions=9,
                                                         odometry_gaps=tuple(gaps))))
    limit = (w.clock.tick_limit() + 1) * w.period
    if vid != "usv1" and gaps or any(max(g.t, g.back or 0.0) > limit for g in gaps):
        assert sum(w.st.rejects.values()) == 1 and set(w.st.rejects) <= {"odometry_not_robot", "odometry_future"}
        assert w.st.stats[vid].tick == 1 and w.events == []
    else:
        assert w.st.rejects == {} and w.st.stats[vid].tick == 2
        assert sorted((e.kind, e.t) for e in w.events) == sorted(
            {(e.kind, e.t) for g in gaps for e in gap_events(vid, "/usv1/odom", 0.5, g)})


def test_a_world_records_a_robot_holding_from_the_start_where_it_starts_and_its_run_ends():
    """A robot without odometry from the first tick steps none, so it sends no row: the world
    recorded no tick and a 6 s realtime run was still going at 60 s (all agents done)."""
    from cdus.wire.messages import StateMsg, encode_states
    w = robot_world()
    for vid in w.ids:
        w.alive(vid, True)
    w.started = True
    for j, v in enumerate(w.scenario.vehicles):
        if v.id != "usv1":
            w.feed(keys.state("t", v.id), encode_states([StateMsg(j, 0, 0.0, (0.0,) * v.dim, 0.0, 0.0, 0.0, -1.0,
                                                                  0.0)]))
    assert w._record(0) and w.next_tick == 1
    assert w._recorded[0].q == pytest.approx((2.0, 0.0)) and w._recorded[0].tick == 0  # its path's start


def test_a_world_that_noted_its_share_of_a_robots_spells_counts_the_rest():
    from world_sim.limits import MAX_ODOMETRY_EVENTS
    w = robot_world()
    for k in range(MAX_ODOMETRY_EVENTS // 16 + 1):  # a hostile robot: ever new spells
        gaps = tuple(OdometryGap(round(0.001 * (16 * k + i), 3), round(0.001 * (16 * k + i) + 0.0005, 4))
                     for i in range(16))
        w.feed(keys.stats("t", "usv1"), encode_stats(AgentStats(id="usv1", tick=1, odometry_gaps=gaps)))
    assert len(w.events) == MAX_ODOMETRY_EVENTS and w.st.rejects["odometry_flood"] >= 1


_gap = st.fixed_dictionaries({"t": st.floats(-1.0, 2e9) | st.integers(-5, 5) | st.booleans() | st.text(max_size=2)},
                             optional={"back": st.none() | st.floats(allow_nan=True) | st.integers(-5, 5),
                                       "x": st.integers(-2**63, 2**63)})


@settings(max_examples=300, deadline=None)
@given(gaps=st.lists(_gap | st.integers(-2**63, 2**63) | st.none(), max_size=MAX_ODOMETRY_GAPS + 2)
       | st.text(max_size=3)
       | st.dictionaries(st.text(max_size=2), st.integers(-9, 9), max_size=2))
def test_any_odometry_gaps_field_decodes_to_ordered_bounded_spells_or_rejects_the_report(gaps):
    s = decode_stats(msgpack.packb({"v": SCHEMA_VERSION, "id": "usv1", "tick": 1, "odometry_gaps": gaps}))
    if isinstance(s, Rejected):
        assert s.reason == "odometry_gaps"
        return
    out = s.odometry_gaps
    assert len(out) <= MAX_ODOMETRY_GAPS and all(type(g.t) is float and 0 <= g.t <= MAX_TIME for g in out)
    assert all(g.back is None or g.t <= g.back <= MAX_TIME for g in out)
    assert all(a.back is not None and a.back <= b.t for a, b in zip(out, out[1:]))
    assert decode_stats(encode_stats(s)) == s


def test_malformed_odometry_is_counted_by_reason_and_changes_nothing():
    a, _ = robot_agent()
    rng = random.Random(3)
    good = odometry_bytes((5.0, 0.0), 0.0)
    for _ in range(200):
        a.feed_odometry(bytes(rng.getrandbits(8) for _ in range(rng.randrange(0, 40))))
    a.feed_odometry(good[:300])
    assert a.pose is None and sum(a.rejected.values()) == 201
    assert set(a.rejected) <= {f"odom_{r}" for r in ODOM_REASONS} and a.rejected["odom_truncated"] >= 1


_any = st.floats() | st.sampled_from([1e200, -1e300, 1e6, 1e6 + 1, 5e-324])


@settings(max_examples=120, deadline=None)
@given(q=st.tuples(_any, _any, _any), v=st.tuples(_any, _any, _any), quat=st.tuples(_any, _any, _any, _any),
       sec=st.integers(-2**31, 2**31 - 1))
def test_any_values_in_an_odometry_are_a_pose_within_bounds_or_counted_and_the_agent_steps_on(q, v, quat, sec):
    a, _ = robot_agent()
    a.feed_odometry(odometry_bytes((5.0, 0.0), 0.0))
    a.step(0)
    node = a.node
    msg = {"header": {"stamp": {"sec": sec}},  # the robot's clock need not be ours: any stamp is read, not judged
           "pose": {"pose": {"position": dict(zip("xyz", q)), "orientation": dict(zip("xyzw", quat))}},
           "twist": {"twist": {"linear": dict(zip("xyz", v))}}}
    a.feed_odometry(cdr.encode(ODOM, msg))
    for n in range(1, 4):
        a.step(n)  # never raises
    if a.rejected:
        assert list(a.rejected.values()) == [1] and set(a.rejected) <= {f"odom_{r}" for r in ODOM_REASONS}
        assert node.vehicle.q == (5.0, 0.0)  # the hostile pose was not taken
    else:
        assert node.vehicle.q == q[:2] and all(abs(x) <= 1e6 for x in node.vehicle.q)
    assert all(math.isfinite(x) for x in node.vehicle.plant.command)


def test_an_odometry_too_large_or_out_of_bounds_is_counted_and_dropped():
    a, _ = robot_agent()
    a.feed_odometry(odometry_bytes((1e200, 0.0), 0.0))  # was taken, and the step raised OverflowError
    a.feed_odometry(odometry_bytes((5.0, 0.0), 0.0, (1e7, 0.0, 0.0)))
    a.feed_odometry(odometry_bytes((5.0, 0.0), 0.0, frame="m" * 70_000))  # 19 ms to decode at 20 MB, 8 a tick
    a.step(0)
    assert a.pose is None and a.holding and a.rejected == {"odom_range": 2, "odom_oversized": 1}
    a.feed_odometry(odometry_bytes((1e6, -1e6), 0.0, (1e6, 0.0, 0.0), frame="m" * 60_000))  # at the bounds: taken
    a.step(1)
    assert not a.holding and a.node.vehicle.q == (1e6, -1e6)


def test_a_lockstep_agent_or_launch_of_a_robot_is_refused_naming_the_clock():
    from vehicle_agent.robot import RobotAgent
    sc = load_scenario(CONFIG)
    with pytest.raises(ValueError, match="--clock: .*usv1.*plant = \"ros2\".*--clock realtime"):
        RobotAgent(sc, "usv1", "t", Transport(), clock="lockstep", log=lambda s: None)
    from cdus import api
    with pytest.raises(ConfigError, match="clock.*real time"):
        api.run(sc)


def test_the_robot_table_is_checked():
    base = load_scenario(CONFIG).raw
    import copy

    from cdus.scenario.config import parse_scenario
    bad = copy.deepcopy(base)
    bad["vehicle"][0]["ros2"] = {"odom": "usv1/odom", "timeout": -1, "x": 1}
    with pytest.raises(ConfigError) as e:
        parse_scenario(bad)
    text = str(e.value)
    assert "vehicle[0] (id \"usv1\").ros2.odom" in text or "ros2.odom" in text
    assert "ros2.timeout" in text and "ros2.x" in text
    other = copy.deepcopy(base)
    other["vehicle"][1]["ros2"] = {"odom": "/usv2/odom"}
    with pytest.raises(ConfigError, match="only used by plant = \"ros2\""):
        parse_scenario(other)
    default = copy.deepcopy(base)
    del default["vehicle"][0]["ros2"]
    assert parse_scenario(default).vehicle("usv1").robot.cmd_vel == "/usv1/cmd_vel"


@pytest.mark.parametrize("over, field, said", [
    ({"vehicle.usv2.plant": "ros2", "vehicle.usv2.ros2": {"odom": "/usv1/odom"}}, 'vehicle[1] (id "usv2").ros2.odom',
     "'/usv1/odom' is also the odom topic of robot 'usv1': give each robot its own (the default is '/usv2/odom')"),
    ({"vehicle.usv2.plant": "ros2", "vehicle.usv2.ros2": {"cmd_vel": "/usv1/cmd_vel"}},
     'vehicle[1] (id "usv2").ros2.cmd_vel', "is also the cmd_vel topic of robot 'usv1'"),
    ({"ros2.enabled": True, "vehicle.usv1.ros2": {"odom": "/cdus/usv3/odom"}}, 'vehicle[0] (id "usv1").ros2.odom',
     "'/cdus/usv3/odom' is where cdus publishes the odometry of vehicle 'usv3' ([ros2] enabled, namespace '/cdus')"),
    ({"ros2.enabled": True, "ros2.namespace": "/"}, 'vehicle[0] (id "usv1").ros2.odom',  # the default topic, then
     "'/usv1/odom' is where cdus publishes the odometry of vehicle 'usv1'"),
])
def test_a_robot_topic_another_robot_or_the_fleets_ros2_face_uses_is_refused_naming_it(over, field, said):
    with pytest.raises(ConfigError) as e:
        load_scenario(CONFIG, over)
    assert f"{field}: " in str(e.value) and said in str(e.value)


def test_a_robot_topic_of_its_own_is_taken():
    load_scenario(CONFIG, {"ros2.enabled": True})  # /usv1/odom beside the bridge's /cdus/usv1/odom
    load_scenario(CONFIG, {"vehicle.usv1.ros2": {"odom": "/cdus/usv1/odom"}})  # no ROS 2 face: nothing publishes it
    two = load_scenario(CONFIG, {"vehicle.usv2.plant": "ros2", "ros2.enabled": True, "ros2.namespace": "/lake"})
    assert [v.robot.odom for v in two.vehicles if v.robot] == ["/usv1/odom", "/usv2/odom"]


def test_cdus_launch_refuses_a_robot_in_lockstep_and_starts_nothing():
    from tests.e2e.conftest import run_cli
    lock = run_cli(["launch", CONFIG, "--rerun", "off"])  # lockstep is launch's default clock
    assert lock.returncode == 2 and "--clock: vehicle 'usv1' has plant = \"ros2\"" in lock.stderr
    assert "nothing was started" in lock.stderr + lock.stdout


def test_cdus_sim_refuses_a_robot_in_its_own_words():
    """`cdus sim` of a robot's scenario said 'error: cdus.run: clock: ... the inproc clock ...' (the
    API's name and a clock the command has no flag for); now the command's own."""
    from tests.e2e.conftest import run_cli
    sim = run_cli(["sim", CONFIG, "--rerun", "off"])
    assert sim.returncode == 2 and sim.stderr.startswith(
        "error: command line: cdus sim: vehicle 'usv1' has plant = \"ros2\", a real robot that moves in real time, "
        "and cdus sim (the inproc clock) steps as fast as the machine allows: run it with cdus launch --clock realtime")


def test_the_fleet_wide_disturbance_and_observer_pass_a_robot_by():
    import copy

    from cdus.scenario.config import parse_scenario
    raw = copy.deepcopy(load_scenario(CONFIG).raw)
    raw["observer"] = {"enabled": True, "bandwidth": 2.0}
    raw["disturbance"] = {"current": {"constant": [0.1, 0.0]}}
    sc = parse_scenario(raw)
    assert sc.vehicle("usv1").observer is None and sc.vehicle("usv1").disturbance == ()
    assert sc.vehicle("usv2").observer == 2.0 and sc.vehicle("usv2").disturbance != ()

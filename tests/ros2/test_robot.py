"""plant = "ros2" without a network: the odometry decoder against rosbags' bytes, every malformed
payload counted by reason and dropped (Hypothesis), the Twist rosbags reads, the agent's hold
on missing or stale odometry and its return, and the config's refusals."""

from __future__ import annotations

import math
import random

import pytest
from hypothesis import given, settings, strategies as st

from cdus.ros2 import cdr
from cdus.ros2.robot import ODOM, ODOM_REASONS, TWIST, RobotPose, read_odometry, twist
from cdus.ros2.types import TYPES
from cdus.scenario.config import ConfigError, load_scenario
from cdus.wire.rejected import Rejected
from cdus.wire.transport import Transport
from tests.ros2.robots import odometry_bytes, read_twist

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
    a.feed_odometry(odometry_bytes((5.0, 0.0), math.pi / 2))
    a.step(1)
    assert not a.holding and a.ticks_done == 2 and node.vehicle.q == (5.0, 0.0)
    u = node.vehicle.plant.command
    assert u is not None and math.hypot(*u) == pytest.approx(1.0)  # the speed limit of the config
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


def test_malformed_odometry_is_counted_by_reason_and_changes_nothing():
    a, _ = robot_agent()
    rng = random.Random(3)
    good = odometry_bytes((5.0, 0.0), 0.0)
    for _ in range(200):
        a.feed_odometry(bytes(rng.getrandbits(8) for _ in range(rng.randrange(0, 40))))
    a.feed_odometry(good[:300])
    assert a.pose is None and sum(a.rejected.values()) == 201
    assert set(a.rejected) <= {f"odom_{r}" for r in ODOM_REASONS} and a.rejected["odom_truncated"] >= 1


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


def test_cdus_launch_refuses_a_robot_in_lockstep_or_on_a_secured_fleet_and_starts_nothing():
    from tests.e2e.conftest import run_cli
    lock = run_cli(["launch", CONFIG, "--rerun", "off"])  # lockstep is launch's default clock
    assert lock.returncode == 2 and "--clock: vehicle 'usv1' has plant = \"ros2\"" in lock.stderr
    assert "nothing was started" in lock.stderr + lock.stdout
    secured = run_cli(["launch", CONFIG, "--clock", "realtime", "--rerun", "off"])
    assert secured.returncode == 2 and "--insecure: a plant = \"ros2\" vehicle needs an open fleet" in secured.stderr


def test_the_fleet_wide_disturbance_and_observer_pass_a_robot_by():
    import copy

    from cdus.scenario.config import parse_scenario
    raw = copy.deepcopy(load_scenario(CONFIG).raw)
    raw["observer"] = {"enabled": True, "bandwidth": 2.0}
    raw["disturbance"] = {"current": {"constant": [0.1, 0.0]}}
    sc = parse_scenario(raw)
    assert sc.vehicle("usv1").observer is None and sc.vehicle("usv1").disturbance == ()
    assert sc.vehicle("usv2").observer == 2.0 and sc.vehicle("usv2").disturbance != ()

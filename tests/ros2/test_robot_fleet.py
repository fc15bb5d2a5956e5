"""A ``plant = "ros2"`` vehicle in a realtime fleet launched by `cdus launch`, driven by a stand-in
robot (tests/ros2/robots.py: rosbags' CDR, its own Zenoh session on the launcher's loopback
router) that integrates the Twist it hears into the Odometry it publishes. The loop closes (the
robot's distance to its circle shrinks), the robot's odometry stopped for a while is a stale
event with zero velocity sent, then it follows again, and the run ends cleanly."""

from __future__ import annotations

import math
import time

import zenoh
import zenoh_ros2_sdk as sdk

from cdus.ros2.rmw import topic_key
from cdus.wire.transport import Transport, free_tcp_port, zenoh_config
from tests.e2e.conftest import launches, unique_fleet  # noqa: F401 (the fixture)
from tests.ros2.robots import ODOM, TWIST, FakeRobot
from tests.ros2.test_launch import ros2_client  # noqa: F401 (the fixture)

RADIUS = 5.0  # configs/ros2_robot.toml: circles of radius 5 about the origin


def error(q) -> float:
    return abs(math.hypot(q[0], q[1]) - RADIUS)


def wait_until(cond, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, what
        time.sleep(0.05)


def test_a_robot_follows_its_path_in_a_realtime_fleet_and_its_silence_is_a_stale_hold(tmp_path, launches, ros2_client):
    fleet, port, run = unique_fleet(), free_tcp_port(), tmp_path / "run"
    la = launches(["configs/ros2_robot.toml", "--clock", "realtime", "--insecure", "--duration", "14",
                   "--rerun", "off", "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run)], fleet)
    la.wait_for("ros2_robot", timeout=60)  # the launcher is up, its router listening
    session = None
    for _ in range(100):
        try:
            session = zenoh.open(zenoh_config(Transport(mode="client", connect=(f"tcp/127.0.0.1:{port}",))))
            break
        except zenoh.ZError:
            time.sleep(0.1)
    assert session is not None
    robot = FakeRobot(session, topic_key(0, "/usv1/odom", ODOM), topic_key(0, "/usv1/cmd_vel", TWIST),
                      start=(8.0, 0.0)).start()
    try:
        wait_until(lambda: any(robot.v), 60, "no non-zero Twist came")
        # the command's publisher is in the ROS graph, as zenoh-ros2-sdk discovers it from the tokens
        topics = dict(sdk.get_topic_names_and_types(domain_id=0, router_port=port, timeout=2.0))
        assert topics["/usv1/cmd_vel"] == ["geometry_msgs/msg/Twist"]
        e0 = error(robot.q)
        time.sleep(3.0)
        e1 = error(robot.q)
        assert e1 < 0.75 * e0, (e0, e1, robot.q)  # the loop closes: the robot nears its circle
        robot.silent = True
        wait_until(lambda: robot.v == (0.0, 0.0, 0.0), 10, "the vehicle did not hold")
        held_at = list(robot.q)
        time.sleep(1.0)
        assert robot.q == held_at  # zero velocity while its odometry is missing
        robot.silent = False
        wait_until(lambda: any(robot.v), 10, "the vehicle did not follow again")
        assert la.wait(timeout=120) == 0
    finally:
        robot.stop()
        session.close()
    seqs = [a[0] for a in robot.attachments]
    assert len(seqs) == robot.twists and seqs == sorted(set(seqs))  # rmw_zenoh's attachment: one GID, seq rising
    assert len({a[2] for a in robot.attachments}) == 1 and all(a[1] > 0 for a in robot.attachments)
    log = (run / "logs" / "usv1.log").read_text()
    assert log.count("following at tick") == 2, log
    stale = [ln for ln in log.splitlines() if "odometry stale" in ln]
    assert len(stale) == 1 and "/usv1/odom" in stale[0] and "holding" in stale[0], log
    assert "done after" in log and "Traceback" not in log

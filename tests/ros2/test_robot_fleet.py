"""A ``plant = "ros2"`` vehicle in a secured realtime fleet of six launched by `cdus launch`
(configs/ros2_robot.toml: the robot usv1, two emulated boats, three drones), driven by a stand-in
robot written with zenoh-ros2-sdk (tests/ros2/robots.py: code nobody here wrote subscribes the
Twist, integrates it and publishes the Odometry), holding the run's robot-usv1 credentials (the
router's access control lets it and usv1 exchange exactly the odometry and the commands). The
loop closes (the robot nears its circle), its odometry stopped for 3 s is a held vehicle (zero
velocity) and a pair of fleet events in the run's metrics, then it follows again; the run
completes with the robot on its path and in formation with the other five."""

from __future__ import annotations

import json
import math
import time

import zenoh_ros2_sdk as sdk

from cdus.wire.transport import free_tcp_port
from tests.e2e.conftest import launches, unique_fleet  # noqa: F401 (the fixture)
from tests.ros2.robots import SdkRobot
from tests.ros2.test_launch import ros2_client  # noqa: F401 (the fixture)

RADIUS = 2.0  # configs/ros2_robot.toml: circles of radius 2 about the origin


def error(q) -> float:
    return abs(math.hypot(q[0], q[1]) - RADIUS)


def wait_until(cond, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, what
        time.sleep(0.05)


def test_a_robot_in_a_realtime_fleet_of_six_follows_holds_on_silence_as_an_event_and_keeps_formation(
        tmp_path, launches, ros2_client):
    fleet, port, run = unique_fleet(), free_tcp_port(), tmp_path / "run"
    # 12 s (it was 14): the silence is over by t ~ 5.8 s; at the end the worst coordination error is
    # 0.14-0.16 (0.08 at 14 s; at 10 s it was 0.31, over the 0.3 asked below)
    la = launches(["configs/ros2_robot.toml", "--clock", "realtime", "--duration", "12",
                   "--rerun", "off", "--listen", f"tcp/127.0.0.1:{port}", "--logs", str(run)], fleet)
    hint = la.wait_for("robot usv1:", timeout=60)  # the launcher is up, its router listening: where the robot goes
    creds = run / "secure" / "robot-usv1.json5"  # a secured fleet (the default): the robot's own role
    assert f"ZENOH_SESSION_CONFIG_URI={creds} " in hint and "/usv1/odom" in hint and "ROS_DOMAIN_ID=0" in hint
    ros2_client.setenv("ZENOH_SESSION_CONFIG_URI", str(creds))
    robot = None
    for _ in range(100):
        try:
            robot = SdkRobot(port, "/usv1/odom", "/usv1/cmd_vel", start=(4.0, 0.0)).start()
            break
        except Exception:  # the SDK's session before the router listens  # noqa: BLE001
            sdk.ZenohSession._instance = None
            time.sleep(0.1)
    assert robot is not None
    try:
        wait_until(lambda: any(robot.v), 60, "no non-zero Twist came")
        # the command's publisher is in the ROS graph, as zenoh-ros2-sdk discovers it from the tokens
        topics = dict(sdk.get_topic_names_and_types(domain_id=0, router_port=port, timeout=2.0))
        assert topics["/usv1/cmd_vel"] == ["geometry_msgs/msg/Twist"]
        e0 = error(robot.q)
        time.sleep(2.0)
        e1 = error(robot.q)
        assert e1 < 0.75 * e0, (e0, e1, robot.q)  # the loop closes: the robot nears its circle
        robot.silent = True
        wait_until(lambda: robot.v == (0.0, 0.0, 0.0), 10, "the vehicle did not hold")
        held_at = list(robot.q)
        time.sleep(1.0)
        assert robot.q == held_at  # zero velocity while its odometry is missing
        time.sleep(2.0)  # 3 s without odometry in all
        robot.silent = False
        wait_until(lambda: any(robot.v), 10, "the vehicle did not follow again")
        assert la.wait(timeout=120) == 0
    finally:
        robot.stop()
    seqs = [a.sequence_id for a in robot.attachments]  # rmw_zenoh's attachment as the SDK parses it
    assert len(seqs) == robot.twists and seqs == sorted(set(seqs))  # one GID, seq rising
    assert len({a.gid for a in robot.attachments}) == 1 and all(a.timestamp_ns > 0 for a in robot.attachments)

    m = json.loads((run / "metrics.json").read_text())
    assert m["completed"] is True and len(m["live_final"]) == 6, m["completion"]
    odometry = [(e["kind"], e["t"]) for e in m["events"] if e["kind"].startswith("odometry_")]
    # the 3 s silence: one spell (a wait before the robot's first odometry may come before it)
    assert len(odometry) in (2, 4) and [k for k, _ in odometry] == ["odometry_stale", "odometry_back"] * (
        len(odometry) // 2), odometry
    (_, t0), (_, t1) = odometry[-2:]
    assert 2.0 < t1 - t0 and all(e["vehicle"] == "usv1" and e["origin"] == "usv1"
                                 for e in m["events"] if e["kind"].startswith("odometry_"))
    # back on its path and in formation with the five others by the end
    assert m["final_path_error"]["usv1"] < 0.3, m["final_path_error"]
    assert m["final_coord_error_max"] < 0.3, m["final_coord_error_max"]
    log = (run / "logs" / "usv1.log").read_text()
    stale = [ln for ln in log.splitlines() if "odometry stale" in ln]
    assert len(stale) == 1 and "/usv1/odom" in stale[0] and "holding" in stale[0], log
    assert "done after" in log and "Traceback" not in log

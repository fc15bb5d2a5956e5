"""The [ros2] table (cdus.scenario.ros2): off by default, every key checked."""

import pytest

from cdus.scenario.config import parse_scenario
from cdus.scenario.ros2 import Ros2Spec, ros_name
from tests.scenario.common import base, edit, problems, section, v0


def test_absent_is_off_with_the_defaults():
    assert parse_scenario(base(), "x.toml").ros2 == Ros2Spec() and not Ros2Spec().enabled


def test_a_full_table():
    data = edit(section("ros2", enabled=True, domain_id=7, namespace="/lake/f1", distro="humble",
                        world_frame="map", rate=25.0))
    assert parse_scenario(data, "x.toml").ros2 == Ros2Spec(True, 7, "/lake/f1", "humble", "map", 25.0)


@pytest.mark.parametrize("key, value, words", [
    ("enabled", "yes", "ros2.enabled: must be true"),
    ("domain_id", 233, "ros2.domain_id: must be at most 232"),
    ("domain_id", -1, "ros2.domain_id: must be an integer >= 0"),
    ("namespace", "cdus", "ros2.namespace: must be a ROS 2 namespace"),
    ("namespace", "/cdus/", "ros2.namespace: must be a ROS 2 namespace"),
    ("namespace", "/1x", "ros2.namespace: must be a ROS 2 namespace"),
    ("distro", "iron", 'ros2.distro: unknown ROS 2 distribution "iron"'),
    ("world_frame", "/world", "ros2.world_frame: must be a frame id"),
    ("rate", 0, "ros2.rate: must be a number > 0"),
    ("colour", 1, 'ros2.colour: unknown key'),
])
def test_bad_values_name_the_field(key, value, words):
    assert words in problems(edit(section("ros2", **{key: value})))


def test_two_ids_one_ros_name_is_an_error_only_when_enabled():
    data = edit(v0(id="usv-2"))
    data["vehicle"][1]["id"] = "usv_2"
    assert parse_scenario(data, "x.toml").ros2.enabled is False
    data["ros2"] = {"enabled": True}
    assert "would share the ROS 2 name 'usv_2'" in problems(data)


def test_ros_names():
    assert [ros_name(v) for v in ("usv1", "usv-1", "1a")] == ["usv1", "usv_1", "v1a"]

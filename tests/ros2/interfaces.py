"""The .msg files of the ROS 2 interface definitions (common_interfaces, rcl_interfaces,
geometry2), as a ROS 2 installation ships them, comments left out: what the third-party client
(zenoh-ros2-sdk) reads to build its decoders and compute its own type hashes. Written here by
hand from those packages, not from cdus.ros2.types, so the two can disagree."""

from __future__ import annotations

from pathlib import Path

MSG_FILES = {
    "builtin_interfaces/msg/Time": "int32 sec\nuint32 nanosec\n",
    "std_msgs/msg/Header": "builtin_interfaces/Time stamp\nstring frame_id\n",
    "std_msgs/msg/Float64": "float64 data\n",
    "std_msgs/msg/String": "string data\n",
    "geometry_msgs/msg/Point": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/msg/Vector3": "float64 x\nfloat64 y\nfloat64 z\n",
    "geometry_msgs/msg/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    "geometry_msgs/msg/Pose": "Point position\nQuaternion orientation\n",
    "geometry_msgs/msg/PoseStamped": "std_msgs/Header header\nPose pose\n",
    "geometry_msgs/msg/PoseWithCovariance": "Pose pose\nfloat64[36] covariance\n",
    "geometry_msgs/msg/Twist": "Vector3 linear\nVector3 angular\n",
    "geometry_msgs/msg/TwistWithCovariance": "Twist twist\nfloat64[36] covariance\n",
    "nav_msgs/msg/Odometry": "std_msgs/Header header\nstring child_frame_id\n"
                             "geometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist\n",
    "nav_msgs/msg/Path": "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses\n",
    "rosgraph_msgs/msg/Clock": "builtin_interfaces/Time clock\n",
}


def write_tree(root: Path) -> Path:
    """The files as <root>/<package>/msg/<Name>.msg (zenoh-ros2-sdk's messages directory)."""
    for name, text in MSG_FILES.items():
        f = root / (name + ".msg")
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(text)
    return root

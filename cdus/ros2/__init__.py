"""The fleet's ROS 2 face (docs/ros2.md): rmw_zenoh's wire format written here, no ROS 2 installed.

``types`` (the message types, their RIHS01 hashes and definitions), ``cdr`` (their bytes),
``rmw`` (rmw_zenoh's keys, liveliness tokens, QoS and attachments), ``fleet`` (the fleet's
topics and messages), ``bridge`` (the process that publishes them), ``export`` (a run as MCAP).
"""

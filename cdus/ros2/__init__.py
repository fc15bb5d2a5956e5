"""How does the fleet look to ROS 2? rmw_zenoh's wire format written here, no ROS 2 installed (docs/ros2.md).

``types`` (the message types, their RIHS01 hashes and definitions), ``cdr`` (their bytes),
``rmw`` (rmw_zenoh's keys, liveliness tokens, QoS and attachments), ``fleet`` (the fleet's
topics and messages), ``bridge`` (the process that publishes them), ``export`` (a run as MCAP).
"""

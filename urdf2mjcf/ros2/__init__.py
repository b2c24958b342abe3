"""The ROS 2 server: a simulation served to a live ROS 2 graph over rmw_zenoh.

The wire format (:mod:`.keyexpr`, :mod:`.liveliness`, :mod:`.attachment`,
:mod:`.type_hash`) is plain Python; only the session needs ``eclipse-zenoh`` (the
``ros2`` extra). See docs/ros2.md.
"""

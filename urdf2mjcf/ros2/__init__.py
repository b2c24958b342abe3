"""The ROS 2 server: a simulation served to a live ROS 2 graph over rmw_zenoh.

The wire format is plain Python; only the session needs ``eclipse-zenoh`` (the ``ros2``
extra). See docs/ros2.md. The modules:

* the wire: :mod:`.keyexpr` (key expressions, QoS), :mod:`.liveliness` (graph tokens),
  :mod:`.attachment` (the 33 bytes on every sample), :mod:`.type_hash` (REP-2016),
  :mod:`.interfaces` (the ``.msg``/``.srv`` definitions spoken), :mod:`.session` (one
  node on one Zenoh session);
* what is served: :mod:`.server` (a model as mujoco_ros2_control serves one),
  :mod:`.world` (a model file or a bundle, with its rovers), :mod:`.controllers` and
  :mod:`.controller_file` (ros2_control's controllers, from the description or a
  user's YAML), :mod:`.trajectory_action` (FollowJointTrajectory), :mod:`.sensors`,
  :mod:`.scans` and :mod:`.cameras` (IMU, wrench, LaserScan, images) on the topics the
  description named (:mod:`.described`), :mod:`.rovers`
  (each MIRA3D rover under its namespace), :mod:`.live` (a run published while it runs);
* the command line: :mod:`.command` (``urdf2mjcf serve``) and :mod:`.options` (the
  transport options, declared once).
"""

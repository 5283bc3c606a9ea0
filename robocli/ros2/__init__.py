"""robocli for ROS 2, with no ROS installed: ROS 2 messages (CDR), and ROS 2 topics on
Zenoh the way ``rmw_zenoh_cpp`` lays them (:mod:`robocli.ros2.rmw`, :mod:`robocli.ros2.node`).
Needs the ``ros2`` extra (``rosbags``, ``xxhash``) and, on Zenoh, the ``zenoh`` extra."""

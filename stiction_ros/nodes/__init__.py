"""
The ROS 2 nodes: thin wrappers that wire the pure core to topics, timers and parameters.

Importing these modules needs rclpy; nothing in :mod:`stiction_ros` outside
this sub-package does.
"""

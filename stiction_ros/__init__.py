"""
stiction_ros: control-valve stiction models in live ROS 2 loops, and their diagnosis.

The core (models, plants, controllers, simulation, analysis) is plain
numpy/scipy and imports without rclpy; only ``stiction_ros.nodes`` needs ROS.
"""

__version__ = '0.1.0'

"""
stiction_ros: control-valve stiction models in live ROS 2 loops, and their diagnosis.

The core (models, plants, controllers, simulation, analysis) is plain
numpy/scipy and imports without rclpy; only ``stiction_ros.nodes`` needs ROS.
"""

__version__ = '0.1.0'

# Before NumPy loads OpenBLAS: the same kernels on every host (_blas.py).
from stiction_ros import _blas  # noqa: E402

_blas.pin()

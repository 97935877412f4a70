"""The simulation and analysis core imports, and runs, with ROS absent."""

import subprocess
import sys

PROBE = r"""
import importlib, pkgutil, sys

class NoRos:
    ROS = ('rclpy', 'rcl_interfaces', 'std_msgs', 'diagnostic_msgs', 'sensor_msgs',
           'rosgraph_msgs', 'builtin_interfaces', 'ament_index_python')

    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in self.ROS:
            raise ImportError(f'{name} blocked: the core must not need ROS')
        return None

sys.meta_path.insert(0, NoRos())
import stiction_ros
names = [m.name for m in pkgutil.walk_packages(stiction_ros.__path__, 'stiction_ros.')
         if not m.name.startswith('stiction_ros.nodes')]
for name in names:
    importlib.import_module(name)
from stiction_ros.models import create
assert create('kano', S=5, J=2).simulate([50, 60, 40]).shape == (3,)
print(len(names))
"""


def test_core_modules_import_without_ros():
    run = subprocess.run([sys.executable, '-c', PROBE], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert int(run.stdout.split()[-1]) >= 10

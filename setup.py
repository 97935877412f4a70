"""Build script of the stiction_ros ament_python package."""

from glob import glob
import os
import subprocess
import sys

from setuptools import find_packages, setup
from setuptools.command.install import install

package_name = 'stiction_ros'


class InstallAndPrecompile(install):
    """Install, then compile the numba kernels into the cache beside the installed files."""

    def run(self):
        """Install; then run stiction-precompile on the installed package."""
        super().run()
        # A wheel build installs into a staging root whose files move afterwards (and a
        # cache is stamped with each file's path and time), so only a direct install
        # (colcon build, setup.py install) is precompiled.
        if self.root or os.environ.get('STICTION_ROS_NO_PRECOMPILE'):
            return
        path = os.pathsep.join(filter(None, [self.install_lib, os.environ.get('PYTHONPATH')]))
        # The installed copy finds its config through the ament index just installed.
        ament = os.pathsep.join(filter(None, [self.install_data,
                                              os.environ.get('AMENT_PREFIX_PATH')]))
        # Run from the install: from the source folder (colcon's working directory)
        # python -m would import, and compile into, the source tree's copy.
        done = subprocess.run([sys.executable, '-m', 'stiction_ros.cli.precompile'],
                              env=dict(os.environ, PYTHONPATH=path, AMENT_PREFIX_PATH=ament),
                              cwd=self.install_lib,
                              check=False)
        if done.returncode != 0:
            print('stiction_ros: precompiling the kernels failed; the first start of each '
                  'node compiles them instead (5-10 s)', file=sys.stderr)


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench', 'bench.*']),
    # The learned stiction detector (make detector), read by numpy without pickle.
    package_data={package_name: ['resources/*.npz']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ] + [
        # One parameter file per loop node for each shipped case (ros2 param load /valve FILE).
        ('share/' + package_name + '/' + folder, glob(folder + '/*.yaml'))
        for folder in sorted(glob('config/params/*'))
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'PyYAML', 'matplotlib', 'mcap', 'numba',
                      'rich'],
    zip_safe=True,
    maintainer='stiction_ros developers',
    maintainer_email='dev@stiction-ros.invalid',
    description='Control-valve stiction models in live ROS 2 loops, and their diagnosis.',
    license='Apache-2.0',
    cmdclass={'install': InstallAndPrecompile},
    entry_points={
        'console_scripts': [
            'stiction-sim = stiction_ros.cli.sim:main',
            'stiction-study = stiction_ros.cli.study:main',
            'stiction-bag = stiction_ros.cli.bag:main',
            'stiction-analyze = stiction_ros.cli.analyze:main',
            'stiction-detector = stiction_ros.cli.detector:main',
            'stiction-cnn = stiction_ros.cli.cnn:main',
            'stiction-precompile = stiction_ros.cli.precompile:main',
            # Node executables, as `ros2 run stiction_ros <name>` finds them.
            'controller = stiction_ros.nodes.controller_node:main',
            'valve = stiction_ros.nodes.valve_node:main',
            'plant = stiction_ros.nodes.plant_node:main',
            'recorder = stiction_ros.nodes.recorder_node:main',
            'sim_clock = stiction_ros.nodes.sim_clock_node:main',
            'loop = stiction_ros.cli.loop:main',
            'loop_nodes = stiction_ros.nodes.composed:main',
            'analyzer = stiction_ros.nodes.analyzer_node:main',
        ],
    },
)

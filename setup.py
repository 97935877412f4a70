"""Build script of the stiction_ros ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'stiction_ros'

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
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'PyYAML', 'matplotlib', 'mcap', 'numba'],
    zip_safe=True,
    maintainer='stiction_ros developers',
    maintainer_email='dev@stiction-ros.invalid',
    description='Control-valve stiction models in live ROS 2 loops, and their diagnosis.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'stiction-sim = stiction_ros.cli.sim:main',
            'stiction-study = stiction_ros.cli.study:main',
            'stiction-bag = stiction_ros.cli.bag:main',
            'stiction-analyze = stiction_ros.cli.analyze:main',
            'stiction-detector = stiction_ros.cli.detector:main',
            # Node executables, as `ros2 run stiction_ros <name>` finds them.
            'controller = stiction_ros.nodes.controller_node:main',
            'valve = stiction_ros.nodes.valve_node:main',
            'plant = stiction_ros.nodes.plant_node:main',
            'recorder = stiction_ros.nodes.recorder_node:main',
            'sim_clock = stiction_ros.nodes.sim_clock_node:main',
            'loop = stiction_ros.cli.loop:main',
            'analyzer = stiction_ros.nodes.analyzer_node:main',
        ],
    },
)

"""
Bring up a loop from a loop description on a ROS 2 install: ``ros2 launch``.

The same as the ``loop`` executable, with the same parameter mapping
(:mod:`stiction_ros.sim.ros_params`)::

    ros2 launch stiction_ros loop.launch.py case:=undershoot
    ros2 launch stiction_ros loop.launch.py namespace:=loop2 rtf:=100.0 record:=/tmp/bag
    ros2 launch stiction_ros loop.launch.py state_dir:=/tmp/loop_state   # respawn, resume

With ``rtf`` > 0 the nodes run on a lockstep ``/clock`` from ``sim_clock``
(which ends the run after the file's duration); with ``record`` the
recorder writes sp, op, mv, pv to that bag directory.
"""

import os

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction
from launch.actions import RegisterEventHandler
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from stiction_ros.resources import config_file
from stiction_ros.sim.loop_config import load_loop
from stiction_ros.sim.ros_params import loop_extras, LOOP_NODES, node_parameters

EXECUTABLES = {'plant': 'plant', 'controller': 'controller', 'valve': 'valve',
               'recorder': 'recorder', 'sim_clock': 'sim_clock'}


def _nodes(context):
    arg = {k: LaunchConfiguration(k).perform(context) for k in
           ('config', 'case', 'namespace', 'rtf', 'record')}
    cfg = load_loop(arg['config'] or config_file('concentration_loop.yaml'), arg['case'] or None)
    rtf = float(arg['rtf'] or 0.0)
    params = node_parameters(cfg)
    params.update(loop_extras(cfg, rtf=rtf, record=arg['record'] or None))
    sim = {'use_sim_time': rtf > 0.0}
    state = LaunchConfiguration('state_dir').perform(context)
    for name in LOOP_NODES:
        if state:
            params[name]['state_file'] = os.path.join(state, f'{name}.state')
    # A loop node that dies is started again and resumes from its state file, as the
    # loop executable's --respawn does.
    nodes = {name: Node(package='stiction_ros', executable=EXECUTABLES[name], name=name,
                        namespace=arg['namespace'], output='screen',
                        respawn=bool(state) and name in LOOP_NODES, respawn_delay=1.0,
                        parameters=[p] if name == 'sim_clock' else [p, sim])
             for name, p in params.items()}
    actions = list(nodes.values())
    if 'sim_clock' in nodes:
        # The clock exits at the end of the run: take the loop down with it.
        actions.append(RegisterEventHandler(OnProcessExit(
            target_action=nodes['sim_clock'], on_exit=[EmitEvent(event=Shutdown())])))
    return actions


def generate_launch_description():
    """Declare the arguments; the nodes are built from the loop file at launch time."""
    return LaunchDescription([
        DeclareLaunchArgument('config', default_value='',
                              description='loop description (default: concentration_loop.yaml)'),
        DeclareLaunchArgument('case', default_value='', description='case in the loop file'),
        DeclareLaunchArgument('namespace', default_value='', description='namespace of the loop'),
        DeclareLaunchArgument('rtf', default_value='0.0',
                              description='real-time factor of a sim clock; 0: wall time'),
        DeclareLaunchArgument('record', default_value='', description='bag directory to record'),
        DeclareLaunchArgument('state_dir', default_value='',
                              description='where the loop nodes keep their state; set, a node '
                              'that dies is respawned and resumes from it'),
        OpaqueFunction(function=_nodes),
    ])

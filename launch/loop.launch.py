"""
Bring up a loop from a loop description on a ROS 2 install: ``ros2 launch``.

The same as the ``loop`` executable, with the same parameter mapping
(:mod:`stiction_ros.sim.launch_plan` works out the nodes; this file only
turns them into launch actions)::

    ros2 launch stiction_ros loop.launch.py case:=undershoot
    ros2 launch stiction_ros loop.launch.py config:=hidden_effect_loop.yaml duration:=600
    ros2 launch stiction_ros loop.launch.py namespace:=loop2 rtf:=100.0 record:=/tmp/bag
    ros2 launch stiction_ros loop.launch.py set:='valve.S=7, valve.J=2' log_level:=warn
    ros2 launch stiction_ros loop.launch.py state_dir:=/tmp/loop_state   # respawn, resume

``config`` is a path or the name of a shipped loop file.  With ``rtf`` > 0
the nodes run on a lockstep clock from ``sim_clock``, which ends the run
after ``duration``; on wall time the launch shuts down after ``duration``.
With ``record`` the recorder writes sp, op, mv, pv to that bag directory.
The clock topic is ``/clock`` without a namespace and ``<namespace>/clock``
in one, so that several loops run on one graph, each on its own time.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, OpaqueFunction
from launch.actions import RegisterEventHandler, TimerAction
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from stiction_ros.sim.launch_plan import launch_plan

ARGUMENTS = (
    ('config', 'concentration_loop.yaml',
     'loop description: a path, or the name of a shipped file in share/stiction_ros/config'),
    ('case', '', 'case in the loop file'),
    ('namespace', '', 'namespace of the loop'),
    ('rtf', '0.0', 'real-time factor of a sim clock; 0: wall time'),
    ('duration', '', 'seconds of loop time (default: from the file)'),
    ('set', '', "overrides of the loop file, e.g. 'valve.S=7, valve.J=2'"),
    ('log_level', 'info', 'log level of every node: debug, info, warn, error, fatal'),
    ('record', '', 'bag directory to record'),
    ('state_dir', '', 'where the loop nodes keep their state; set, a node that dies is '
     'respawned and resumes from it'),
)


def _nodes(context):
    arg = {name: LaunchConfiguration(name).perform(context) for name, _, _ in ARGUMENTS}
    plan = launch_plan(config=arg['config'], case=arg['case'], rtf=arg['rtf'],
                       record=arg['record'], state_dir=arg['state_dir'],
                       duration=arg['duration'], settings=arg['set'],
                       log_level=arg['log_level'])
    # Every node's /clock (the sim clock's publisher, each time source) goes to the
    # relative 'clock', which rcl resolves in the node's namespace: <namespace>/clock,
    # also under an including file's PushRosNamespace, and /clock with none.  Two loops
    # on one /clock would drive each other's time.
    nodes = {spec.name: Node(package='stiction_ros', executable=spec.name, name=spec.name,
                             namespace=arg['namespace'], output='screen',
                             respawn=spec.respawn, respawn_delay=1.0,
                             parameters=[spec.parameters, {'use_sim_time': spec.sim_time}],
                             remappings=[('/clock', 'clock')],
                             ros_arguments=plan.ros_arguments)
             for spec in plan.nodes}
    actions = list(nodes.values())
    end = [EmitEvent(event=Shutdown(reason='the loop ran its duration'))]
    if 'sim_clock' in nodes:
        # The clock exits at the end of the run: take the loop down with it.
        actions.append(RegisterEventHandler(OnProcessExit(
            target_action=nodes['sim_clock'], on_exit=end)))
    elif plan.end_after is not None:
        actions.append(TimerAction(period=plan.end_after, actions=end))
    return actions


def generate_launch_description():
    """Declare the arguments; the nodes are built from the loop file at launch time."""
    return LaunchDescription(
        [DeclareLaunchArgument(name, default_value=default, description=text)
         for name, default, text in ARGUMENTS] + [OpaqueFunction(function=_nodes)])

"""
``loop_nodes``: plant, controller and valve as three nodes in one process, on one executor.

ROS 2 composition for a Python loop: the same node classes, sharing one
process and one single-threaded executor, so a sample's three actions are
callbacks of one thread instead of wake-ups of three processes competing for
the cores (docs/BENCHMARKS.md compares their timing).  Messages between them
still go through DDS, so the recorder and ``ros2 topic`` see the loop as
before.  Parameters come from a params file with one section per node
(``loop --composed`` writes it); ``-p`` arguments would reach all three.

Example::

    ros2 run stiction_ros loop_nodes --ros-args --params-file loop.params.yaml
"""

import sys

from stiction_ros.nodes.controller_node import ControllerNode
from stiction_ros.nodes.plant_node import PlantNode
from stiction_ros.nodes.run import run
from stiction_ros.nodes.valve_node import ValveNode

# In the order of their phases in each sample.
NODES = (PlantNode, ControllerNode, ValveNode)


def build():
    """Return the loop's three nodes; a node that cannot start stops the others."""
    built = []
    try:
        for cls in NODES:
            built.append(cls())
    except BaseException:
        for node in built:
            node.destroy_node()
        raise
    return built


def main(args=None):
    """Run the three loop nodes in this process."""
    return run(build, args, 'loop_nodes', NODES)


if __name__ == '__main__':
    sys.exit(main())

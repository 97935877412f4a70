"""
Entry point shared by every node executable: init, spin, clean shutdown.

SIGINT and SIGTERM end the spin through rclpy's signal handlers; the node's
``close()`` (the recorder finalises its bag there) runs before the context is
shut down.  A node that cannot start prints one line saying why and exits 2.
"""

import gc
import sys

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from stiction_ros.models.base import ModelError
from stiction_ros.nodes.sampled import StartupError


def run(factory, args=None, prog='node'):
    """
    Create the node with ``factory()`` and spin it until shutdown; return an exit code.

    A node with a ``finished`` future is spun until it completes, and its
    result is the exit code.
    """
    rclpy.init(args=args)
    try:
        node = factory()
    except (StartupError, ModelError, ParameterException, ValueError) as err:
        print(f'{prog}: error: {err}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    code = 0
    # Everything built so far lives for the whole run: move it out of the collector's
    # way, so a collection of the few short-lived objects of a sample stays short.
    gc.collect()
    gc.freeze()
    try:
        finished = getattr(node, 'finished', None)
        if finished is None:
            rclpy.spin(node)
        else:
            rclpy.spin_until_future_complete(node, finished)
            code = finished.result() if finished.done() else 1
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RCLError:
        # A callback that was running when SIGINT/SIGTERM shut the context down fails
        # to publish; that is the shutdown, not an error.
        if rclpy.ok():
            raise
    finally:
        close = getattr(node, 'close', None)
        if close is not None:
            close()
        node.destroy_node()
        rclpy.try_shutdown()
    return code

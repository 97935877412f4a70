"""
Entry point shared by every node executable: init, spin, clean shutdown.

The first SIGINT or SIGTERM ends the spin: rclpy's signal handlers shut the
context down and wake the executor.  The shutdown then runs to its end
whatever signals follow: the node's ``close()`` (the recorder finalises its
bag there), ``destroy_node()``, the context shutdown, and exit status 0.

Python's own SIGINT handler would raise KeyboardInterrupt wherever the signal
lands: inside a callback halfway through a write, or inside ``close()`` when
``ros2 launch`` forwards its SIGINT right after the one the whole process
group got from the terminal or a supervisor (the bag was left unreadable and
the process died by the signal).  So :func:`run` puts a handler in its place
that only notes the signal (rclpy's handlers chain to it), and ignores both
signals from the first step of the shutdown on.  A signal during start-up is
noted too, and the node stops as soon as it exists.

Once the nodes are closed (their work, the bag included, is done), what is
left is DDS's teardown, which has been seen to stall under load: a plant,
its summary printed, still running 30 s after the stop.  A watchdog
(:func:`end_teardown_within`) then ends the process with the run's status
after ``TEARDOWN_S``, with every thread's stack in the log, before a
launcher's SIGKILL would take the status away.  A stall that holds the GIL
(rclpy holds it in every call into DDS but a wait) starves that watchdog;
faulthandler then prints the stacks ``BACKSTOP_S`` later, and a kernel timer
(:mod:`stiction_ros.nodes.exit_timer`) ends the process with the run's status,
through interpreter exit too.

A node that cannot start prints one line saying why and exits 2.

SIGUSR1 prints every thread's stack to stderr and the node goes on: a node
that hangs says where, to an operator (``kill -USR1 PID``) or to a launcher
about to SIGKILL it (the shutdown tests' runner does so).  Printed by
faulthandler's C handler, it needs no GIL, so a stall inside C code shows too.
"""

from collections.abc import Callable, Sequence
import faulthandler
import gc
import os
import signal
import sys
import threading
from typing import Any

import rclpy
from rclpy._rclpy_pybind11 import RCLError
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import get_current_signal_handlers_options, install_signal_handlers
from rclpy.signals import SignalHandlerOptions, uninstall_signal_handlers
from stiction_ros.app.docstrings import plain
from stiction_ros.models.base import ModelError
from stiction_ros.nodes.exit_timer import exit_after
from stiction_ros.nodes.params import help_entry
from stiction_ros.nodes.sampled import SampledNode, StartupError
from stiction_ros.nodes.sampled_params import common_params

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
# Below ros2 launch's 5 s between its SIGINT and its SIGTERM (which a closing node
# ignores), and its SIGKILL 5 s after that; a teardown takes well under 1 s.
TEARDOWN_S = 3.0
# The watchdog is a Python thread, which a teardown stalled inside C code with the
# GIL held starves; faulthandler's thread and a kernel timer need no GIL.  This much
# later faulthandler prints every stack, and STACKS_S after it the timer ends the
# process with the run's status, through interpreter exit too.
BACKSTOP_S = 4.0
# Between faulthandler's stacks and the backstop's exit: time to write them out.
STACKS_S = 0.25


class StopRequest:
    """A signal handler that notes the first SIGINT/SIGTERM instead of raising."""

    def __init__(self):
        self.signum = None

    def __call__(self, signum, frame):
        """Note the signal; ending the spin is the work of rclpy's handler, which chains here."""
        if self.signum is None:
            self.signum = signum


def ignore_stop_signals():
    """Ignore SIGINT and SIGTERM from now on; calling it again changes nothing."""
    # rclpy's C handler goes first: it would go on shutting contexts down and chaining
    # to the handler it found, and uninstalling it later would put that one back.  Only
    # if installed: rclpy's uninstall sets SIG_DFL for a moment when it has nothing to
    # restore, and a signal in that moment would kill the process.
    if get_current_signal_handlers_options() != SignalHandlerOptions.NO:
        uninstall_signal_handlers()
    for signum in STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)


def wants_help(args=None):
    """Return True if ``-h`` or ``--help`` comes before any ``--ros-args``."""
    argv = sys.argv[1:] if args is None else list(args)[1:]
    if '--ros-args' in argv:
        argv = argv[:argv.index('--ros-args')]
    return '-h' in argv or '--help' in argv


def params_help(nodes: Sequence[Any]) -> str:
    """
    Return the parameters of ``nodes`` (node classes) as ``--help`` lists them.

    One node: each of its parameters.  Several in one process (``loop_nodes``):
    each node's own, then the names the loop nodes share, once.
    """
    if len(nodes) == 1:
        return ('Parameters (-p NAME:=VALUE, or --params-file FILE; on a running\n'
                'node `ros2 param describe` shows the same):\n'
                + '\n'.join(help_entry(p) for p in nodes[0].declared_params()))
    parts = []
    for cls in nodes:
        parts.append(f'Parameters of {cls.KIND} (its section of the params file):')
        parts += [help_entry(p) for p in cls.own_params()]
    if all(issubclass(cls, SampledNode) for cls in nodes):
        shared = ', '.join(p.name for p in common_params(0.5))
        parts.append(f'Every loop node also has: {shared} ('
                     + ', '.join(f'{cls.KIND} --help' for cls in nodes) + ' describe them).')
    return '\n'.join(parts)


def help_text(factory: Callable, prog: str, nodes: Sequence[Any] | None = None) -> str:
    """
    Return the executable's help: its module's docstring, its parameters, how to run it.

    ``nodes`` are the node classes the factory builds, when it is not one itself.
    """
    doc = plain((sys.modules[factory.__module__].__doc__ or '').strip())
    nodes = nodes or ((factory,) if hasattr(factory, 'declared_params') else ())
    params = f'\n\n{params_help(nodes)}' if nodes else ''
    return (f'usage: {prog} [-h] [--ros-args [-p NAME:=VALUE] [--params-file FILE] '
            '[-r FROM:=TO] [--log-level LEVEL]]\n\n'
            f'{doc}{params}\n\n'
            'Exit status: 0 after a clean stop (SIGINT/SIGTERM), 2 if the node cannot start.\n'
            "SIGUSR1 prints every thread's stack to stderr; the node goes on.")


def run(factory: Callable, args: list[str] | None = None, prog: str = 'node',
        nodes: Sequence[Any] | None = None) -> int:
    """
    Create the node with ``factory()`` and spin it until shutdown; return an exit code.

    ``factory`` may return several nodes, spun on one executor (composition).
    A node with a ``finished`` future is spun until it completes, and its
    result is the exit code (0 when a signal stopped it first).
    ``-h``/``--help`` prints :func:`help_text` (with the parameters of
    ``nodes``, the classes the factory builds, or of the factory when it is
    a node class) and starts nothing.
    """
    if wants_help(args):
        try:
            print(help_text(factory, prog, nodes), flush=True)
        except BrokenPipeError:
            # Read by `head` or a pager that quit: nothing more to say.
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    # Before anything can hang: a stall at start-up is worth its stacks as well.
    faulthandler.register(signal.SIGUSR1, file=sys.stderr, all_threads=True)
    stop = StopRequest()
    for signum in STOP_SIGNALS:
        signal.signal(signum, stop)
    # rclpy's handlers would shut the context down under a node still being built, whose
    # next create_* call would then fail: they go in once the node exists.
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = factory()
    except (StartupError, ModelError, ParameterException, ValueError) as err:
        ignore_stop_signals()
        print(f'{prog}: error: {err}', file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    code = 0
    # Everything built so far lives for the whole run: move it out of the collector's
    # way, so a collection of the few short-lived objects of a sample stays short.
    gc.collect()
    gc.freeze()
    # Installed after the node is built, so they chain to ``stop``; a signal that came
    # before this line is in ``stop`` and skips the spin, one after it ends the spin.
    install_signal_handlers(SignalHandlerOptions.ALL)
    try:
        finished = getattr(node, 'finished', None)
        if stop.signum is not None:
            pass                # stopped during start-up
        elif isinstance(node, list):
            executor = SingleThreadedExecutor()
            for one in node:
                executor.add_node(one)
            executor.spin()
        elif finished is None:
            rclpy.spin(node)
        else:
            rclpy.spin_until_future_complete(node, finished)
            if finished.done():
                code = finished.result()
            elif stop.signum is None:
                code = 1    # the context was shut down, and not by a signal
    except ExternalShutdownException:
        pass
    except RCLError:
        # A callback that was running when SIGINT/SIGTERM shut the context down fails
        # to publish; that is the shutdown, not an error.
        if rclpy.ok():
            raise
    finally:
        ignore_stop_signals()
        nodes = node if isinstance(node, list) else [node]
        # An exception on its way out (a callback's) fails the run even if teardown stalls.
        status = [code if sys.exc_info()[1] is None else 1]
        try:
            _close_all(nodes)
        except BaseException:
            status[0] = 1
            raise
        finally:
            watchdog = end_teardown_within(TEARDOWN_S, prog, status)
            for one in nodes:
                one.destroy_node()
            rclpy.try_shutdown()
            watchdog.cancel()
    return code


def end_teardown_within(seconds: float, prog: str, status: list) -> threading.Timer:
    """
    Start a timer that ends the process with ``status[0]`` if teardown outlasts ``seconds``.

    It prints one line and every thread's stack to stderr first.  The caller
    cancels it when the teardown is done.  A teardown that stalls while
    holding the GIL holds this timer back as well, so faulthandler prints
    every stack ``BACKSTOP_S`` later and a kernel timer ends the process
    with ``status[0]`` (as it is now) ``STACKS_S`` after that; faulthandler
    ends it itself, with status 1, where there is no such timer.  Both stay
    armed through interpreter exit, where a stall would otherwise wait for a
    launcher's SIGKILL: call this only in a process that is about to end.
    """
    backstop = seconds + BACKSTOP_S
    # The stacks at the backstop, then the exit with the run's status a moment later; where
    # the C library has no such timer, faulthandler ends the process itself (status 1).
    # Never raise here, inside run()'s teardown: an exit status is a byte anyway.
    hard = exit_after(backstop + STACKS_S,
                      status[0] & 0xFF if isinstance(status[0], int) else 1)
    faulthandler.dump_traceback_later(backstop, exit=not hard, file=sys.stderr)

    def _end():
        print(f'{prog}: DDS teardown still running {seconds:g} s after the node closed; '
              f'exiting without it (status {status[0]}); stacks follow', file=sys.stderr,
              flush=True)
        faulthandler.dump_traceback(sys.stderr, all_threads=True)
        sys.stdout.flush()
        os._exit(status[0])
    timer = threading.Timer(seconds, _end)
    timer.daemon = True
    timer.start()
    return timer


def _close_all(nodes):
    """Close every node (the recorder finalises its bag), even if one before it fails."""
    failed = None
    for one in nodes:
        close = getattr(one, 'close', None)
        try:
            if close is not None:
                close()
        except Exception as err:  # noqa: B902 - the others still close; it is raised after
            failed = failed or err
    if failed is not None:
        raise failed

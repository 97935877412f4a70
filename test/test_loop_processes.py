"""
The loop launcher notices a node that stops, whatever its exit code.

Real processes, no ROS: a node asked to stop by SIGTERM exits 0, and the
launcher had taken that as no failure, so a recorder stopped so left the run
going on with nothing recorded and nothing said.
"""

import sys
import time

from stiction_ros.cli.loop import Processes


def _wait(procs, name):
    deadline = time.monotonic() + 10.0
    while procs.procs[name][0].poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)


def test_any_node_but_the_sim_clock_that_exits_has_stopped(tmp_path):
    procs = Processes(tmp_path)
    quiet = [sys.executable, '-c', 'import time; time.sleep(30)']
    done = [sys.executable, '-c', 'raise SystemExit(0)']
    try:
        procs.start('valve', quiet, None)
        procs.start('sim_clock', done, None)
        _wait(procs, 'sim_clock')
        # The clock ends the run by exiting 0: not a stop.
        assert procs.failed() is None
        procs.start('recorder', done, None)
        _wait(procs, 'recorder')
        assert procs.failed() == 'recorder'
    finally:
        procs.stop(['valve', 'recorder', 'sim_clock'])

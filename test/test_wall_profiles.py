"""
Profiles on wall time count from the run's start, not from 1970.

On wall time a node's sample index counts from the Unix epoch; a set-point
step 'at 1.5 s' read on that clock was decades past before the node started,
so a live loop on wall time never took its steps.  A real controller node,
over DDS: from its first sample, and from a ``start_time`` the loop launcher
gives every node.
"""

import signal
import time

import pytest
from ros_helpers import start_node, stop, wait_for

pytestmark = pytest.mark.ros


def test_a_set_point_step_on_wall_time_comes_when_the_profile_says(probe, tmp_path):
    # SP 1 from 0 s, 2 from 5 s: long enough that discovery on a busy machine (a second or
    # two) leaves some of the first value to see.
    steps = [0.0, 1.0, 5.0, 2.0]
    base = {'sample_time': 0.1, 'setpoint_profile.type': 'steps',
            'setpoint_profile.steps': steps, 'use_sim_time': False}
    for ns in ('/own', '/given'):
        probe.listen(f'{ns}/sp')
    own = start_node('controller', base, '/own', str(tmp_path))
    # The launcher's start 100 s ago: the step is long past when this node starts.
    given = start_node('controller', {**base, 'start_time': time.time() - 100.0}, '/given',
                       str(tmp_path))
    try:
        wait_for(lambda: 2.0 in probe.values('/own/sp')
                 and len(probe.values('/given/sp')) >= 30, timeout=60.0, what='the step')
    finally:
        assert stop(own) == 0 and stop(given) == 0
    sp = probe.values('/own/sp')
    # Counted from its first sample: 1 first, then the step to 2, 50 samples later
    # (the first messages may be lost to discovery, so only the order is exact).
    assert sp[0] == 1.0 and sp[-1] == 2.0 and sorted(sp) == sp
    assert 1 <= sp.count(1.0) <= 50
    assert set(probe.values('/given/sp')) == {2.0}


def test_a_restarted_node_goes_on_with_its_profile_on_wall_time(probe, tmp_path):
    # No start_time (ros2 run): the first run's origin is kept in the state file, so a
    # node killed after the step and restarted does not take it again from the start.
    base = {'sample_time': 0.1, 'setpoint_profile.type': 'steps',
            'setpoint_profile.steps': [0.0, 1.0, 3.0, 2.0], 'use_sim_time': False,
            'state_file': str(tmp_path / 'controller.state')}
    probe.listen('/again/sp')
    first = start_node('controller', base, '/again', str(tmp_path))
    try:
        wait_for(lambda: 2.0 in probe.values('/again/sp'), timeout=30.0, what='the step')
    finally:
        stop(first, signal.SIGKILL)
    seen = len(probe.values('/again/sp'))
    second = start_node('controller', base, '/again', str(tmp_path))
    try:
        wait_for(lambda: len(probe.values('/again/sp')) >= seen + 10, timeout=30.0,
                 what='10 set points after the restart')
    finally:
        assert stop(second) == 0
    assert set(probe.values('/again/sp')[seen:]) == {2.0}

"""
On sim time a node acts on its sample's input even when the message comes late.

The lockstep clock moves on once a message reached the clock, which does not
prove it reached the node that uses it; on a busy machine it sometimes had not,
and the live loop then drifted from the offline simulator.  Here the test is
the clock and the controller: it brings a valve's clock to the valve's action
instant, and only then, a wall-time while later, sends that sample's OP.  The
valve must wait for it (``input_wait``) and move on that OP; with the wait off
it acts on the held one and says so on ``held_inputs``.  A sample whose OP never
comes is acted on once ``input_wait`` has passed, on the held value.
"""

import time

from diagnostic_msgs.msg import KeyValue
import numpy as np
import pytest
from ros_helpers import start_node, stop, wait_for
from stiction_ros.models import Kano
from stiction_ros.nodes.sampled import DATA_QOS

pytestmark = pytest.mark.ros

TS = 0.1
VALVE = {'model': 'kano', 'S': 4.0, 'J': 1.5, 'sample_time': TS, 'initial_position': 50.0}
LATE = 0.15         # wall seconds between the action instant and the OP of that sample


def sim_time_valve(probe, ns, log_dir, **params):
    """Start a valve on sim time, matched with the test; return (process, held marks)."""
    marks = []
    probe.node.create_subscription(KeyValue, f'{ns}/held_inputs',
                                   lambda m: marks.append(int(m.value.split()[0])), DATA_QOS)
    probe.listen(f'{ns}/mv')
    op_pub = probe.publisher(f'{ns}/op')
    proc = start_node('valve', dict(VALVE, **params), ns, str(log_dir),
                      extra=['-p', 'use_sim_time:=true'])
    try:
        wait_for(lambda: op_pub.get_subscription_count() >= 1
                 and probe.node.count_publishers(f'{ns}/mv') >= 1,
                 timeout=30.0, what='the valve to match the test')
    except AssertionError:
        stop(proc)
        raise
    time.sleep(0.5)
    return proc, marks


@pytest.mark.parametrize('wait', [0.5, 0.0])
def test_a_late_input_is_waited_for_on_sim_time(probe, tmp_path, wait):
    ns = f'/inwait{int(wait * 10)}'
    proc, marks = sim_time_valve(probe, ns, tmp_path, input_wait=wait)
    k0 = 1000
    try:
        ops = 50.0 + 10.0 * np.sin(2 * np.pi * np.arange(30) / 15)
        acted_after = []
        for i, op in enumerate(ops):
            k = k0 + i
            before = len(probe.values(f'{ns}/mv'))
            for slot in range(4):            # up to the valve's action instant, 3/4
                probe.publish_clock(k * TS + slot * TS / 4)
                time.sleep(0.005)
            start = time.monotonic()
            time.sleep(LATE)
            if i != 20:                      # sample 20's OP never comes
                probe.publish(f'{ns}/op', op)
            wait_for(lambda: len(probe.values(f'{ns}/mv')) > before, timeout=10.0,
                     what=f'the valve to act at sample {k}')
            acted_after.append(time.monotonic() - start)
            time.sleep(0.05)                 # the OP reaches the valve before the next tick
        mv = np.array(probe.values(f'{ns}/mv'))
        assert proc.poll() is None
    finally:
        assert stop(proc) == 0, (tmp_path / 'valve.log').read_text()
    assert len(mv) == len(ops)
    used = ops.copy()
    used[20] = ops[19]
    if wait > 0:
        # Every sample moved on its own OP, as the offline model does...
        expected = Kano(S=4.0, J=1.5).simulate(used, y0=50.0)
        assert np.array_equal(mv, expected), np.flatnonzero(mv != expected)
        # ...and only the sample without one is marked, after the wait was over.
        wait_for(lambda: marks == [k0 + 20], timeout=5.0, what=f'one mark, got {marks}')
        assert acted_after[20] >= 0.8 * wait, acted_after[20]
        assert 'waited for an input at' in (tmp_path / 'valve.log').read_text()
    else:
        # Without the wait the valve acts at the instant on the previous OP: one
        # sample late throughout, and every sample is marked as held.
        late = Kano(S=4.0, J=1.5).simulate(used[:-1], y0=50.0)
        assert mv[0] == 50.0 and np.array_equal(mv[1:], late), np.flatnonzero(mv[1:] != late)
        wait_for(lambda: len(marks) >= len(ops) - 2, timeout=5.0,
                 what=f'a mark per sample, got {marks}')


def test_an_input_that_comes_before_the_clock_catches_up_is_not_held(probe, tmp_path):
    """
    The OP of sample k can reach the valve before the /clock ticks that lead to k do.

    The valve's clock then still reads sample k - 1 when OP(k) comes; dated by
    that clock it looked a sample late, and the lockstep demo warned of a held
    OP although nothing was lost.  Here every OP is sent before its clock ticks.
    """
    ns = '/clock_behind'
    proc, marks = sim_time_valve(probe, ns, tmp_path)
    k0 = 500
    try:
        ops = 50.0 + 10.0 * np.sin(2 * np.pi * np.arange(20) / 10)
        for i, op in enumerate(ops):
            k = k0 + i
            before = len(probe.values(f'{ns}/mv'))
            probe.publish(f'{ns}/op', op)
            time.sleep(0.05)                 # it reaches the valve, its clock at k - 1
            for slot in range(4):
                probe.publish_clock(k * TS + slot * TS / 4)
                time.sleep(0.005)
            wait_for(lambda: len(probe.values(f'{ns}/mv')) > before, timeout=10.0,
                     what=f'the valve to act at sample {k}')
        mv = np.array(probe.values(f'{ns}/mv'))
    finally:
        assert stop(proc) == 0, (tmp_path / 'valve.log').read_text()
    assert marks == []
    assert np.array_equal(mv, Kano(S=4.0, J=1.5).simulate(ops, y0=50.0))
    assert 'none on a held input' in (tmp_path / 'valve.log').read_text()

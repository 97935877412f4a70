"""
Bad messages at the nodes: rejected, the last good value held, counted and reported.

The rules (``InputGuard``) alone, then a real valve node fed NaN, infinities and
an absurd value over DDS, watched on its ``mv`` and on its namespace's ``diagnostics``.
"""

import math
import time

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
from ros_helpers import start_node, stop, wait_for
from stiction_ros.nodes.input_guard import ERROR, InputGuard, OK, WARN

pytestmark = pytest.mark.ros


def test_guard_rejects_what_is_not_a_measurement_and_says_when_input_goes_stale():
    g = InputGuard('op', limit=1e3, stale_after=2.0)
    assert g.status(0.0)[0] == WARN  # nothing yet
    assert g.check(42.0, 1.0)
    for bad in (math.nan, math.inf, -math.inf, 1e300, -1001.0):
        assert not g.check(bad, 1.5)
    level, message, values = g.status(1.6)
    assert level == WARN and 'rejected 5' in message and values['last_good'] == '42.0'
    assert g.status(1.7)[0] == OK  # reported once; nothing new since
    level, message, _ = g.status(3.1)
    assert level == ERROR and 'stale' in message and '42' in message
    assert 'rejected' not in message
    assert not g.check(math.nan, 3.15)
    level, message, _ = g.status(3.2)
    assert level == ERROR and 'stale' in message and 'rejected 1' in message
    assert g.check(-1000.0, 3.3) and g.status(3.4)[0] == OK


def test_a_valve_node_holds_its_position_through_nan_inf_and_absurd_op(probe, tmp_path):
    ns = '/bad'
    probe.listen(f'{ns}/mv')
    diags = []
    probe.node.create_subscription(DiagnosticArray, f'{ns}/diagnostics',
                                   lambda m: diags.extend(m.status), 10)
    valve = start_node('valve', {'sample_time': 0.05, 'model': 'kano', 'S': 1.0, 'J': 0.5,
                                 'stale_after': 1.0, 'input_limit': 1000.0}, ns, str(tmp_path))
    try:
        wait_for(lambda: len(probe.values(f'{ns}/mv')) > 3, what='valve output')

        sent = []

        def moved():
            # Alternate OP 50 and 60 until the valve has matched and taken the step to 60
            # (an OP sent before discovery is lost).
            sent.append(60.0 if len(sent) % 20 >= 10 else 50.0)
            probe.publish(f'{ns}/op', sent[-1])
            return abs(probe.values(f'{ns}/mv')[-1] - 59.75) < 1e-9 and sent[-1] == 60.0
        wait_for(moved, what='the valve at the good OP')
        for _ in range(5):
            probe.publish(f'{ns}/op', 60.0)
            time.sleep(0.02)
        time.sleep(0.2)
        n_good = len(probe.values(f'{ns}/mv'))
        for bad in (math.nan, math.inf, -math.inf, 1e300, 5000.0):
            probe.publish(f'{ns}/op', bad)
            time.sleep(0.06)
        wait_for(lambda: len(probe.values(f'{ns}/mv')) > n_good + 10, what='more samples')
        after = np.array(probe.values(f'{ns}/mv')[n_good:])
        # Held, not moved by any of them, and nothing non-finite propagated.
        assert np.all(after == 59.75), after
        # WARN, or ERROR if the report came after stale_after (nothing valid since).
        # (The reports are once a second: the five may be split over two of them.)
        wait_for(lambda: any(s.level != OK.to_bytes(1, 'little') and 'rejected' in s.message
                             and {'rejected_total': '5'}.items()
                             <= {kv.key: kv.value for kv in s.values}.items()
                             for s in diags if s.name.endswith('valve: op')),
                 what='a diagnostic naming the rejected values')
        # Then no OP at all: the input goes stale and says so.
        wait_for(lambda: any(s.level == ERROR.to_bytes(1, 'little') and 'stale' in s.message
                             for s in diags if s.name.endswith('valve: op')),
                 timeout=10.0, what='an ERROR diagnostic for a stale op')
        assert all(s.name == f'{ns}/valve: op' for s in diags if s.name.endswith('valve: op'))
    finally:
        assert stop(valve) == 0
    log = (tmp_path / 'valve.log').read_text()
    assert 'ignored op = nan' in log and 'holding the last good value' in log
    assert '5 inputs rejected' in log


def test_a_node_that_acted_before_its_input_came_says_so_at_shutdown(tmp_path):
    # No OP publisher at all: every sample acted on is one before any OP came, and
    # the summary counts them rather than say 'none on a held input'.
    valve = start_node('valve', {'sample_time': 0.05, 'model': 'kano', 'S': 1.0, 'J': 0.5},
                       '/unheard', str(tmp_path))
    log = tmp_path / 'valve.log'
    wait_for(lambda: log.exists() and 'Kano' in log.read_text(), timeout=30, what='the valve')
    time.sleep(0.5)
    assert stop(valve) == 0
    text = log.read_text()
    assert 'before any op came' in text, text
    assert 'none on a held input' not in text

"""
Lost and late messages in a live loop: reported, marked in the bag, left out by the analyzer.

The valve's fault injection (``inject_*`` parameters, as ``loop --inject``
sets them) loses 10 % of the OP messages on their way in and delays the rest
by up to 0.3 of a sample, in order, so that some arrive after the valve has
acted.  The valve then acts on the OP it held: it
reports that on ``/diagnostics`` and publishes ``held_inputs`` with the
value it used, which the recorder records.  In the bag, ``op`` is what the
controller sent, so at a held sample the recorded OP is not what the valve
used; the analyzer puts the used value in its place (and excludes the
samples where the plant or the controller held an input), and the true
valve model then fits the recorded MV far better than the signals as
recorded.
"""

import time

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
from ros_helpers import start_node, stop, wait_for
from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.readers.bag_signals import HELD, read_bag_record
from stiction_ros.bag.reader import read_bag
from stiction_ros.models import create

pytestmark = pytest.mark.ros
TS = 0.05
S, J = 4.0, 1.0
NODES = {
    'plant': {'sample_time': TS, 'num': [1.0], 'den': [2.0, 1.0], 'delay': 0.0,
              'mv0': 50.0, 'pv0': 0.0},
    'controller': {'sample_time': TS, 'Kc': 2.0, 'Ti': 1.0, 'setpoint': 5.0, 'bias': 50.0},
    'valve': {'sample_time': TS, 'model': 'kano', 'S': S, 'J': J,
              'inject_drop': 0.1, 'inject_jitter': 0.3 * TS, 'inject_seed': 3},
}


def test_lost_and_late_op_is_reported_marked_and_left_out(probe, tmp_path):
    ns = f'/mf{time.monotonic_ns() % 10**6}'
    bag = tmp_path / 'bag'
    warnings = []

    def on_diag(msg):
        warnings.extend(s.message for s in msg.status
                        if s.name.startswith(f'{ns}/valve') and 'lost or late' in s.message)
    probe.node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 10)

    topics = ['sp', 'op', 'mv', 'pv', 'held_inputs']
    rec = start_node('recorder', {'output': str(bag), 'topics': topics},
                     namespace=ns, log_dir=str(tmp_path))
    procs = {n: start_node(n, p, namespace=ns, log_dir=str(tmp_path))
             for n, p in NODES.items()}
    probe.listen(f'{ns}/mv')
    try:
        wait_for(lambda: len(probe.values(f'{ns}/mv')) >= 400, timeout=90,
                 what='400 samples of the loop')
        wait_for(lambda: warnings, what='a /diagnostics warning about held OP')
    finally:
        for name, proc in procs.items():
            assert stop(proc) == 0, (tmp_path / f'{name}.log').read_text()
        assert stop(rec) == 0
    log = (tmp_path / 'valve.log').read_text()
    assert 'acted on a held op' in log and 'inputs lost' in log

    marks = read_bag(bag).topic('held_inputs').decoded()
    held_op = [m for m in marks if m.key == f'{ns}/op']
    record = load_record(bag)
    assert len(held_op) > 0.1 * record.samples
    fixed = [n for n in record.notes if 'hold the OP the valve acted on' in n]
    assert fixed and int(fixed[0].split()[1]) >= 0.9 * len(held_op)
    excluded = sum(e['samples'] for e in record.excluded if e['reason'] == HELD)
    assert excluded <= len(marks) - len(held_op)

    as_sent = read_bag_record(bag, held=False)
    fits = {name: settled_mse(rec) for name, rec in (('corrected', record),
                                                     ('as sent', as_sent))}
    print(f'{len(held_op)} of {record.samples} samples on a held OP, {excluded} excluded; '
          f'MSE {fits["corrected"]:.3g} corrected vs {fits["as sent"]:.3g} as sent')
    assert fits['corrected'] < 0.05 * fits['as sent'], fits


def settled_mse(rec, settle=60):
    """
    Return the true Kano model's MSE against MV, skipping each stretch's first samples.

    A fit starts each stretch with the valve at rest, and the valve may be moving
    there; that costs until it next sticks, whatever the faults, so it is left out.
    """
    err = []
    for a, b in rec.valve_segments(min_samples=settle + 2):
        y = create('kano', S=S, J=J).simulate(rec.signals['op'][a:b], y0=rec.signals['mv'][a])
        err.append((y - rec.signals['mv'][a:b])[settle:])
    return float(np.mean(np.concatenate(err) ** 2))


def test_inject_options_are_checked():
    from stiction_ros.cli.loop import parse_inject
    from stiction_ros.loop_config import ConfigError
    assert parse_inject(['op:drop=0.1,jitter=0.02', 'pv:delay=0.5,seed=4']) == {
        'op': {'drop': 0.1, 'jitter': 0.02}, 'pv': {'delay': 0.5, 'seed': 4}}
    for bad in ('sp:drop=0.1', 'op:lose=0.1', 'op:drop=lots', 'op:drop'):
        with pytest.raises(ConfigError, match='--inject'):
            parse_inject([bad])

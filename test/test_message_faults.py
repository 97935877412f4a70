"""
Lost and late messages in a live loop: reported, marked in the bag, left out by the analyzer.

The loop runs from the ``loop`` executable on a lockstep sim clock with
``--inject op:...``: the valve loses 10 % of the OP messages on their way in
and delays the rest by up to 0.4 of a sample, in order, so that some arrive
after it has acted.  The valve then acts on the OP it held: it
reports that on its ``diagnostics`` and publishes ``held_inputs`` with the
value it used, which the recorder records.  In the bag, ``op`` is what the
controller sent, so at a held sample the recorded OP is not what the valve
used; the analyzer puts the used value in its place (and excludes the
samples where the plant or the controller held an input), and the true
valve model then fits the recorded MV far better than the signals as
recorded.
"""

import json
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
import pytest
from ros_helpers import wait_for
from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.readers.bag_signals import HELD, read_bag_record
from stiction_ros.bag.reader import read_bag
from stiction_ros.models import create

pytestmark = pytest.mark.ros
TS = 0.05
S, J = 4.0, 1.0
LOOP = f"""
name: faults
sample_time: {TS}
duration: 20.0
plant: {{num: [1.0], den: [2.0, 1.0], delay: 0.0, mv0: 50.0, pv0: 0.0}}
controller: {{Kc: 2.0, Ti: 1.0, setpoint: 5.0}}
valve: {{model: kano, S: {S}, J: {J}}}
"""


def test_lost_and_late_op_is_reported_marked_and_corrected(probe, tmp_path):
    ns = f'/mf{time.monotonic_ns() % 10**6}'
    bag = tmp_path / 'bag'
    (tmp_path / 'loop.yaml').write_text(LOOP)
    warnings = []

    def on_diag(msg):
        warnings.extend(s.message for s in msg.status
                        if s.name.startswith(f'{ns}/valve') and 'lost or late' in s.message)
    probe.node.create_subscription(DiagnosticArray, f'{ns}/diagnostics', on_diag, 10)

    # A lockstep sim clock: which messages come late is decided by the seeded faults
    # alone, not by how busy the machine is.
    run = subprocess.run(
        [sys.executable, '-m', 'stiction_ros.cli.loop', str(tmp_path / 'loop.yaml'),
         '--namespace', ns, '--rtf', '4', '--record', str(bag), '--json',
         str(tmp_path / 'summary.json'), '--inject', f'op:drop=0.1,jitter={0.4 * TS},seed=3'],
        capture_output=True, text=True, timeout=240)
    assert run.returncode == 0, run.stdout + run.stderr
    log = (tmp_path / 'bag.logs' / 'valve.log').read_text()
    assert 'acted on a held op' in log and 'inputs lost' in log
    wait_for(lambda: warnings, what='a diagnostics warning about held OP')
    assert json.loads((tmp_path / 'summary.json').read_text())['bag'] == str(bag)

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
    assert fits['as sent'] > 0 and fits['corrected'] < 0.05 * fits['as sent'], fits


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
    from stiction_ros.sim.loop_config import ConfigError
    assert parse_inject(['op:drop=0.1,jitter=0.02', 'pv:delay=0.5,seed=4']) == {
        'op': {'drop': 0.1, 'jitter': 0.02}, 'pv': {'delay': 0.5, 'seed': 4}}
    for bad in ('sp:drop=0.1', 'op:lose=0.1', 'op:drop=lots', 'op:drop'):
        with pytest.raises(ConfigError, match='--inject'):
            parse_inject([bad])

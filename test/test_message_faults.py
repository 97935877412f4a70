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
samples where the plant or the controller held an input, or where the
valve had no OP at all yet), and the true
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
from stiction_ros.analysis.readers.bag_signals import HELD, NO_OP, read_bag_record
from stiction_ros.bag.reader import read_bag
from stiction_ros.models import create

pytestmark = pytest.mark.ros
TS = 0.05
S, J = 4.0, 1.0
MV0 = 50.0
LOOP = f"""
name: faults
sample_time: {TS}
duration: 20.0
plant: {{num: [1.0], den: [2.0, 1.0], delay: 0.0, mv0: {MV0}, pv0: 0.0}}
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
    # A 'nan' mark: no OP had come yet (the first ones lost), a sample left out.
    held_op = [m for m in marks if m.key == f'{ns}/op' and not m.value.endswith(' nan')]
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
    Return the true Kano model's MSE against MV, replaying the valve as the node ran it.

    Up to its first OP the valve node rests at its initial position under that
    input; the first stretch is replayed from there, so the model's state
    (stuck or moving, and which way) is the node's at every sample.  A later
    stretch starts at rest, which need not be the valve's state: its first
    ``settle`` samples are left out.  A quiet loop may never wash that out
    (the model's stuck reference is remembered while stuck), which is why the
    first stretch is replayed, not settled.
    """
    op, mv = rec.signals['op'], rec.signals['mv']
    err = []
    for i, (a, b) in enumerate(rec.valve_segments(min_samples=settle + 2)):
        model = create('kano', S=S, J=J)
        if i == 0 and np.all(mv[:a] == MV0):
            model.reset(y0=MV0)
            y = np.array([model.step(u) for u in op[a:b]])
            skip = 0
        else:
            y = model.simulate(op[a:b], y0=mv[a])
            skip = settle
        err.append((y - mv[a:b])[skip:])
    return float(np.mean(np.concatenate(err) ** 2))


def test_inject_options_are_checked():
    from stiction_ros.cli.loop import parse_inject
    from stiction_ros.sim.loop_config import ConfigError
    assert parse_inject(['op:drop=0.1,jitter=0.02', 'pv:delay=0.5,seed=4']) == {
        'op': {'drop': 0.1, 'jitter': 0.02}, 'pv': {'delay': 0.5, 'seed': 4}}
    for bad in ('sp:drop=0.1', 'op:lose=0.1', 'op:drop=lots', 'op:drop'):
        with pytest.raises(ConfigError, match='--inject'):
            parse_inject([bad])


def test_samples_before_the_valve_had_any_op_are_left_out_of_the_valve_fit(tmp_path):
    """
    Samples at which the valve had no OP yet are marked ``nan`` and left out of its fit.

    The valve's first OP messages can all be lost or late: it then holds its position.
    Fitted from sample 0 on the OP the controller sent, the model
    starts stuck at an OP the valve never saw; a run of CI saw it stay stuck for the whole
    record (MSE 0.29 where the true model fits exactly).  Left out, the fit is exact.
    """
    from diagnostic_msgs.msg import KeyValue
    from rclpy.serialization import serialize_message
    from stiction_ros.bag.metadata import qos_profile
    from stiction_ros.bag.writer import BagWriter
    from std_msgs.msg import Float64

    n, none, held = 200, 3, 40
    op = 60.0 + 3.0 * np.sin(np.arange(n) / 7.0)
    used = op.copy()
    used[held] = op[held - 1]               # sample 40 acted on the OP of 39 (lost)
    valve = create('kano', S=S, J=J)
    valve.reset(y0=MV0)                     # as the valve node starts
    mv = np.full(n, MV0)
    mv[none:] = [valve.step(u) for u in used[none:]]
    bag = tmp_path / 'bag'
    w = BagWriter(bag)
    for name, kind in (('/v/op', 'std_msgs/msg/Float64'), ('/v/mv', 'std_msgs/msg/Float64'),
                       ('/v/held_inputs', 'diagnostic_msgs/msg/KeyValue')):
        w.add_topic(name, kind, [qos_profile(depth=100)], 'RIHS01_' + '0' * 64)
    ns = 10**9
    for k in range(n):
        t0 = 10 * ns + k * int(TS * ns)
        w.write('/v/op', serialize_message(Float64(data=float(op[k]))), t0 + int(TS * ns) // 2)
        if k < none or k == held:
            value = 'nan' if k < none else repr(float(used[k]))
            w.write('/v/held_inputs', serialize_message(KeyValue(key='/v/op',
                                                                 value=f'{k + 200} {value}')),
                    t0 + 3 * int(TS * ns) // 4)
        w.write('/v/mv', serialize_message(Float64(data=float(mv[k]))), t0 + 3 * int(TS * ns) // 4)
    w.close()

    record = load_record(bag)
    assert record.valve_segments() == [(none, n)]
    assert [e['samples'] for e in record.excluded if e['reason'] == NO_OP] == [none]
    assert record.signals['op'][held] == used[held] and record.signals['op'][0] == op[0]
    assert settled_mse(record, settle=0) == 0.0

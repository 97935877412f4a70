"""
The lockstep clock against a producer that misses ticks or skips a sample.

A loop node that falls behind on a busy machine can skip a sample and never
send its message: the clock must then stall once (``sync_timeout``) and go
on in lockstep.  A count kept one short stalled every later tick instead,
and a namespaced loop in CI made 23 samples in 90 wall seconds.  A node's
time source subscribes best-effort, so a tick can be lost, most often at
start-up under load: the clock repeats the current time while it waits, and
the node acts on the repeat (CI: a plant that never heard the first sample
left the loop one PV short).
"""

import re
import threading

import pytest
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_helpers import start_node, stop, wait_for
from rosgraph_msgs.msg import Clock

pytestmark = [pytest.mark.ros]
STOP_AT = 12.0


def run_clock(probe, tmp_path, ns, skip=(), deaf_for=0, stop_at=STOP_AT, last_after=0.0):
    """
    Run a lockstep clock on ``ns`` with the probe as the PV producer; return (sent, log).

    The probe publishes PV at a quarter of each sample, as the plant does, except
    in the samples ``skip``; it ignores the first ``deaf_for`` clock messages, and
    answers the last sample ``last_after`` wall seconds late.
    """
    sent, heard, clock = [], [], {}

    def send(k):
        probe.publish(f'{ns}/pv', float(k))
        sent.append(k)
        clock.setdefault('running_when_sent', {})[k] = clock['proc'].poll() is None

    def on_clock(msg):
        heard.append(msg)
        if len(heard) <= deaf_for:
            return
        k, phase = divmod(round((msg.clock.sec + msg.clock.nanosec * 1e-9) * 4), 4)
        if phase == 1 and k not in skip and k not in sent and k not in clock:
            if k == int(stop_at) and last_after:
                clock[k] = threading.Timer(last_after, send, (k,))
                clock[k].start()
            else:
                send(k)
    probe.publisher(f'{ns}/pv')
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    sub = probe.node.create_subscription(Clock, f'{ns}/clock', on_clock, qos)
    proc = start_node('sim_clock', {'rtf': 20.0, 'step': 0.25, 'sample_time': 1.0,
                                    'stop_at': stop_at, 'sync': ['pv@0.25'],
                                    'sync_timeout': 1.0, 'wait_timeout': 10.0,
                                    'wait_for': ['/clock=1']},
                      namespace=ns, log_dir=tmp_path, extra=['-r', f'/clock:={ns}/clock'])
    clock['proc'] = proc
    try:
        # 12 sim s at rtf 20 is 0.6 wall s, plus start-up and the stalls under test; a
        # clock that stalls at every later tick takes 4 x 8 x 1 s more.
        wait_for(lambda: proc.poll() is not None, timeout=25.0, what='the clock to stop')
    finally:
        rc = stop(proc)
        probe.node.destroy_subscription(sub)
    log = (tmp_path / 'sim_clock.log').read_text()
    assert rc == 0, log
    return sent, log, clock.get('running_when_sent', {})


def stalls(log):
    """Return the stall counts of the clock's final report."""
    return [int(n) for n in re.findall(r'rtf [0-9.]+, (\d+) stalls', log)]


def test_a_skipped_message_costs_one_stall_not_one_per_tick(probe, tmp_path):
    sent, log, _ = run_clock(probe, tmp_path, '/clock_skip', skip={3})
    assert 3 not in sent and set(range(int(STOP_AT))) - set(sent) == {3}, sent
    # exactly the skipped sample's message was waited for, once
    assert stalls(log) == [1], log
    assert "moved on without ['pv']" in log, log


def test_a_producer_that_lost_its_first_ticks_acts_on_the_repeat(probe, tmp_path):
    sent, log, _ = run_clock(probe, tmp_path, '/clock_deaf', deaf_for=4)
    # every sample from the first, and no stall: the time was repeated until heard
    assert sent == list(range(int(STOP_AT))), (sent, log)
    assert stalls(log) == [0], log


def test_the_clock_stops_only_once_the_last_samples_messages_have_come(probe, tmp_path):
    # The last tick is sample 12's PV instant; the producer answers it 0.5 s late.
    sent, log, running = run_clock(probe, tmp_path, '/clock_last', stop_at=STOP_AT + 0.25,
                                   last_after=0.5)
    assert sent == list(range(int(STOP_AT) + 1)), (sent, log)
    # the clock was still there to hear it, and waited without a stall
    assert running[int(STOP_AT)], log
    assert stalls(log) == [0], log

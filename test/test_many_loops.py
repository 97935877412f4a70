"""
Several sped-up loops on one graph, at once, each in its own namespace.

Each namespaced loop runs on its own clock topic (``/ns/clock``) and reports on
its own ``/ns/diagnostics``.  On one shared ``/clock`` two loops at rtf 50 drove
each other's nodes back and forth in time ("clock went back" 33 to 54 times per
loop node) and both stalled: neither finished its 300 s in 100 wall seconds
(6 s alone).  Here each loop must equal its offline twin to the bit.
"""

import re
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray
import pytest
from ros_helpers import wait_for
from stiction_ros.app.live_summary import summarise
from stiction_ros.bag.reader import read_bag
from stiction_ros.cli.loop import run_loop
from stiction_ros.resources import config_file
from stiction_ros.sim.loop_config import load_loop

pytestmark = [pytest.mark.ros, pytest.mark.slow]
RTF = 50.0
# Wall seconds a run may take before the test gives up on it (a stalled loop never ends).
DEADLINE = 100.0


class Watchdog(Exception):
    """A loop ran past the deadline: raised inside run_loop, which then stops its nodes."""


def run_together(prefix, cases, duration, tmp_path, probe):
    """
    Run one loop per case, all started at once; return what each run left.

    ``{ns: error or None}``, the diagnostics heard per topic, and the most
    publishers seen on each clock topic during the runs.
    """
    nss = [f'/{prefix}_{case}' for case in cases]
    diags = {topic: [] for topic in ['/diagnostics'] + [f'{ns}/diagnostics' for ns in nss]}
    for topic, got in diags.items():
        probe.node.create_subscription(DiagnosticArray, topic,
                                       lambda m, got=got: got.extend(m.status), 10)
    clocks = dict.fromkeys(['/clock'] + [f'{ns}/clock' for ns in nss], 0)
    errors = {}
    end = time.monotonic() + DEADLINE
    together = threading.Barrier(len(cases))

    def watch():
        # run_loop calls this every 0.1 s: look at the graph, and end a loop that hangs.
        for topic in clocks:
            clocks[topic] = max(clocks[topic], probe.node.count_publishers(topic))
        if time.monotonic() > end:
            raise Watchdog(f'not done after {DEADLINE} s')

    def one(case, ns):
        cfg = load_loop(config_file('concentration_loop.yaml'), case)
        together.wait()
        try:
            run_loop(cfg, namespace=ns, rtf=RTF, duration=duration,
                     record=tmp_path / case / 'bag', log_dir=tmp_path / case / 'logs',
                     progress=watch)
            errors[ns] = None
        except Exception as err:   # the test thread reports it, with the rest
            errors[ns] = err

    threads = [threading.Thread(target=one, args=(case, ns)) for case, ns in zip(cases, nss)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return errors, diags, clocks


def check_loops(prefix, cases, duration, tmp_path, probe):
    """Run the cases together; each must equal its offline twin, on its own clock."""
    errors, diags, clocks = run_together(prefix, cases, duration, tmp_path, probe)
    n = int(duration) + 1
    results = {}
    for case in cases:
        ns = f'/{prefix}_{case}'
        logs = {p.stem: p.read_text(errors='replace')
                for p in sorted((tmp_path / case / 'logs').glob('*.log'))}
        back = {name: text.count('clock went back') for name, text in logs.items()}
        r = results[ns] = {'error': repr(errors[ns]), 'clock_went_back': back}
        # What a loop that left its twin did differently, for the failure message: a node
        # that gave up waiting for an input (acting on a held one), a clock that moved on.
        gave_up = {name: sum(map(int, re.findall(r'gave up at (\d+)', text)))
                   for name, text in logs.items()}
        r['gave_up'] = {name: count for name, count in gave_up.items() if count}
        if errors[ns] is not None:
            # The last lines each node wrote (a stalled node's stacks on SIGUSR1 among them).
            r['tails'] = {name: [ln for ln in text.splitlines() if 'subscribed to' not in ln][-3:]
                          for name, text in logs.items()}
        clock_log = logs.get('sim_clock', '')
        r['stalls'] = sum(map(int, re.findall(r'(\d+) stalls$', clock_log, re.M)))
        bag = tmp_path / case / 'bag'
        if (bag / 'metadata.yaml').exists():    # a loop stopped by the watchdog has one too
            s = summarise(read_bag(bag), load_loop(config_file('concentration_loop.yaml'), case))
            r['messages'] = s['messages']
            r['diff'] = {k: s['signals'][k].get('max_abs_difference')
                         for k in ('op', 'mv', 'pv') if k in s['signals']}
            r['first_difference_s'] = {k: s['signals'][k].get('first_difference_s')
                                       for k in ('op', 'mv', 'pv') if k in s['signals']}
    print(results, clocks)
    # Each loop had its own clock topic, one publisher each, and none used /clock.
    assert clocks == {'/clock': 0, **{f'/{prefix}_{c}/clock': 1 for c in cases}}, clocks
    for case in cases:
        ns = f'/{prefix}_{case}'
        r = results[ns]
        assert errors[ns] is None, r
        assert not any(r['clock_went_back'].values()), r
        # lossless: one message per sample and topic, every sample present
        assert r['messages'] == {f'{ns}/{t}': n for t in ('sp', 'op', 'mv', 'pv')}, r
        # Each loop on its own clock computes exactly what the offline simulator does.
        assert r['diff'] == {'op': 0.0, 'mv': 0.0, 'pv': 0.0}, r
        # Every loop node reports once a wall second, on its own namespace's topic.
        expected = {f'{ns}/plant: mv', f'{ns}/controller: pv', f'{ns}/valve: op'}
        heard = diags[f'{ns}/diagnostics']
        wait_for(lambda: expected <= {s.name for s in heard}, timeout=5.0,
                 what=f'diagnostics of every node on {ns}/diagnostics')
        assert {s.name for s in heard} == expected
    # and none of them on the global topic
    ours = tuple(f'/{prefix}_{c}/' for c in cases)
    leaked = {s.name for s in diags['/diagnostics'] if s.name.startswith(ours)}
    assert not leaked, leaked


def test_three_loops_at_once_each_equal_their_offline_twin(probe, tmp_path):
    check_loops('three', ['undershoot', 'overshoot', 'no_offset'], 400.0, tmp_path, probe)

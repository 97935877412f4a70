"""
A loop node killed (SIGKILL) and restarted resumes where it was: no jump, no bump.

Each node writes its state to ``state_file`` after every sample.  The valve
is checked against a twin that is never killed: both see the same OP over
DDS, and after the restart their positions agree to the last bit through
breakaways, a reversal inside the stick band and a stop.  The plant and the
controller are killed in a running loop whose PV and OP sit far from where a
fresh node would start (pv0, the bias).
"""

import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from ros_helpers import start_node, stop, wait_for
from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.readers.bag_signals import HELD
from stiction_ros.analysis.record import runs
from stiction_ros.cli.loop import RESPAWN_AFTER
from stiction_ros.nodes import state_file

pytestmark = [pytest.mark.ros, pytest.mark.alone]
TS = 0.05
VALVE = {'sample_time': TS, 'model': 'kano', 'S': 6.0, 'J': 2.0, 'initial_position': 50.0}


def latest(probe, topic):
    values = probe.values(topic)
    return values[-1] if values else None


def settle(probe, topics, samples=6):
    """Wait a few samples, then return the newest value of each topic."""
    counts = [len(probe.values(t)) for t in topics]
    wait_for(lambda: all(len(probe.values(t)) >= c + samples for t, c in zip(topics, counts)),
             what=f'{samples} more samples on {topics}')
    return [latest(probe, t) for t in topics]


def test_a_killed_valve_resumes_its_position_stick_state_and_direction(probe, tmp_path):
    ns = f'/rv{time.monotonic_ns() % 10**6}'
    state = tmp_path / 'valve.state'
    op = f'{ns}/op'
    twin = start_node('valve', VALVE, namespace=f'{ns}/twin', log_dir=str(tmp_path),
                      extra=['-r', f'op:={op}'])
    valve = start_node('valve', dict(VALVE, state_file=str(state)), namespace=ns,
                       log_dir=str(tmp_path))
    mv, mv_twin = f'{ns}/mv', f'{ns}/twin/mv'
    probe.listen(mv)
    probe.listen(mv_twin)
    try:
        probe.hear(op, 50.0, [ns, f'{ns}/twin'])
        # Up through a breakaway, then back by less than the stick band: stuck, and the
        # next move down must first overcome S. A fresh valve would know none of that.
        for value in (58.0, 63.0, 60.0):
            probe.publish(op, value)
            before = settle(probe, [mv, mv_twin])
        assert before[0] == before[1]
        saved = state_file.read(state)
        assert saved['node'] == 'valve' and saved['state']['op'] == 60.0

        valve.send_signal(signal.SIGKILL)
        valve.wait()
        dead = len(probe.values(mv))
        time.sleep(0.5)
        valve = start_node('valve', dict(VALVE, state_file=str(state)), namespace=ns,
                           log_dir=str(tmp_path))
        wait_for(lambda: len(probe.values(mv)) > dead, what='the restarted valve publishing')
        first = probe.values(mv)[dead]
        assert first == before[0], f'jumped from {before[0]} to {first}'
        probe.hear(op, 60.0, [ns])

        for value in (57.0, 55.0, 52.0, 61.0, 66.0, 66.0, 64.0):
            probe.publish(op, value)
            now, now_twin = settle(probe, [mv, mv_twin])
            assert now == now_twin, f'after op {value}: {now} vs the twin {now_twin}'
    finally:
        assert stop(valve) == 0, (tmp_path / 'valve.log').read_text()
        stop(twin)
    assert 'resumed from' in (tmp_path / 'valve.log').read_text()


def test_a_corrupt_state_file_is_set_aside_and_the_valve_starts_afresh(probe, tmp_path):
    ns = f'/rc{time.monotonic_ns() % 10**6}'
    state = tmp_path / 'valve.state'
    state.write_text('{"node": "valve", "sample_time": 0.05, "k": 7, "state": {"model": ')
    valve = start_node('valve', dict(VALVE, state_file=str(state)), namespace=ns,
                       log_dir=str(tmp_path))
    probe.listen(f'{ns}/mv')
    try:
        wait_for(lambda: len(probe.values(f'{ns}/mv')) >= 3, what='the valve publishing')
        assert probe.values(f'{ns}/mv')[0] == 50.0
    finally:
        assert stop(valve) == 0
    assert (tmp_path / 'valve.state.unusable').exists()
    assert 'starting afresh' in (tmp_path / 'valve.log').read_text()
    assert state_file.read(state)['node'] == 'valve'     # a new state since


LOOP = {
    'plant': {'sample_time': TS, 'num': [1.0], 'den': [2.0, 1.0], 'delay': 0.0,
              'mv0': 50.0, 'pv0': 0.0},
    'controller': {'sample_time': TS, 'Kc': 2.0, 'Ti': 1.0, 'setpoint': 5.0, 'bias': 50.0},
    'valve': {'sample_time': TS, 'model': 'linear'},
}


@pytest.mark.parametrize('victim', ['plant', 'controller'])
def test_a_killed_plant_or_controller_resumes_without_a_jump(probe, tmp_path, victim):
    ns = f'/rl{victim}{time.monotonic_ns() % 10**5}'
    params = {n: dict(p, state_file=str(tmp_path / f'{n}.json')) for n, p in LOOP.items()}
    procs = {n: start_node(n, p, namespace=ns, log_dir=str(tmp_path))
             for n, p in params.items()}
    signal_of = {'plant': f'{ns}/pv', 'controller': f'{ns}/op'}
    topic = signal_of[victim]
    far_from = {'plant': 0.0, 'controller': 50.0}[victim]     # pv0, the bias
    for t in signal_of.values():
        probe.listen(t)
    try:
        # Settled near SP = 5 (PV) and OP = 55, away from where a fresh node starts.
        wait_for(lambda: len(probe.values(topic)) > 200 and abs(
            latest(probe, f'{ns}/pv') - 5.0) < 0.05, timeout=60, what='the loop settled')
        last = settle(probe, [topic], 3)[0]
        procs[victim].send_signal(signal.SIGKILL)
        procs[victim].wait()
        dead = len(probe.values(topic))
        time.sleep(0.5)
        procs[victim] = start_node(victim, params[victim], namespace=ns,
                                   log_dir=str(tmp_path))
        wait_for(lambda: len(probe.values(topic)) > dead + 20, what='the restarted node')
        after = probe.values(topic)[dead:dead + 20]
        fresh_jump = abs(last - far_from)
        assert fresh_jump > 4.0
        assert max(abs(v - last) for v in after) < 0.1 * fresh_jump, (last, after[:5])
    finally:
        for name, proc in procs.items():
            assert stop(proc) == 0, (tmp_path / f'{name}.log').read_text()
    assert 'resumed from' in (tmp_path / f'{victim}.log').read_text()


LOOP_FILE = """
name: restart
sample_time: 0.05
duration: 30.0
plant: {num: [1.0], den: [2.0, 1.0], delay: 0.0, mv0: 50.0, pv0: 0.0}
controller: {Kc: 2.0, Ti: 1.0, setpoint: 5.0}
valve: {model: kano, S: 4.0, J: 1.0}
"""


def _plant_has_mv(path):
    try:
        return state_file.read(path)['state']['mv'] is not None
    except (state_file.StateFileError, KeyError, TypeError):
        return False


def _recording(log, topics):
    try:
        text = log.read_text(errors='replace')
    except OSError:
        return False
    return all(f'subscribed to {t} [' in text for t in topics)


def _pids(*words):
    out = []
    for d in Path('/proc').iterdir():
        try:
            cmd = (d / 'cmdline').read_bytes().replace(b'\0', b' ').decode()
        except OSError:
            continue
        if d.name.isdigit() and all(w in cmd for w in words):
            out.append(int(d.name))
    return out


def _uptime(pid):
    """Return how long process ``pid`` has been running, in seconds (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    started = int(fields[19]) / os.sysconf('SC_CLK_TCK')
    return float(Path('/proc/uptime').read_text().split()[0]) - started


def test_the_loop_respawns_a_killed_valve_and_the_gap_is_marked_and_left_out(tmp_path):
    ns = f'/rs{time.monotonic_ns() % 10**6}'
    (tmp_path / 'loop.yaml').write_text(LOOP_FILE)
    bag = tmp_path / 'bag'
    run = subprocess.Popen(
        [sys.executable, '-m', 'stiction_ros.cli.loop', str(tmp_path / 'loop.yaml'),
         '--namespace', ns, '--record', str(bag), '--respawn', '--json',
         str(tmp_path / 'summary.json')], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True)
    # Killed only once the plant has heard from it and the recorder records what the
    # plant does: a valve killed before discovery matched them leaves the plant nothing
    # to hold, or the bag nothing to show (each seen in about 1 run of 5).
    logs = Path(f'{bag}.logs')
    wait_for(lambda: _plant_has_mv(logs / 'plant.state') and _recording(
        logs / 'recorder.log', [f'{ns}/{t}' for t in ('mv', 'pv', 'held_inputs')]),
        timeout=30, what="the plant acting on the valve's MV, recorded")
    time.sleep(1.0)
    victims = _pids('valve_node', ns)
    assert len(victims) == 1
    # The launcher restarts only a node that ran for RESPAWN_AFTER s (one dying at
    # once would only die again); on a quick machine discovery beats that.
    time.sleep(max(0.0, RESPAWN_AFTER + 0.5 - _uptime(victims[0])))
    # A slow start can leave little of the loop's 30 s: a kill after its end tests nothing
    # (one CI run on two workers left no gap in the bag; the cause was not caught).
    up = _uptime(victims[0])
    assert run.poll() is None, f'the loop ended before the kill (valve up {up:.1f} s)'
    os.kill(victims[0], signal.SIGKILL)
    print(f'valve killed {up:.1f} s after it started')
    out, _ = run.communicate(timeout=90)
    assert run.returncode == 0, out
    assert 'restarting it from its state' in out, out
    summary = json.loads((tmp_path / 'summary.json').read_text())
    assert summary['respawned'] == {'valve': 1}
    assert 'resumed from' in (logs / 'valve.log').read_text()

    record = load_record(bag)
    held = sum(e['samples'] for e in record.excluded if e['reason'] == HELD)
    missing = np.isnan(record.signals['mv'])
    assert held >= 5 and missing.sum() >= 5       # the plant held MV while the valve was down
    pv = record.signals['pv']
    since = np.flatnonzero(~np.isnan(pv))[0]      # the plant may start after the controller
    gaps = [b - a for a, b in runs(np.isnan(pv[since:]))]
    a, b = max(runs(missing[since:]), key=lambda r: r[1] - r[0])
    alive = np.isfinite(pv[since + a:since + b])
    print(f'valve down for {b - a} samples (from {since + a} of {len(pv)}), PV in '
          f'{alive.sum()}; {held} samples held; pv gaps {gaps}')
    # The plant kept running while the valve was down. Not at every sample: the valve's
    # new process takes a core for a second to start, and the plant then skips some
    # (up to 9 in a row seen in 10 runs).
    assert alive.mean() >= 1 / 3
    assert not record.valid[missing].any()

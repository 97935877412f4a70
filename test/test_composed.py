"""
Composition: plant, controller and valve as three nodes in one process, on one executor.

The composed loop must compute what the three-process loop and the offline
simulator compute, to the bit; and every executable must answer ``--help``
without starting a node.
"""

import subprocess
import sys

import pytest
from stiction_ros.app.live_summary import summarise
from stiction_ros.bag.reader import read_bag
from stiction_ros.cli.loop import MODULES, run_loop
from stiction_ros.resources import config_file
from stiction_ros.sim.loop_config import load_loop

pytestmark = [pytest.mark.ros, pytest.mark.slow]


def test_the_composed_loop_equals_its_offline_twin(tmp_path):
    cfg = load_loop(config_file('concentration_loop.yaml'), 'overshoot')
    bag = run_loop(cfg, namespace='/composed', rtf=100.0, duration=400.0,
                   record=tmp_path / 'bag', log_dir=tmp_path / 'logs', composed=True)
    logs = sorted(p.name for p in (tmp_path / 'logs').glob('*.log'))
    assert logs == ['loop_nodes.log', 'recorder.log', 'sim_clock.log']
    s = summarise(read_bag(bag), cfg)
    assert sorted(s['messages'].values()) == [401] * 4, s['messages']
    diff = {k: s['signals'][k]['max_abs_difference'] for k in ('op', 'mv', 'pv')}
    assert diff == {'op': 0.0, 'mv': 0.0, 'pv': 0.0}, diff


@pytest.mark.parametrize('module', sorted(set(MODULES.values()) | {'analyzer_node'}))
def test_every_node_executable_answers_help_without_starting(module):
    run = subprocess.run([sys.executable, '-m', f'stiction_ros.nodes.{module}', '--help'],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith('usage: ') and '--ros-args' in run.stdout
    # The node's own description follows, and nothing was started (no ROS log lines).
    assert 'node' in run.stdout.split('\n\n')[1] and '[INFO]' not in run.stdout + run.stderr
    # Its parameters follow (the composed loop: each node's own, by its params-file section).
    sections = ['Parameters of plant', 'Parameters of controller', 'Parameters of valve']
    assert (all(h in run.stdout for h in sections) if module == 'composed'
            else '\nParameters (' in run.stdout), run.stdout

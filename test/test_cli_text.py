"""Every command's ``--help`` reads as plain text, and a closed pipe ends a command quietly."""

import subprocess
import sys

import pytest
from stiction_ros.cli.text import description, plain

COMMANDS = ('accuracy', 'analyze', 'bag', 'detector', 'loop', 'precompile', 'sim', 'study')


def test_markup_is_removed_from_help_text():
    assert plain('``stiction-sim``: run :mod:`stiction_ros.sim` via :func:`~a.b`') == (
        'stiction-sim: run stiction_ros.sim via a.b')
    assert description('\n``loop``: bring up a loop.\n\nMore.') == 'loop: bring up a loop.'


@pytest.mark.parametrize('command', COMMANDS)
def test_every_command_describes_itself_in_plain_text(command):
    run = subprocess.run([sys.executable, '-m', f'stiction_ros.cli.{command}', '--help'],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    blocks = run.stdout.split('\n\n')
    # usage, then the description: the command's name and what it does
    assert len(blocks[1].split()) > 3, run.stdout[:400]
    assert '``' not in run.stdout and ':mod:' not in run.stdout and ':func:' not in run.stdout


def test_a_reader_that_stops_early_ends_the_command_quietly():
    # 2 000 CSV rows into `head -1`: the writes after the first line hit a closed pipe.
    cmd = (f'{sys.executable} -m stiction_ros.cli.sim config/concentration_loop.yaml '
           '--case undershoot --quiet | head -1')
    run = subprocess.run(['bash', '-o', 'pipefail', '-c', cmd], capture_output=True,
                         text=True, timeout=120)
    assert run.stdout.startswith('t,'), run.stdout
    assert 'Traceback' not in run.stderr and 'BrokenPipe' not in run.stderr, run.stderr
    assert run.returncode == 0, run.stderr


def test_analyzer_help_loads_nothing_of_the_analysis():
    # The help must answer in Python's own start-up time: no numpy, scipy or numba.
    code = ('import sys\n'
            'from stiction_ros.cli.analyze import main\n'
            'try:\n'
            '    main(["--help"])\n'
            'except SystemExit:\n'
            '    pass\n'
            'heavy = ("numpy", "scipy", "numba", "matplotlib", "rclpy")\n'
            'print(sorted(m for m in sys.modules if m.split(".")[0] in heavy)[:5])\n')
    run = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=60)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip().splitlines()[-1] == '[]', run.stdout[-300:]


def test_a_node_describes_itself_in_plain_text():
    from stiction_ros.nodes.run import help_text
    from stiction_ros.nodes.valve_node import ValveNode
    text = help_text(ValveNode, 'valve')
    assert 'valve node: subscribes op' in text, text[:300]
    assert '``' not in text and ':class:' not in text and '::\n' not in text

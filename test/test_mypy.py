"""Run mypy with the setup.cfg configuration over the typed core of the package."""

import configparser
import importlib.util
from pathlib import Path
import subprocess
import sys

import pytest

ROOT = Path(__file__).resolve().parents[1]
# The core that setup.cfg types strictly: the layers below sim (see test_layers.py).
CORE = ('stiction_ros/_jit.py', 'stiction_ros/errors.py', 'stiction_ros/resources.py',
        'stiction_ros/kernels', 'stiction_ros/models', 'stiction_ros/bag')


def _configured_files():
    parser = configparser.ConfigParser()
    parser.read(ROOT / 'setup.cfg', encoding='utf-8')
    return tuple(f.strip() for f in parser['mypy']['files'].split(',') if f.strip())


def test_setup_cfg_checks_the_same_core():
    assert _configured_files() == CORE, 'setup.cfg [mypy] files and CORE here differ'


@pytest.mark.linter
@pytest.mark.skipif(importlib.util.find_spec('mypy') is None,
                    reason='mypy is not installed (requirements/test.txt has it)')
def test_mypy():
    # The cache (.mypy_cache, git-ignored) makes a repeated run take a fraction of a second.
    cmd = [sys.executable, '-m', 'mypy', '--config-file', str(ROOT / 'setup.cfg'),
           '--cache-dir', str(ROOT / '.mypy_cache'), *CORE]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, (f'mypy found type errors (exit {done.returncode}):\n'
                                  + done.stdout + done.stderr)

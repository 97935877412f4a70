"""Ctrl-C at a terminal, sent as a terminal sends it: to the whole process group."""

import os
from pathlib import Path
import shutil
import signal
import subprocess
import sys
import time

from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop, write_csv
from stiction_ros.sim.loop_config import load_loop

RECORDINGS = 60


def test_ctrl_c_stops_a_folders_run_on_two_workers_without_finishing_the_queue(tmp_path):
    folder = tmp_path / 'loops'
    folder.mkdir()
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot')
    write_csv(folder / 'loop_0.csv', simulate_loop(cfg, duration=3000.0))
    for k in range(1, RECORDINGS):
        shutil.copy(folder / 'loop_0.csv', folder / f'loop_{k}.csv')
    out = tmp_path / 'reports'
    cli = Path(sys.executable).with_name('stiction-analyze')
    err = tmp_path / 'err.txt'
    with open(err, 'wb') as errf:
        # As a terminal starts it: Ctrl-C not ignored (a test worker of pytest-xdist ignores
        # it, and a child inherits that).
        proc = subprocess.Popen([str(cli), str(folder), '--jobs', '2', '--out-dir', str(out)],
                                stdout=subprocess.DEVNULL, stderr=errf, start_new_session=True,
                                preexec_fn=_ctrl_c_as_a_terminal_has_it)
        try:
            # Under way: the first report is written (imports and workers long started).
            give_up = time.monotonic() + 120
            while not (out.is_dir() and any(out.glob('*.json'))):
                assert proc.poll() is None and time.monotonic() < give_up, err.read_text()
                time.sleep(0.01)
            os.killpg(proc.pid, signal.SIGINT)
            # A hang guard, not a timing claim: the queue left would take much longer.
            rc = proc.wait(timeout=60)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
    text = err.read_text()
    assert rc == 130 and text.strip().splitlines()[-1] == 'stiction-analyze: interrupted'
    assert 'Traceback' not in text
    # The queued recordings were dropped, not worked through; no worker is left behind.
    assert len(list(out.glob('*.json'))) < RECORDINGS // 2
    assert _in_session(proc.pid) == []


def _in_session(sid):
    # The processes of a session, from /proc (the fields after the command's ')').
    found = []
    for stat in Path('/proc').glob('[0-9]*/stat'):
        try:
            fields = stat.read_text().rsplit(')', 1)[1].split()
        except (OSError, IndexError):
            continue                        # gone meanwhile
        if int(fields[3]) == sid and fields[0] != 'Z':
            found.append(int(stat.parent.name))
    return found


def _ctrl_c_as_a_terminal_has_it():
    signal.signal(signal.SIGINT, signal.SIG_DFL)

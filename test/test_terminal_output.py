"""
What stiction-analyze shows in a terminal: the summary, progress that fits, and no warnings.

The command runs as a subprocess on simulated records, with stderr a pipe
(plain lines) or a real pseudo-terminal (the live display); ``COLUMNS=80``
is the narrow terminal a new user has.
"""

import fcntl
import io
import json
import os
import pty
import re
import struct
import subprocess
import sys
import termios
import warnings

import numpy as np
import pytest

from stiction_ros.analysis.mismatch import locate
from stiction_ros.app.progress import PlainLines, Step
from stiction_ros.sim.closed_loop import write_csv
from test_analyze_cli import loop_csv

pytestmark = pytest.mark.slow
WIDTH = 80
ANSI = re.compile(r'\x1b\[[0-9;?]*[A-Za-z]')
# Two MV gaps: 30 samples (a dropped historian link), then 2 at 1 s.
GAPS = ((200, 230), (400, 402))


def analyze(*args, strict=False):
    env = dict(os.environ, COLUMNS=str(WIDTH))
    flags = ['-W', 'error::RuntimeWarning'] if strict else []
    return subprocess.run([sys.executable, *flags, '-m', 'stiction_ros.cli.analyze',
                           *map(str, args)], capture_output=True, text=True, timeout=600,
                          env=env)


@pytest.fixture(scope='module')
def records(tmp_path_factory):
    d = tmp_path_factory.mktemp('terminal')
    data = loop_csv(d / 'short.csv', duration=600)
    for a, b in GAPS:
        data['mv'][a:b] = np.nan
    write_csv(d / 'gap.csv', data)
    return d


def test_the_summary_names_verdict_evidence_size_gaps_and_files(records):
    res = analyze(records / 'gap.csv', '--json', records / 'r.json')
    assert res.returncode == 0, res.stderr
    assert max(len(line) for line in res.stderr.splitlines()) <= WIDTH, res.stderr
    rep = json.loads((records / 'r.json').read_text())
    st, lines = rep['stiction'], res.stdout.splitlines()
    assert lines[0] == f'gap: {st["answer"]} (score {st["score"]:.2f})'
    said = dict(line.strip().split(':', 1) for line in lines[1:])
    said = {k: v.strip() for k, v in said.items()}
    assert set(said) == {'fits', 'why', 'size', 'excluded', 'report'}
    for f in rep['fits']:
        assert f'{f["model"]} S={f["S"]:.2f} J={f["J"]:.2f}' in said['fits']
    assert said['why'] == st['reason']
    best = min(rep['fits'], key=lambda f: f['mse'])
    assert said['size'].startswith(
        f'S={best["S"]:.2f} % J={best["J"]:.2f} % ({best["model"]}, identified from MV; 95 %')
    # 32 samples of 1 s in two stretches, as the gaps were made.
    assert said['excluded'] == ('2 stretches, 32 s in all (5.3 % of 601 samples): '
                                'no mv value (2)')
    assert said['report'] == str(records / 'r.json')


def test_explain_progress_is_a_line_per_task_within_80_columns(records):
    res = analyze(records / 'short.csv', '--explain', '--bootstrap', '1')
    assert res.returncode == 0, res.stderr
    err = res.stderr.splitlines()
    assert max(len(line) for line in err) <= WIDTH, res.stderr
    # Each model's search is named once, at its last level (of as many as it has).
    for model in ('kano', 'choudhury'):
        (line,) = [x for x in err if x.startswith(f'{model}: search level')]
        assert re.fullmatch(rf'{model}: search level (\d+)/\1, \d+ evaluations', line), line
    # The 16 candidate fits (8 effects, on the record and one replicate): one line at the
    # end, and at most one more per 10 s while they ran; never a line per fit.
    assert not [x for x in err if 'fitted ' in x]
    fits = [x for x in err if x.startswith('candidate fits')]
    assert fits[-1] == 'candidate fits 16/16' and len(fits) <= 3, fits
    assert 'mismatch:' in res.stdout


def test_fit_filter_progress_counts_every_filter_search_of_each_model(records):
    res = analyze(records / 'short.csv', '--fit-filter', '--no-hammerstein')
    assert res.returncode == 0, res.stderr
    err = res.stderr.splitlines()
    for model, filters in (('kano', 10), ('choudhury', 8)):
        (line,) = [x for x in err if x.startswith(f'{model}: search level')]
        assert re.fullmatch(rf'{model}: search level (\d+)/\1, filter {filters}/{filters}, '
                            r'\d+ evaluations', line), line


def _run_on_terminal(args, columns=WIDTH):
    """Return (stdout, everything written to the terminal that stderr was, exit status)."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack('HHHH', 24, columns, 0, 0))
    env = {k: v for k, v in os.environ.items()
           if k not in ('NO_COLOR', 'FORCE_COLOR', 'TTY_COMPATIBLE', 'TTY_INTERACTIVE')}
    env.update(COLUMNS=str(columns), TERM='xterm-256color')
    proc = subprocess.Popen([sys.executable, '-m', 'stiction_ros.cli.analyze', *map(str, args)],
                            stdout=subprocess.PIPE, stderr=slave, env=env)
    os.close(slave)
    shown = []
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:     # Linux: the terminal is gone once the command has ended
            break
        if not chunk:
            break
        shown.append(chunk)
    os.close(master)
    out = proc.stdout.read().decode()
    proc.stdout.close()
    return out, b''.join(shown).decode(), proc.wait(timeout=600)


def test_the_live_display_on_a_terminal_stays_within_its_width(records):
    out, shown, code = _run_on_terminal([records / 'short.csv', '--explain', '--bootstrap', '1'])
    assert code == 0, shown
    text = ANSI.sub('', shown)
    # Every stretch the terminal draws between two returns fits its 80 columns.
    assert max(len(piece) for piece in re.split(r'[\r\n]', text)) <= WIDTH
    # What stays on the screen: one line per line written (the live line is redrawn in
    # place after a return, and removed at the end).
    kept = [line.rstrip('\r').split('\r')[-1] for line in text.split('\n')]
    assert [x for x in kept if x.startswith('candidate fits')] == ['candidate fits 16/16']
    assert [x for x in kept if x.startswith('kano: search level')] != []
    assert '\x1b[?25h' in shown             # the cursor is shown again
    assert out.startswith('short: stiction (')


def test_no_runtime_warning_leaks_from_a_default_or_explain_run(records):
    # The gaps put a plain-model breakaway at the end of a valid stretch, where the
    # residual after it was an empty mean.
    for extra in ([], ['--explain', '--bootstrap', '1']):
        res = analyze(records / 'gap.csv', '--quiet', *extra, strict=True)
        assert res.returncode == 0, res.stderr
        assert res.stderr == ''


def test_a_valid_stretch_that_ends_at_rest_has_no_breakaway_there():
    n, stop = 40, 25
    t = np.arange(n, dtype=float)
    op = 50.0 + 0.1 * t
    mv = np.where(t < stop, 50.0, np.nan)
    model = mv.copy()
    resting = np.where((t >= 10) & (t < stop), 1.0, 0.0)
    resting[5] = 1.0            # one real breakaway, at sample 6
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        rows = locate.breakaways(t, op, mv, model, resting, 1.0)
    assert [r['t'] for r in rows] == [6.0]


def test_a_near_perfect_plain_fit_leaves_nothing_to_explain(tmp_path):
    # Choudhury's valve without noise, read through Kano's model: RMS error 5e-4 % of
    # span, a residual so small that its structure is no missing physics.
    loop_csv(tmp_path / 'clean.csv', model='choudhury', S=5.0, J=2.0, duration=2000,
             noise={'pv_std': 0.0, 'mv_std': 0.0, 'seed': 1})
    res = analyze(tmp_path / 'clean.csv', '--explain', '--bootstrap', '1', '--quiet',
                  '--json', tmp_path / 'r.json', '--html', tmp_path / 'r.html')
    assert res.returncode == 0, res.stderr
    rep = json.loads((tmp_path / 'r.json').read_text())
    m = rep['mismatch']
    assert rep['baseline']['mse_fit'] < 1e-6
    assert m['effect'] == 'none' and m['effects'] == []
    assert m['explanation'].startswith('Nothing is left to explain')
    assert 'unexplained' not in res.stdout
    assert 'mismatch: none (confidence 1.00): Nothing is left to explain' in res.stdout
    assert 'Nothing is left to explain' in (tmp_path / 'r.html').read_text()
    # The frictionless valve's best imitation of a limit cycle (a long dead time) is
    # printed beside what it loses to, so that its odd figures read as what they are.
    f, plain = rep['frictionless']['mse_holdout'], rep['baseline']['mse_holdout']
    assert f > plain
    assert f'held-out MSE {f:.4g}, worse than the plain friction model ({plain:.4g})' in res.stdout


def test_plain_lines_wrap_to_the_width_and_count_only_now_and_then(monkeypatch):
    monkeypatch.setenv('COLUMNS', '40')
    now = [0.0]
    stream = io.StringIO()
    say = PlainLines(stream, every=10.0, clock=lambda: now[0])
    path = 'a/very/long/path/to/a/recording/of/the/loop/called/FIC101.csv'
    say(f'reading {path}')
    for k in range(1, 33):
        now[0] = float(k)
        say(Step('candidate fits', k, 32, f'effect {k}'))
    say(Step('candidate fits', 32, 32))    # a second thread finishing at the same time
    lines = stream.getvalue().splitlines()
    # The path is longer than the width: it keeps a line of its own, whole, to copy.
    assert [x.strip() for x in lines[:-4]] == ['reading', path]
    assert max(len(x) for x in lines if path not in x) <= 40
    counted = [x for x in lines if x.startswith('candidate fits')]
    # Started at 1 s: a line at 11, 21 and 31 s, then the end once.
    assert counted == ['candidate fits 11/32, effect 11', 'candidate fits 21/32, effect 21',
                       'candidate fits 31/32, effect 31', 'candidate fits 32/32, effect 32']


def test_after_explain_the_terminal_gives_the_explained_size_and_the_friction_figures():
    # The size line is the plain model's; with a lag on the position reading it reads
    # J 0 for a valve of J 1 (demo part 2): the explained model's size must follow.
    from stiction_ros.app.report_text import _mismatch_lines
    report = {'stiction': {'detected': True},
              'baseline': {'S': 3.086, 'J': 0.001, 'mse_fit': 0.587, 'mse_holdout': 0.8185},
              'mismatch': {'effect': 'measurement_lag', 'confidence': 1.0, 'explanation': '',
                           'effects': [], 'mse_holdout': 0.05027, 'friction': True,
                           'friction_kind': 'stiction',
                           'model': {'name': 'kano+measurement_lag',
                                     'params': {'S': 2.974, 'J': 0.981,
                                                'time_constant_s': 3.059}}},
              'frictionless': {'dead_time_s': 0.0, 'lag_s': 4.17, 'offset': 0.0, 'gain': 1.0,
                               'stages': ['tau'], 'mse_holdout': 0.6698}}
    text = _mismatch_lines(report)
    assert ('explained model: kano+measurement_lag S=2.974 J=0.981 (time_constant_s 3.059)'
            in text)
    assert ('friction: stiction claimed (held-out MSE of the explained model 0.05027, of the '
            'best valve without friction 0.6698)') in text
    report['mismatch'].update(friction=False, friction_kind='none', model=None)
    text = _mismatch_lines(report)
    assert 'explained model:' not in text and '\nfriction: not claimed\n' in text

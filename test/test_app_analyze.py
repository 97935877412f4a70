"""
The analyzer's use-case layer: ``analyze_file(AnalyzeOptions(...))`` without the command line.

Its report must be the one ``stiction-analyze --json`` writes for the same
file (timings aside), bad options must fail when they are made, with a
message naming the option, and drawing the figures must leave the caller's
matplotlib alone.
"""

import dataclasses
import json
import os
import pickle
import subprocess
import sys

import pytest

from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
from stiction_ros.app.report_text import summary_text, to_json_text
from stiction_ros.errors import InputError, StictionError
from test_analyze_cli import analyze, loop_csv


def _untimed(x):
    # Wall-clock times differ between any two runs; everything else must not.
    if isinstance(x, dict):
        return {k: _untimed(v) for k, v in x.items()
                if k not in ('elapsed_s', 'seconds') and not k.endswith('_seconds')}
    if isinstance(x, list):
        return [_untimed(v) for v in x]
    return x


@pytest.fixture(scope='module')
def loop(tmp_path_factory):
    d = tmp_path_factory.mktemp('app')
    loop_csv(d / 'loop.csv', duration=1500)
    return d


def test_the_report_is_the_one_the_command_line_writes(loop):
    res = analyze(loop / 'loop.csv', '--model', 'kano', '--json', loop / 'cli.json')
    assert res.returncode == 0, res.stderr
    said = []
    analysis = analyze_file(AnalyzeOptions(loop / 'loop.csv', model='kano',
                                           json_path=loop / 'app.json'), said.append)
    cli = json.loads((loop / 'cli.json').read_text())
    app = json.loads((loop / 'app.json').read_text())
    assert 'elapsed_s' in cli and 'elapsed_s' in app
    assert _untimed(app) == _untimed(cli)
    # The returned report is the one written, and the printed verdict is the command's.
    assert _untimed(json.loads(to_json_text(analysis.report))) == _untimed(app)
    assert summary_text(analysis.report, [str(loop / 'cli.json')]) == res.stdout.rstrip('\n')
    assert said[0] == f'reading {loop / "loop.csv"}' and said[-1] == f'wrote {loop / "app.json"}'
    # The search is said once per level, naming the model.
    assert [s for s in said if s.startswith('kano: search level 1/')]
    assert [f['model'] for f in app['fits']] == ['kano']


def test_the_html_page_embeds_every_figure_the_signatures_too(loop):
    analyze_file(AnalyzeOptions(str(loop / 'loop.csv'), model='kano',
                                html_path=str(loop / 'r.html')))
    html = (loop / 'r.html').read_text()
    figs = sorted(p.name for p in (loop / 'r_figures').glob('*.png'))
    assert {'trends.png', 'maps.png', 'signatures.png', 'landscape_kano.png'} <= set(figs)
    for name in figs:
        assert f'alt="{name}" src="data:image/png;base64,' in html, name


@pytest.mark.parametrize('change, words', [
    ({'jobs': 0}, ('jobs', '--jobs', '1 or more', 'leave it out')),
    ({'bootstrap': -1}, ('bootstrap', '--bootstrap', '0 or more', 'default 3')),
    ({'bootstrap': 1.5}, ('bootstrap', 'whole number')),
    ({'holdout': 1.5}, ('holdout', '--holdout', '[0, 0.9)', 'default 0.3')),
    ({'holdout': float('nan')}, ('holdout', '[0, 0.9)')),
    ({'S': 3.0}, ('give both S and J, or neither',)),
    ({'S': 120.0, 'J': 1.0}, ('S = 120.0', '[0, 100]')),
    ({'model': 'kanoo'}, ('model must be one of', "'kanoo'")),
    ({'loop_type': 'level'}, ('loop type must be one of', "'level'")),
    ({'window': (10.0,)}, ('window', '--window T0 T1', 'two times')),
    ({'window': (0.0, float('inf'))}, ('window', 'finite')),
    ({'input': ''}, ('input is empty', 'CSV')),
    ({'json_path': 3}, ('json_path', 'path')),
])
def test_bad_options_fail_when_made_and_say_which_and_how(change, words):
    kwargs = {'input': 'no/such/file.csv', **change}
    with pytest.raises(InputError) as err:
        AnalyzeOptions(**kwargs)
    assert isinstance(err.value, StictionError) and isinstance(err.value, ValueError)
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_options_are_frozen_normalised_and_travel_to_worker_processes(tmp_path):
    o = AnalyzeOptions(tmp_path / 'a.csv', S=3, J=1, window=[0, 100], jobs=2,
                       json_path=tmp_path / 'r.json')
    assert o.input == str(tmp_path / 'a.csv') and o.json_path == str(tmp_path / 'r.json')
    assert (o.S, o.J, o.window) == (3.0, 1.0, (0.0, 100.0)) and isinstance(o.S, float)
    assert pickle.loads(pickle.dumps(o)) == o
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.jobs = 1
    # replace() checks again: a worker's copy cannot be made invalid either.
    with pytest.raises(InputError):
        dataclasses.replace(o, jobs=0)


def test_the_command_line_reports_a_bad_option_in_one_line_exit_2(loop):
    res = analyze(loop / 'loop.csv', '--bootstrap', '-1')
    assert res.returncode == 2 and 'Traceback' not in res.stderr
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith('stiction-analyze: error: bootstrap (--bootstrap)')


def test_drawing_the_figures_chooses_no_matplotlib_backend(loop):
    # A caller with its own backend keeps it, and pyplot is never loaded.
    code = '\n'.join([
        'import sys, matplotlib',
        "matplotlib.use('svg')",
        'from stiction_ros.app.analyze import analyze_file, AnalyzeOptions',
        'import stiction_ros.study.plots, stiction_ros.viz.figures',
        'import stiction_ros.viz.mismatch_figures, stiction_ros.viz.signature_plots',
        f"analyze_file(AnalyzeOptions({str(loop / 'loop.csv')!r}, model='kano', "
        f"S=3.5, J=1.2, html_path={str(loop / 'svg' / 'r.html')!r}))",
        "assert matplotlib.get_backend() == 'svg', matplotlib.get_backend()",
        "assert 'matplotlib.pyplot' not in sys.modules",
    ])
    env = {k: v for k, v in os.environ.items() if k != 'MPLBACKEND'}
    res = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         env=env, timeout=300)
    assert res.returncode == 0, res.stderr
    assert (loop / 'svg' / 'r_figures' / 'trends.png').stat().st_size > 10_000


def test_each_part_of_a_long_analysis_is_said_as_a_step_before_it_runs(loop):
    from stiction_ros.app.progress import Step
    said = []
    analyze_file(AnalyzeOptions(loop / 'loop.csv', model='kano'), said.append)
    parts = [s for s in said if isinstance(s, Step) and s.task == 'analysing']
    # With MV the fits answer; only the signatures run after them, a bar of one part.
    assert [(p.detail, p.done, p.total) for p in parts] == [('signatures', 0, 1)]
    assert not parts[0].finished
    # OP and PV alone: the detector, the signatures, then the size from OP and PV.
    lines = (loop / 'loop.csv').read_text().splitlines()
    head = lines[0].split(',')
    keep = [i for i, c in enumerate(head) if c != 'mv']
    (loop / 'oppv.csv').write_text('\n'.join(','.join(line.split(',')[i] for i in keep)
                                             for line in lines) + '\n')
    said = []
    analysis = analyze_file(AnalyzeOptions(loop / 'oppv.csv'), said.append)
    parts = [s for s in said if isinstance(s, Step) and s.task == 'analysing']
    assert [p.detail for p in parts] == ['learned detector', 'signatures', 'Hammerstein fit']
    assert [p.done for p in parts] == [0, 1, 2] and not any(p.finished for p in parts)
    assert analysis.report['stiction']['detector']['judgeable']['ok']

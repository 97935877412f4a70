"""Where reports go: never over a recording, never over each other, never merged."""

import json
import shutil

import pytest

from stiction_ros.app.analyze import AnalyzeOptions
from stiction_ros.app.batch import expand, report_names
from stiction_ros.cli.analyze import EXIT_INPUT, main
from stiction_ros.errors import InputError
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop, write_csv
from stiction_ros.sim.loop_config import load_loop
from test_analysis_inputs import write_bag


@pytest.fixture(scope='module')
def loop():
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot')
    return simulate_loop(cfg, duration=300.0)


@pytest.fixture
def csv(loop, tmp_path):
    path = tmp_path / 'loop.csv'
    write_csv(path, loop)
    return path


def test_a_report_over_the_recording_or_over_the_other_report_is_refused(csv, tmp_path,
                                                                         capsys):
    before = csv.read_bytes()
    for argv in ([str(csv), '--json', str(csv)],
                 [str(csv), '--html', str(tmp_path / '.' / 'loop.csv')],
                 [str(csv), '--json', str(tmp_path / 'r'), '--html', str(tmp_path / 'r')]):
        assert main([*argv, '--quiet']) == EXIT_INPUT
        err = capsys.readouterr().err
        assert err.count('\n') == 1 and 'error:' in err and 'overwrite' in err
    other = tmp_path / 'other.csv'
    write_csv(other, {'t': [0.0, 1.0], 'op': [1.0, 2.0], 'sp': [0, 0], 'pv': [0, 0],
                      'mv': [1, 2]})
    with pytest.raises(InputError, match='looks like a recording'):
        AnalyzeOptions(str(csv), json_path=str(other))
    assert csv.read_bytes() == before and not (tmp_path / 'r').exists()


def test_a_report_that_cannot_be_written_names_the_option(csv, capsys):
    assert main([str(csv), '--quiet', '--json', '/proc/no/r.json']) == EXIT_INPUT
    assert 'cannot write the JSON report (--json) /proc/no/r.json' in capsys.readouterr().err


def test_loose_mcap_files_in_a_folder_are_recordings_of_their_own(loop, tmp_path):
    # Read as one bag before, two recordings' samples were merged without a word.
    bag = write_bag(tmp_path / 'made', loop)
    folder = tmp_path / 'runs'
    folder.mkdir()
    for name in ('a.mcap', 'b.mcap'):
        shutil.copy(next(bag.glob('*.mcap')), folder / name)
    # A recorder killed before its metadata.yaml: files named as rosbag2 names them.
    killed = folder / 'killed'
    killed.mkdir()
    shutil.copy(next(bag.glob('*.mcap')), killed / 'killed_0.mcap')
    shutil.copy(next(bag.glob('*.mcap')), killed / 'killed_1.mcap')
    assert expand(str(folder)) == [str(folder / 'a.mcap'), str(folder / 'b.mcap'),
                                   str(killed)]
    assert expand(str(killed)) is None and expand(str(bag)) is None
    summary = tmp_path / 's.json'
    assert main([str(folder), '--quiet', '--jobs', '1', '--json', str(summary)]) == 0
    rows = json.loads(summary.read_text())['rows']
    assert len(rows) == 3 and all(r['ok'] for r in rows)
    # Each loose file is the whole loop, once: S and J as the simulation drew them.
    for r in rows[:2]:
        assert [round(f['S'], 2) for f in r['fits']] == [round(rows[0]['fits'][0]['S'], 2)] * 2


def test_reports_of_paths_that_flatten_alike_are_all_kept(csv, tmp_path):
    col = tmp_path / 'col'
    for sub in ('a/b', 'a_b'):
        (col / sub).mkdir(parents=True)
        shutil.copy(csv, col / sub / 'c.csv')
    names = report_names([str(col / 'a/b/c.csv'), str(col / 'a_b/c.csv')], col)
    assert len(set(names.values())) == 2
    out = tmp_path / 'reports'
    assert main([str(col), '--quiet', '--jobs', '1', '--out-dir', str(out)]) == 0
    reports = sorted(out.glob('*.json'))
    assert len(reports) == 2
    inputs = {json.loads(p.read_text())['input']['path'] for p in reports}
    assert inputs == {str(col / 'a/b/c.csv'), str(col / 'a_b/c.csv')}
    # Names that do not collide stay as they were.
    one = str(col / 'a/b/c.csv')
    assert report_names([one], col) == {one: 'a_b_c.csv.json'}


def test_out_dir_with_one_recording_writes_its_report_there(csv, tmp_path, capsys):
    out = tmp_path / 'one'
    assert main([str(csv), '--quiet', '--out-dir', str(out)]) == 0
    assert json.loads((out / 'loop.csv.json').read_text())['input']['path'] == str(csv)
    assert main([str(csv), '--quiet', '--out-dir', str(out), '--json', 'r.json']) == EXIT_INPUT
    assert 'give one of them' in capsys.readouterr().err


def test_a_killed_recorders_bag_given_as_dot_is_one_bag(loop, tmp_path, monkeypatch):
    bag = write_bag(tmp_path / 'killed', loop)
    (bag / 'metadata.yaml').unlink()
    monkeypatch.chdir(bag)
    assert expand('.') is None
    out = tmp_path / 'out'
    assert main(['.', '--quiet', '--no-hammerstein', '--out-dir', str(out)]) == 0
    assert [p.name for p in out.iterdir()] == ['killed.json']


def test_an_unwritable_out_dir_is_each_rows_error_not_the_end_of_the_audit(csv, tmp_path):
    folder = tmp_path / 'two'
    folder.mkdir()
    for name in ('a.csv', 'b.csv'):
        shutil.copy(csv, folder / name)
    blocked = tmp_path / 'file'
    blocked.write_text('not a folder')
    summary = tmp_path / 's.json'
    assert main([str(folder), '--quiet', '--jobs', '1', '--no-hammerstein', '--out-dir',
                 str(blocked), '--json', str(summary)]) == EXIT_INPUT
    rows = json.loads(summary.read_text())['rows']
    assert len(rows) == 2 and all('cannot write its report (--out-dir)' in r['error']
                                  for r in rows)


def test_a_page_is_written_only_to_html_and_a_report_never_to_html(csv, tmp_path, capsys):
    # `--html r.json` had replaced the JSON report of an earlier run with a page.
    report = tmp_path / 'r.json'
    report.write_text('{"earlier": true}\n')
    for argv, flag in (([str(csv), '--html', str(report)], '--html'),
                       ([str(csv), '--json', str(tmp_path / 'r.html')], '--json')):
        assert main([*argv, '--quiet']) == EXIT_INPUT
        err = capsys.readouterr().err
        assert f'({flag}) ' in err and '.html' in err
    assert report.read_text() == '{"earlier": true}\n'
    assert not (tmp_path / 'r.html').exists()


def test_a_report_that_cannot_be_written_is_refused_before_the_recording_is_read(
        csv, tmp_path, capsys):
    blocker = tmp_path / 'a_file'
    blocker.write_text('not a folder\n')
    target = blocker / 'sub' / 'r.html'
    assert main([str(csv), '--quiet', '--html', str(target)]) == EXIT_INPUT
    err = capsys.readouterr().err
    assert f'cannot write the HTML report (--html) {target}: {blocker} is not a folder' in err
    assert 'checked before the recording is read' in err


@pytest.mark.parametrize('case', ['folder at the report', 'file at the figures',
                                  'dangling link'])
def test_other_paths_a_report_cannot_take_are_refused_before_reading(csv, tmp_path, case):
    if case == 'folder at the report':
        (tmp_path / 'r.json').mkdir()
        argv, why = ['--json', str(tmp_path / 'r.json')], 'is a folder'
    elif case == 'file at the figures':
        (tmp_path / 'r_figures').write_text('')
        argv, why = ['--html', str(tmp_path / 'r.html')], 'is not a folder'
    else:
        (tmp_path / 'gone').symlink_to(tmp_path / 'nowhere')
        argv, why = ['--json', str(tmp_path / 'gone' / 'r.json')], 'is a link to nothing'
    with pytest.raises(InputError, match=why):
        AnalyzeOptions(str(csv), **{('json_path' if argv[0] == '--json' else 'html_path'):
                                    argv[1]})


def test_a_report_that_replaces_another_recordings_says_whose(csv, tmp_path, capsys):
    second = tmp_path / 'second.csv'
    shutil.copy(csv, second)
    json_path, html_path = tmp_path / 'r.json', tmp_path / 'r.html'
    assert main([str(csv), '--json', str(json_path), '--html', str(html_path)]) == 0
    assert 'held the report of' not in capsys.readouterr().err
    # The same recording again: its own report, replaced without a note.
    assert main([str(csv), '--json', str(json_path)]) == 0
    assert 'held the report of' not in capsys.readouterr().err
    assert main([str(second), '--json', str(json_path), '--html', str(html_path)]) == 0
    out = ' '.join(capsys.readouterr().err.split())   # long lines are wrapped
    assert f'note: {json_path} held the report of {csv}; it is replaced' in out
    assert f'note: {html_path} held the report of {csv.resolve()}; it is replaced' in out
    assert json.loads(json_path.read_text())['input']['path'] == str(second)

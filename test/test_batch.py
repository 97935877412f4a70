"""stiction-analyze on a folder or a glob: fan-out over processes and over a Dask cluster."""

import json
from pathlib import Path
import shutil

from data_paths import plant_loops_dir
import pytest

from stiction_ros.cli.analyze import EXIT_INPUT, main
from stiction_ros.sim.closed_loop import write_csv
from stiction_ros.sim.concealed_cases import concealed_case

pytestmark = pytest.mark.slow


@pytest.fixture(scope='module')
def plant_folder(tmp_path_factory):
    # Four real plant loops in nested folders, a broken CSV and a file that is no recording.
    loops = plant_loops_dir()
    if loops is None:
        pytest.skip('the shared plant loops are not beside this checkout')
    root = tmp_path_factory.mktemp('audit')
    # With two answered "cannot tell" for different reasons: balanced evidence, a PV of zero.
    picks = sorted((loops / 'stiction').glob('*.txt'))[:1] + \
        sorted((loops / 'no_stiction').glob('*.txt'))[:1] + \
        sorted((loops / 'stiction').glob('*FIC20102_0609_0957*')) + \
        sorted((loops / 'stiction').glob('*FIC10112_0630*'))
    for i, src in enumerate(picks):
        (root / f'unit{i}').mkdir()
        shutil.copy(src, root / f'unit{i}' / src.name)
    # A simulated loop with the valve position, so that S and J are identified too.
    record, _ = concealed_case('asymmetric_friction', 2, duration=2000.0)
    write_csv(root / 'unit0' / 'loop.csv', {k: record[k] for k in ('t', 'sp', 'pv', 'op', 'mv')})
    picks.append(root / 'unit0' / 'loop.csv')
    (root / 'broken.csv').write_text('t,op\n0,1\n1,\n')
    (root / 'README.md').write_text('not a recording\n')
    return root, picks


def _rows(path):
    return {Path(r['input']).name: r for r in json.loads(path.read_text())['rows']}


def test_a_folder_is_analysed_recording_by_recording_and_a_bad_one_is_one_row(
        plant_folder, tmp_path, capsys):
    root, picks = plant_folder
    code = main([str(root), '--jobs', '2', '--quiet', '--json', str(tmp_path / 's.json'),
                 '--out-dir', str(tmp_path / 'reports')])
    assert code == EXIT_INPUT       # one recording failed; the others are still reported
    rows = _rows(tmp_path / 's.json')
    assert set(rows) == {p.name for p in picks} | {'broken.csv'}
    assert not rows['broken.csv']['ok'] and 'broken.csv' in rows['broken.csv']['error']
    for p in picks:
        row = rows[p.name]
        assert row['ok'], row
        assert bool(row['fits']) == (p.suffix == '.csv')     # the plant loops have no MV
        report = json.loads(Path(row['report']).read_text())
        assert report['stiction']['detected'] == row['detected']
    out = capsys.readouterr().out
    assert '6 recordings' in out and '1 failed' in out and 'error:' in out
    # The tally tells a case for a travel test from a record that cannot be judged.
    why = {p.name: rows[p.name].get('why_not') for p in picks}
    assert sorted(w for w in why.values() if w) == ['evidence balanced', 'pv constant']
    assert '2 cannot tell (1 evidence balanced, 1 pv constant)' in out


def test_the_same_audit_runs_on_a_dask_cluster(plant_folder, tmp_path):
    distributed = pytest.importorskip('distributed')
    root, picks = plant_folder
    pattern = str(root / 'unit*' / '*.*')
    assert main([pattern, '--jobs', '1', '--quiet', '--json', str(tmp_path / 'local.json')]) == 0
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None, host='127.0.0.1') as cluster:
        assert main([pattern, '--scheduler', cluster.scheduler_address, '--quiet',
                     '--json', str(tmp_path / 'dask.json')]) == 0
    local, dask = _rows(tmp_path / 'local.json'), _rows(tmp_path / 'dask.json')
    assert set(local) == set(dask) == {p.name for p in picks}
    assert local['loop.csv']['fits']
    for name in local:
        assert dask[name]['fits'] == local[name]['fits']
        assert dask[name]['score'] == local[name]['score']
        assert dask[name]['detected'] == local[name]['detected']
    assert 'Dask cluster tcp://127.0.0.1' in json.loads((tmp_path / 'dask.json').read_text())[
        'workers']


def test_a_glob_that_matches_nothing_is_a_one_line_error(tmp_path, capsys):
    assert main([str(tmp_path / '*.csv'), '--quiet']) == EXIT_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'no file matches' in err[0]


def test_an_audit_writes_a_page_per_recording_beside_its_report(
        plant_folder, tmp_path, capsys):
    root, picks = plant_folder
    out = tmp_path / 'reports'
    pattern = str(root / 'unit[01]' / '*.txt')
    assert main([pattern, '--jobs', '2', '--quiet', '--json', str(tmp_path / 's.json'),
                 '--out-dir', str(out), '--pages']) == 0
    rows = _rows(tmp_path / 's.json')
    assert set(rows) == {p.name for p in picks[:2]}
    for row in rows.values():
        page = Path(row['page'])
        assert page.parent == out and page.name == Path(row['report']).name[:-5] + '.html'
        text = page.read_text(encoding='utf-8')
        report = json.loads(Path(row['report']).read_text())
        assert report['name'] in text and 'data:image/png;base64,' in text
        assert (out / (page.stem + '_figures') / 'trends.png').is_file()
    # An index beside them lists every recording, each linked to its page.
    index = (out / 'index.html').read_text(encoding='utf-8')
    for row in rows.values():
        cls = {'stiction': 'yes', 'no stiction': 'no'}.get(row['answer'], 'und')
        assert f'<a href="{Path(row["page"]).name}">' in index
        assert f'<span class="{cls}">{row["answer"]}</span>' in index
    assert '2 recordings' in index
    # One recording: its page where the folder's run would put it.
    one = tmp_path / 'one'
    assert main([str(picks[0]), '--quiet', '--out-dir', str(one), '--pages']) == 0
    assert sorted(p.suffix for p in one.iterdir() if p.is_file()) == ['.html', '.json']
    # A page needs the folder its report goes to.
    capsys.readouterr()
    assert main([pattern, '--quiet', '--pages']) == EXIT_INPUT
    assert 'give --out-dir' in capsys.readouterr().err

"""Bad options and damaged files: one line, the documented exit status, nothing lost."""

import json
import os
import shutil

import numpy as np
import pytest

from stiction_ros.cli import analyze, bag as bag_cli, loop as loop_cli, sim, study
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop, write_csv
from stiction_ros.sim.loop_config import load_loop
from test_analysis_inputs import write_bag


@pytest.fixture(scope='module')
def loop():
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot')
    return simulate_loop(cfg, duration=300.0)


def _one_line(capsys, *words):
    err = capsys.readouterr().err.strip().splitlines()
    assert err and 'Traceback' not in '\n'.join(err)
    assert all(w in err[-1] for w in words), err[-1]


@pytest.mark.parametrize('value', ['-5', 'nan'])
def test_stiction_sim_refuses_a_duration_that_is_no_time(value, capsys):
    with pytest.raises(SystemExit) as stop:
        sim.main(['concentration_loop.yaml', '--quiet', '--duration', value])
    assert stop.value.code == 2
    _one_line(capsys, '--duration must be a positive number of seconds')


def test_stiction_sim_names_a_csv_it_cannot_write(tmp_path, capsys):
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    target = blocker / 'x' / 's.csv'
    assert sim.main(['concentration_loop.yaml', '--quiet', '--duration', '10',
                     '-o', str(target)]) == 2
    _one_line(capsys, f'cannot write {target}', 'is not a folder', 'before the run')
    # A missing folder is made, as the analyzer's reports do.
    made = tmp_path / 'new' / 'deeper' / 's.csv'
    assert sim.main(['concentration_loop.yaml', '--quiet', '--duration', '10',
                     '-o', str(made)]) == 0 and made.is_file()


@pytest.mark.parametrize('name', ['run.mcap', 'loop.yaml'])
def test_stiction_sim_writes_csv_only_and_never_over_its_loop_file(tmp_path, capsys, name):
    loop_file = tmp_path / 'loop.yaml'
    shutil.copy(config_file('concentration_loop.yaml'), loop_file)
    before = loop_file.read_bytes()
    assert sim.main([str(loop_file), '--quiet', '--duration', '10',
                     '-o', str(tmp_path / name)]) == 2
    _one_line(capsys, 'name a .csv file')
    assert loop_file.read_bytes() == before and not (tmp_path / 'run.mcap').exists()


@pytest.mark.parametrize('setting, words', [
    ('noise.mv_std=abc', 'noise.mv_std: must be a standard deviation >= 0'),
    ('noise.pv_std=-1', 'noise.pv_std: must be a standard deviation >= 0'),
    ('noise.seed=[1,2]', 'noise.seed: must be a whole number >= 0'),
    ('duration=.inf', 'duration: must be a positive number of seconds'),
    ('case=overshoot', 'choose a case with --case NAME'),
    ('plant.mv0=120', 'plant.mv0: must be a valve position within its travel, 0-100 %'),
])
def test_stiction_sim_names_a_bad_setting_in_one_line(setting, words, capsys):
    assert sim.main(['concentration_loop.yaml', '--quiet', '--set', setting]) == 2
    _one_line(capsys, words)


def test_a_number_yaml_reads_as_text_is_a_number_still(tmp_path):
    # YAML reads 1e3 (no dot) as a string.
    cfg = load_loop(config_file('concentration_loop.yaml'),
                    overrides={'duration': '1e3', 'sample_time': '1e0'})
    assert cfg['duration'] == 1000.0 and cfg['sample_time'] == 1.0


def test_a_folder_given_as_the_loop_file_is_named_a_folder(tmp_path, capsys):
    assert sim.main([str(tmp_path), '--quiet']) == 2
    _one_line(capsys, 'a folder, not a loop file')


def test_a_file_that_is_no_text_is_no_loop_file(tmp_path, capsys):
    (tmp_path / 'bin.yaml').write_bytes(b'\xff\xfe\x00binary')
    assert sim.main([str(tmp_path / 'bin.yaml'), '--quiet']) == 2
    _one_line(capsys, 'not a loop file (not UTF-8 text)')


def test_ctrl_c_ends_a_command_in_one_line_with_status_130(capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt
    monkeypatch.setattr(sim, 'simulate_loop', interrupted)
    assert sim.main(['concentration_loop.yaml', '--quiet']) == 130
    _one_line(capsys, 'interrupted')


def test_a_simulated_csv_reads_back_bit_for_bit(loop, tmp_path):
    # Ten digits moved a slip by a sample on the stick band's edge: J 2.00 read as 1.99.
    path = tmp_path / 'loop.csv'
    write_csv(path, loop)
    back = np.genfromtxt(path, delimiter=',', names=True)
    for name in ('t', 'sp', 'op', 'mv', 'pv'):
        np.testing.assert_array_equal(back[name], loop[name])


def test_a_csv_write_stopped_half_way_leaves_the_earlier_file_whole(tmp_path):
    rows = 200_000                          # more than one block of rows
    data = {c: np.linspace(0.0, 1.0, rows) for c in ('t', 'sp', 'op', 'mv', 'pv')}
    path = tmp_path / 'loop.csv'
    path.write_text('t,op\n0,1\n')
    seen = []

    def stop(done, total):
        seen.append((done, total))
        raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        write_csv(path, data, progress=stop)
    assert seen == [(65536, rows)]
    assert path.read_text() == 't,op\n0,1\n' and os.listdir(tmp_path) == ['loop.csv']
    # Written through, its progress ends at every row, and the rows read back.
    write_csv(path, data, progress=lambda done, total: seen.append((done, total)))
    assert seen[-1] == (rows, rows) and len(path.read_text().splitlines()) == rows + 1


def test_stiction_study_names_a_missing_loop_file(capsys):
    with pytest.raises(SystemExit) as stop:
        study.main(['--config', 'no-such-loop.yaml', '--out', '/nonexistent-dir/study'])
    assert stop.value.code == 2
    _one_line(capsys, "--config: config 'no-such-loop.yaml': no such file")


def test_loop_checks_its_options_before_starting_a_node(capsys):
    # Nothing may start: the error comes before the first node would be spawned.
    assert loop_cli.main(['concentration_loop.yaml', '--duration', '-5', '--rtf', '100']) == 2
    _one_line(capsys, '--duration must be a positive number of seconds')
    assert loop_cli.main(['no-such-loop.yaml']) == 2
    _one_line(capsys, 'no-such-loop.yaml')


def test_a_bare_mcap_cut_short_is_flagged_on_the_terminal_and_repaired_in_place(
        loop, tmp_path, capsys):
    made = write_bag(tmp_path / 'made', loop, chunk_size=1024)
    whole = next(made.glob('*.mcap')).read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(whole[:len(whole) // 2])
    assert analyze.main([str(cut), '--quiet', '--no-hammerstein']) == 0
    out = capsys.readouterr().out
    warning = [line for line in out.splitlines() if line.strip().startswith('warning:')]
    assert len(warning) == 1 and 'ends early' in warning[0]
    assert f'stiction-bag repair {cut}' in warning[0]
    assert bag_cli.main(['repair', str(cut)]) == 0
    assert 'recovered' in capsys.readouterr().out
    # The damaged original is kept; the repaired file reads as complete.
    assert (tmp_path / 'cut.mcap.damaged').read_bytes() == whole[:len(whole) // 2]
    assert bag_cli.main(['info', str(cut)]) == 0
    assert '(complete)' in capsys.readouterr().out
    assert analyze.main([str(cut), '--quiet', '--no-hammerstein', '--json',
                         str(tmp_path / 'r.json')]) == 0
    assert 'warnings' not in json.loads((tmp_path / 'r.json').read_text())['input']


def test_stiction_bag_errors_exit_2(tmp_path, capsys):
    assert bag_cli.main(['info', str(tmp_path / 'none')]) == 2
    _one_line(capsys, 'stiction-bag: error:')
    (tmp_path / 'x.txt').write_text('not a bag')
    assert bag_cli.main(['repair', str(tmp_path / 'x.txt')]) == 2
    _one_line(capsys, 'a bag directory or an .mcap file')


def test_report_input_fields_are_json_objects(loop, tmp_path):
    made = write_bag(tmp_path / 'b', loop)
    shutil.rmtree(tmp_path / 'b.logs', ignore_errors=True)
    assert analyze.main([str(made), '--quiet', '--no-hammerstein', '--json',
                         str(tmp_path / 'r.json')]) == 0
    got = json.loads((tmp_path / 'r.json').read_text())['input']
    assert got['topics']['op'] == '/loop1/op' and isinstance(got['phases']['pv'], float)


def test_stiction_study_takes_a_shipped_loop_files_name(tmp_path, capsys):
    # Its help names concentration_loop.yaml as the default: the name alone is found.
    assert study.main(['--config', 'concentration_loop.yaml', '--out', str(tmp_path)]) == 0
    err = capsys.readouterr().err
    figures = len(list((tmp_path / 'figures').glob('*.png')))
    assert f'and {figures} figures' in err and figures == 7


def test_a_csv_written_through_a_link_lands_in_the_file_it_names(tmp_path):
    data = {c: np.arange(5.0) for c in ('t', 'sp', 'op', 'mv', 'pv')}
    real = tmp_path / 'real.csv'
    real.write_text('old\n')
    os.chmod(real, 0o640)
    link = tmp_path / 'link.csv'
    link.symlink_to(real)
    write_csv(link, data)
    # The link stays a link, the file it names gets the rows and keeps its permissions.
    assert link.is_symlink() and real.read_text().startswith('t,sp,op,mv,pv\n')
    assert (real.stat().st_mode & 0o777) == 0o640
    assert sorted(p.name for p in tmp_path.iterdir()) == ['link.csv', 'real.csv']

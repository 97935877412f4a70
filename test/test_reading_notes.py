"""What the reader did is said where the engineer looks: the terminal, and the page."""

import subprocess
import sys

from data_paths import plant_loops_dir
import numpy as np
import pytest

from stiction_ros.analysis.readers import load_record
from stiction_ros.errors import InputError

PLANT_LOOPS = plant_loops_dir()
plant = pytest.mark.skipif(PLANT_LOOPS is None, reason='shared plant loops not found')


def _plant_csv(path, header, sp_cells=None, pv_cells=None):
    """Write a plant record (FIC46005 of 2 September) as a CSV under ``header``."""
    f = sorted((PLANT_LOOPS / 'stiction').glob('*FIC46005_0902*'))[0]
    r = load_record(f)
    op, pv, sp = (np.asarray(r.signals[k], float) for k in ('op', 'pv', 'sp'))
    lines = [','.join(header)]
    for i in range(r.samples):
        p = (pv_cells or {}).get(i, f'{pv[i]:.8g}')
        s = (sp_cells or {}).get(i, f'{sp[i]:.8g}')
        lines.append(f'{r.t[i]:g},{op[i]:.8g},{p},{s}')
    path.write_text('\n'.join(lines) + '\n')
    return path


def analyze(*args):
    return subprocess.run([sys.executable, '-m', 'stiction_ros.cli.analyze', *map(str, args)],
                          capture_output=True, text=True, timeout=300)


@plant
@pytest.mark.parametrize('name', ['Setpoint', 'Set point', 'FIC101.Setpoint', 'SP (kg/h)'])
def test_a_set_point_column_named_as_engineers_name_it_is_read(tmp_path, name):
    path = _plant_csv(tmp_path / 'l.csv', ['t', 'FIC101.OP', 'FIC101.PV', name])
    rec = load_record(path)
    assert rec.has('sp') and not any('ignored' in n for n in rec.notes)


@plant
def test_the_words_a_historian_writes_for_no_value_are_missing_values_and_said(tmp_path):
    words = {10: '<null>', 11: '---', 12: '?', 13: 'I/O Timeout'}
    path = _plant_csv(tmp_path / 'w.csv', ['Time', 'OP', 'PV', 'Setpoint'], pv_cells=words)
    rec = load_record(path)
    assert np.isnan(rec.signals['pv'][10:14]).all()
    res = analyze(path)
    assert res.returncode == 0, res.stderr
    # Said on the terminal, not only in the JSON: it decides what was analysed.
    assert "note: PV: 4 cells marked bad ('<null>', '---', '?', 'I/O Timeout')" in \
        ' '.join(res.stderr.split())


@plant
def test_an_ignored_column_is_named_on_the_terminal(tmp_path):
    path = _plant_csv(tmp_path / 'x.csv', ['t', 'OP', 'PV', 'Remarks'])
    res = analyze(path)
    assert res.returncode == 0, res.stderr
    assert 'signals op, pv\n' in res.stderr and 'note: ignored columns: Remarks' in res.stderr


@plant
def test_a_record_that_cannot_be_judged_has_no_score_of_zero_on_its_page(tmp_path):
    # OP as a fraction of its stroke: under the no-excitation floor, so not judged.
    f = sorted((PLANT_LOOPS / 'stiction').glob('*FIC46005_0902*'))[0]
    r = load_record(f)
    lines = ['t,op,pv,sp'] + [f'{t:g},{o / 100:.8g},{p:.8g},{s:.8g}' for t, o, p, s in zip(
        r.t, r.signals['op'], r.signals['pv'], r.signals['sp'])]
    path = tmp_path / 'frac.csv'
    path.write_text('\n'.join(lines) + '\n')
    res = analyze(path, '--html', tmp_path / 'p.html')
    assert res.returncode == 0, res.stderr
    page = (tmp_path / 'p.html').read_text()
    assert 'cannot tell &mdash; not judged, so no probability' in page
    assert 'score 0 (0 = none' not in page


def test_excel_serial_dates_are_read_as_dates_not_seconds(tmp_path):
    day0 = 45456.0 + (21 * 3600 + 55 * 60) / 86400.0      # 2024-06-13 21:55:00
    t = day0 + np.arange(300) * 10.0 / 86400.0
    rng = np.random.default_rng(0)
    lines = ['Time,op,pv'] + [f'{x:.8f},{50 + rng.normal():.4f},{20 + rng.normal():.4f}'
                              for x in t]
    path = tmp_path / 'xl.csv'
    path.write_text('\n'.join(lines) + '\n')
    rec = load_record(path)
    assert rec.sample_time == pytest.approx(10.0, abs=1e-3) and rec.samples == 300
    assert rec.start_time.startswith('2024-06-13T21:55:00')
    assert any('Excel serial dates' in n for n in rec.notes)
    # Seconds that happen to lie in Excel's range but step by whole seconds stay seconds.
    lines = ['t,op,pv'] + [f'{45000 + 10 * k},{50 + rng.normal():.4f},{rng.normal():.4f}'
                           for k in range(300)]
    path.write_text('\n'.join(lines) + '\n')
    rec = load_record(path)
    assert rec.sample_time == 10.0 and not any('Excel' in n for n in rec.notes)


@pytest.mark.parametrize('rows', [
    [',%,kg/h'], ['s;%;kg/h'], ['Time,Valve output,Flow', ',%,kg/h']])
def test_units_and_description_rows_under_the_header_are_skipped_and_said(tmp_path, rows):
    delim = ';' if ';' in rows[0] else ','
    rng = np.random.default_rng(1)
    data = [delim.join([str(10 * k), f'{50 + rng.normal():.4f}', f'{rng.normal():.4f}'])
            for k in range(300)]
    path = tmp_path / 'u.csv'
    path.write_text('\n'.join([delim.join(['t', 'op', 'pv']), *rows, *data]) + '\n')
    rec = load_record(path)
    assert rec.samples == 300 and rec.sample_time == 10.0
    said = [n for n in rec.notes if 'read as units or descriptions' in n]
    assert [n.split()[1] for n in said] == [str(2 + i) for i in range(len(rows))]


def test_three_label_rows_are_not_taken_for_units_and_the_file_is_refused(tmp_path):
    data = [f'{10 * k},{50 + k % 3},{k % 5}' for k in range(300)]
    path = tmp_path / 'u.csv'
    path.write_text('\n'.join(['t,op,pv', ',%,kg/h', ',%,kg/h', ',%,kg/h', *data]) + '\n')
    with pytest.raises(InputError, match="row 2: t is ''"):
        load_record(path)


@plant
def test_columns_given_more_than_once_all_count_and_a_signal_twice_is_refused(tmp_path):
    path = _plant_csv(tmp_path / 'e.csv', ['Time', 'Output %', 'Flow kg/h', 'SP'])
    res = analyze(path, '--columns', 'op=Output %', '--columns', 'pv=Flow kg/h', '--json',
                  tmp_path / 'e.json')
    assert res.returncode == 0, res.stderr
    assert 'signals op, pv, sp' in res.stderr
    res = analyze(path, '--columns', 'op=Output %', '--columns', 'op=Flow kg/h')
    assert res.returncode == 2 and 'op is given twice' in res.stderr


@pytest.mark.parametrize('stamp', [lambda k: f'{10 * k}',
                                   lambda k: f'2024-06-13 21:{k // 6:02d}:{10 * (k % 6):02d}'])
def test_a_newest_first_export_is_read_oldest_first_and_said(tmp_path, stamp):
    rng = np.random.default_rng(2)
    rows = [f'{stamp(k)},{50 + rng.normal():.4f},{rng.normal():.4f}' for k in range(300)]
    path = tmp_path / 'old.csv'
    path.write_text('\n'.join(['Time,OP,PV', *rows]) + '\n')
    ahead = load_record(path)
    path = tmp_path / 'new.csv'
    path.write_text('\n'.join(['Time,OP,PV', *rows[::-1]]) + '\n')
    back = load_record(path)
    np.testing.assert_array_equal(back.signals['op'], ahead.signals['op'])
    assert back.start_time == ahead.start_time and back.sample_time == ahead.sample_time
    assert any('newest first' in n for n in back.notes)
    assert not any('newest first' in n for n in ahead.notes)


@pytest.mark.parametrize('header, manual', [('FIC101.MODE', 'MAN'), ('Mode', '0'),
                                            ('FIC101.MODE', 'IMAN')])
def test_rows_a_mode_column_puts_in_manual_are_excluded(tmp_path, header, manual):
    rng = np.random.default_rng(3)
    auto = '1' if manual == '0' else 'AUTO'
    rows = [f'{10 * k},{50 + rng.normal():.4f},{rng.normal():.4f},'
            f'{manual if 100 <= k < 160 else auto}' for k in range(400)]
    path = tmp_path / 'm.csv'
    path.write_text('\n'.join([f't,FIC101.OP,FIC101.PV,{header}', *rows]) + '\n')
    rec = load_record(path)
    assert np.flatnonzero(~rec.valid).tolist() == list(range(100, 160))
    assert rec.source['columns']['mode'] == header
    assert not any('ignored' in n for n in rec.notes)


def test_a_mode_column_of_unknown_codes_is_not_guessed_at(tmp_path):
    rows = [f'{10 * k},{50 + k % 7},{k % 5},{8 if k < 200 else 16}' for k in range(400)]
    path = tmp_path / 'm.csv'
    path.write_text('\n'.join(['t,op,pv,mode', *rows]) + '\n')
    rec = load_record(path)
    assert rec.valid.all() and 'mode' not in rec.source['columns']
    assert any("mode values '16', '8' are neither automatic" in n for n in rec.notes)


def test_a_stored_on_change_mode_holds_until_the_next_row():
    from stiction_ros.analysis.readers.modes import held
    got = held(np.array([0.0, 25.0, 50.0]), np.array([1.0, 0.0, 1.0]),
               np.array([-5.0, 0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0]))
    np.testing.assert_array_equal(got, [np.nan, 1, 1, 1, 0, 0, 1, 1])


@pytest.mark.parametrize('irregular', [False, True])
def test_a_mode_written_only_when_it_changes_holds_on_the_rows_between(tmp_path, irregular):
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(4.0, 16.0, 400)) if irregular else 10.0 * np.arange(400)
    cells = {100: 'MAN', 120: 'No Data', 160: 'AUTO'}
    rows = [f'{t[k]:.3f},{50 + rng.normal():.4f},{rng.normal():.4f},{cells.get(k, "")}'
            for k in range(400)]
    path = tmp_path / 'c.csv'
    path.write_text('\n'.join(['t,FIC1.OP,FIC1.PV,FIC1.MODE', *rows]) + '\n')
    rec = load_record(path)
    out = rec.t[~rec.valid] + rec.time_origin
    # Excluded from the MAN row's time to before the AUTO row's, nothing else.
    assert out.min() >= t[100] - rec.sample_time and out.max() < t[160]
    assert out.max() - out.min() > 0.8 * (t[160] - t[100])


def test_another_loops_mode_is_not_taken_for_this_ones(tmp_path):
    rows = [f'{10 * k},{50 + k % 7},{k % 5},{"MAN" if 100 <= k < 160 else "AUTO"}'
            for k in range(300)]
    path = tmp_path / 'o.csv'
    path.write_text('\n'.join(['t,FIC1.OP,FIC1.PV,P101.MODE', *rows]) + '\n')
    rec = load_record(path)
    assert rec.valid.all() and any('no column is the mode of' in n for n in rec.notes)


def test_a_fast_loggers_seconds_in_excels_range_stay_seconds(tmp_path):
    path = tmp_path / 'f.csv'
    path.write_text('\n'.join(['t,op,pv'] + [f'{30000 + 0.001 * k:.3f},{50 + k % 7},{k % 5}'
                                             for k in range(300)]) + '\n')
    rec = load_record(path)
    assert rec.sample_time == pytest.approx(0.001) and not any('Excel' in n for n in rec.notes)


@plant
def test_a_folder_audit_keeps_each_files_reading_notes_in_its_row(tmp_path):
    from stiction_ros.app.analyze import AnalyzeOptions
    from stiction_ros.app.batch import analyze_one
    path = _plant_csv(tmp_path / 'n.csv', ['t', 'OP', 'PV', 'Remarks'], pv_cells={10: 'Bad'})
    row = analyze_one(path, AnalyzeOptions(input=str(path), hammerstein=False))
    assert row['ok'] and row['warnings'] == []
    assert 'ignored columns: Remarks' in row['notes']
    assert any("1 cell marked bad ('Bad')" in n for n in row['notes'])
    assert not any(n.startswith('excluded ') for n in row['notes'])


@pytest.mark.parametrize('step, noted', [(1000, True), (300, True), (10, False), (1, False)])
def test_whole_number_stamps_a_long_sample_apart_say_they_were_read_as_seconds(
        tmp_path, step, noted):
    k = np.arange(300)
    rows = ''.join(f'{i * step},{50 + 5 * np.sin(i / 7):.4f},{20 + np.cos(i / 7):.4f}\n'
                   for i in k)
    path = tmp_path / 'ms.csv'
    path.write_text('t,op,pv\n' + rows)
    rec = load_record(path)
    assert rec.sample_time == step
    hint = [n for n in rec.notes if 'if they are milliseconds' in n]
    assert bool(hint) == noted
    if noted:
        assert f'whole numbers {step} apart' in hint[0] and "name the column 't (ms)'" in hint[0]
        path.write_text('t (ms),op,pv\n' + rows)
        rec = load_record(path)
        assert rec.sample_time == step / 1000 and not any('milliseconds' in n for n in rec.notes)


@pytest.mark.parametrize('header, units', [
    ('t,OP (mA),PV', None), ('t,OP,PV', 's,mA,kg/h'), ('t,op,pv', None)])
def test_a_controller_output_in_milliamps_is_read_as_percent_of_span(tmp_path, header, units):
    k = np.arange(300)
    ma = np.round(12 + 6 * np.sin(k / 9), 4)
    rows = ''.join(f'{i},{ma[i]:.4f},{20 + np.cos(i / 9):.4f}\n' for i in k)
    path = tmp_path / 'ma.csv'
    path.write_text(header + '\n' + (units + '\n' if units else '') + rows)
    rec = load_record(path)
    said = [n for n in rec.notes if '4-20 mA read as 0-100 % of span' in n]
    if header == 't,op,pv':
        # No unit given: nothing guessed, the numbers are read as they are.
        np.testing.assert_allclose(rec.signals['op'], ma)
        assert not said
    else:
        np.testing.assert_allclose(rec.signals['op'], (ma - 4) * 100 / 16)
        assert len(said) == 1

"""
Historian and spreadsheet exports as they come: time columns, tags, --columns, locales, Excel.

Each test writes a real file in ``tmp_path`` the way an export writes it and
reads it with :func:`load_record` (or the command line), then compares the
signals read with the values written, or checks that the one-line refusal
names the exact fix.  No ROS needed.
"""

import codecs
import dataclasses
from datetime import datetime, timedelta
import json
import pickle
import zipfile

import numpy as np
import pytest
from stiction_ros.analysis.readers import detect_format, load_record
from stiction_ros.app.analyze import AnalyzeOptions
from stiction_ros.cli.analyze import main
from stiction_ros.errors import InputError
from test_analysis_inputs import check_invariants, historian_text

N = 60
K = np.arange(N)


def decimals(x):
    """Return ``x`` as it reads back from 4 decimals, so that equality is exact."""
    return np.array([float(f'{v:.4f}') for v in x])


OP = decimals(50 + 8 * np.sin(K / 6))
PV = decimals(20 + 3 * np.cos(K / 6))
SP = np.full(N, 20.0)
MV = decimals(50 + 7 * np.sin(K / 6))
EXCEL_FIX = 'is an Excel workbook: save the sheet as CSV (File > Save As > CSV UTF-8) and pass ' \
    'that file'


def write(path, header, rows, sep=','):
    path.write_text(sep.join(header) + '\n' + ''.join(sep.join(r) + '\n' for r in rows),
                    encoding='utf-8')
    return path


def stamp(k, fmt='%Y-%m-%d %H:%M:%S'):
    return (datetime(2026, 3, 1, 12) + timedelta(seconds=int(k))).strftime(fmt)


def rows_of(times, *signals):
    return [[t] + [f'{s[k]:.4f}' for s in signals] for k, t in enumerate(times)]


def refusal(path, **kw):
    with pytest.raises(InputError) as err:
        load_record(path, **kw)
    msg = str(err.value)
    assert '\n' not in msg and str(path) in msg
    return msg


# ---- the time column ------------------------------------------------------------------

def test_the_new_users_file_time_sp_op_mv_pv_is_read(tmp_path):
    # The file: its header was refused with "no 't' column ... 'time'".
    path = write(tmp_path / 'loop.csv', ['time', 'sp', 'op', 'mv', 'pv'],
                 rows_of([f'{k:g}' for k in K], SP, OP, MV, PV))
    rec = load_record(path)
    assert rec.sample_time == 1.0 and rec.samples == N and rec.time_origin == 0.0
    for name, v in (('op', OP), ('mv', MV), ('pv', PV), ('sp', SP)):
        np.testing.assert_array_equal(rec.signals[name], v)
    assert rec.source['time'] == 'time (seconds)' and rec.source['sampling'] == "the rows' spacing"
    assert rec.valid.all() and not rec.notes
    check_invariants(rec)


@pytest.mark.parametrize('header, scale, ts', [
    ('Time (s)', 0.5, 0.5), ('time [ms]', 500.0, 0.5), ('t_min', 0.25, 15.0), ('T', 2.0, 2.0)])
def test_time_headers_with_units(tmp_path, header, scale, ts):
    path = write(tmp_path / 'u.csv', [header, 'op', 'pv'],
                 rows_of([f'{k * scale:g}' for k in K], OP, PV))
    rec = load_record(path)
    assert rec.sample_time == ts and rec.samples == N
    np.testing.assert_array_equal(rec.signals['op'], OP)


@pytest.mark.parametrize('fmt, start', [
    ('%Y-%m-%d %H:%M:%S', '2026-03-01T12:00:00'),
    ('%Y-%m-%dT%H:%M:%SZ', '2026-03-01T12:00:00+00:00'),
    ('%Y-%m-%dT%H:%M:%S+01:00', '2026-03-01T12:00:00+01:00'),
    ('%Y-%m-%d %H:%M:%S.000', '2026-03-01T12:00:00'),
    ('%d.%m.%Y %H:%M:%S', '2026-03-01T12:00:00'),
    ('%Y/%m/%d %H:%M:%S', '2026-03-01T12:00:00'),
])
def test_timestamp_columns_with_and_without_zone(tmp_path, fmt, start):
    path = write(tmp_path / 'ts.csv', ['Timestamp', 'OP', 'PV'],
                 rows_of([stamp(k, fmt) for k in K], OP, PV))
    rec = load_record(path)
    assert rec.start_time == start and rec.sample_time == 1.0 and rec.samples == N
    assert rec.source['time'] == 'Timestamp (datetime)'
    np.testing.assert_array_equal(rec.signals['op'], OP)
    np.testing.assert_array_equal(rec.signals['pv'], PV)


def test_a_change_of_offset_is_no_jump(tmp_path):
    # Clocks go forward at 02:00+01:00 = 03:00+02:00: the same instant, one second on.
    times = [f'2026-03-29T01:59:{s:02d}+01:00' for s in range(30, 60)]
    times += [f'2026-03-29T03:00:{s:02d}+02:00' for s in range(30)]
    path = write(tmp_path / 'dst.csv', ['timestamp', 'op', 'pv'], rows_of(times, OP, PV))
    rec = load_record(path)
    assert rec.samples == N and rec.valid.all()
    np.testing.assert_array_equal(rec.signals['op'], OP)


def test_local_time_going_back_an_hour_is_refused_with_the_fix(tmp_path):
    # A Wednesday, when no clocks change (a Sunday's is read: test_clock_changes.py).
    times = ['2026-10-21 02:59:58', '2026-10-21 02:59:59', '2026-10-21 02:00:00']
    path = write(tmp_path / 'back.csv', ['Timestamp', 'op'], [[t, '1'] for t in times])
    msg = refusal(path)
    assert "row 4: Timestamp = '2026-10-21 02:00:00' does not increase" in msg
    assert 'export the stamps in UTC or with their offset' in msg


def test_us_excel_dates_and_joined_date_and_time_columns(tmp_path):
    us = [f'3/1/2026 1:{k // 60:02d}:{k % 60:02d} PM' for k in K]
    rec = load_record(write(tmp_path / 'us.csv', ['Date/Time', 'op', 'pv'],
                            rows_of(us, OP, PV)))
    assert rec.start_time == '2026-03-01T13:00:00' and rec.samples == N
    np.testing.assert_array_equal(rec.signals['pv'], PV)
    rows = [['2026-03-01', f'23:59:{k:02d}', f'{OP[k]:.4f}', f'{PV[k]:.4f}'] for k in K]
    rec = load_record(write(tmp_path / 'dt.csv', ['Date', 'Time', 'op', 'pv'], rows, ';'))
    assert rec.start_time == '2026-03-01T23:59:00' and rec.samples == N
    assert "time: 'Date' and 'Time' joined into one stamp" in rec.notes
    ambiguous = [f'03/01/2026 12:00:{k:02d}' for k in K]
    msg = refusal(write(tmp_path / 'amb.csv', ['Timestamp', 'op'], rows_of(ambiguous, OP)))
    assert 'no day over 12 shows whether the day or the month comes first' in msg
    assert msg.endswith('write the column as 2026-03-01 12:00:00 (ISO 8601) or in seconds')


def test_unix_milliseconds_and_seconds_give_a_start_time(tmp_path):
    first = 1772366400                                        # 2026-03-01 12:00:00 UTC
    ms = write(tmp_path / 'ms.csv', ['timestamp', 'op'],
               rows_of([f'{(first + k) * 1000}' for k in K], OP))
    rec = load_record(ms)
    assert rec.start_time == '2026-03-01T12:00:00+00:00' and rec.sample_time == 1.0
    assert any('read as Unix time in milliseconds' in n for n in rec.notes)
    s = load_record(write(tmp_path / 's.csv', ['t', 'op'],
                          rows_of([f'{first + k}' for k in K], OP)))
    assert s.start_time == rec.start_time and s.time_origin == first


def test_a_zone_in_the_header_applies_to_stamps_without_one(tmp_path):
    path = write(tmp_path / 'utc.csv', ['Timestamp (UTC)', 'op'],
                 rows_of([stamp(k) for k in K], OP))
    assert load_record(path).start_time == '2026-03-01T12:00:00+00:00'


@pytest.mark.parametrize('header, rows, words', [
    (['time', 'timestamp', 'op'], [['0', '0', '1'], ['1', '1', '2']],
     ("2 time columns: 'time', 'timestamp'", '--columns t=time')),
    (['zeitpunkt', 'op'], [['0', '1'], ['1', '2']],
     ("no time column (t, time or timestamp: seconds or dates); columns: 'zeitpunkt', 'op'",
      '--columns t=COLUMN')),
    (['time (fortnights)', 'op'], [['0', '1'], ['1', '2']],
     ("unknown time unit 'fortnights'", "'time (s)'")),
    (['Timestamp', 'op'], [['2026-03-01 12:00:00Z', '1'], ['2026-03-01 12:00:01', '2']],
     ("row 2 has a time zone ('2026-03-01 12:00:00Z'), row 3 has none",
      'give every stamp its offset, or none')),
    (['2026-03-01 12:00:00', '1.5'], [['2026-03-01 12:00:01', '2']],
     ('no header row; line 1 holds data', 'a time (t, time or timestamp), op')),
    (['Tag', 'Timestamp', 'Value'], [['FIC1.OP', '2026-03-01 12:00:00', '1'],
                                     ['FIC1.PV', '2026-03-01 12:00:00', '2']],
     ('one row per tag and time (a long export', 'one column each '
      '(Timestamp,FIC101.OP,FIC101.PV)')),
])
def test_time_column_refusals_name_the_fix(tmp_path, header, rows, words):
    msg = refusal(write(tmp_path / 'bad.csv', header, rows))
    for w in words:
        assert w in msg, (w, msg)


# ---- irregular rows ---------------------------------------------------------------------

def test_jittered_rows_are_resampled_at_the_median_interval_by_interpolation(tmp_path):
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.6, 1.4, 300))
    t = np.round(t - t[0], 3)
    # Linear in t: interpolation reads it exactly at any instant, holding would not.
    op, pv = 10 + 0.05 * t, 30 - 0.02 * t
    path = write(tmp_path / 'jit.csv', ['t', 'op', 'pv'],
                 [[f'{a:.3f}', f'{b:.6f}', f'{c:.6f}'] for a, b, c in zip(t, op, pv)])
    rec = load_record(path)
    median = np.median(np.diff(t))
    assert rec.sample_time == float(f'{median:.2g}')
    assert rec.samples == int(t[-1] / rec.sample_time + 1e-9) + 1
    np.testing.assert_allclose(rec.signals['op'], 10 + 0.05 * rec.t, atol=1e-6)
    np.testing.assert_allclose(rec.signals['pv'], 30 - 0.02 * rec.t, atol=1e-6)
    note = next(n for n in rec.notes if n.startswith('rows not on one sample grid'))
    assert f'resampled at {rec.sample_time:g} s, the median interval between rows' in note
    assert 'linear interpolation between stored values' in note
    assert 'holding each value would draw steps' in note
    assert rec.source['sampling'].startswith(f'resampled at {rec.sample_time:g} s')
    check_invariants(rec)


def test_values_stored_on_change_are_interpolated_and_long_silences_stay_gaps(tmp_path):
    # A raw export on a 1 s scan: a row when a tag changed, the other tag's cell empty;
    # a silence of 700 s (over a historian's 600 s exception maximum) is a gap.
    stored = sorted({*range(0, 120, 3), *range(0, 120, 7), *range(820, 900, 4), 899})
    rows = []
    for s in stored:
        op = f'{40 + 0.1 * s:.1f}' if s % 3 == 0 or s > 800 else ''
        pv = f'{60 - 0.2 * s:.1f}' if s % 7 == 0 or s > 800 else ''
        rows.append([stamp(s), op, pv])
    rows[5][1] = 'No Data'                                # a bad value stored at t = 12 s
    rec = load_record(write(tmp_path / 'raw.csv', ['Timestamp', 'FIC7.OP', 'FIC7.PV'], rows))
    assert rec.sample_time == 1.0 and rec.samples == 900
    assert rec.start_time == '2026-03-01T12:00:00'
    good = np.r_[0:10, 15:118, 820:900]
    np.testing.assert_allclose(rec.signals['op'][good], 40 + 0.1 * good, atol=1e-9)
    # nothing is drawn to or from the bad value: 10 to 14 s are gaps, 9 and 15 stored
    assert np.isnan(rec.signals['op'][10:15]).all() and rec.signals['op'][15] == 41.5
    pv_good = np.r_[0:120, 820:900]
    np.testing.assert_allclose(rec.signals['pv'][pv_good], 60 - 0.2 * pv_good, atol=1e-9)
    assert np.isnan(rec.signals['pv'][120:820]).all()
    text = ' | '.join(rec.notes)
    assert 'resampled at 1 s, the scan every stamp falls on' in text
    assert "FIC7.OP: 1 cell marked bad ('No Data') read as missing values" in text
    assert ('op: 1 interval longer than 600 s without a stored value (the longest 703 s, '
            'from t = 117 s) left as gaps') in text
    assert 'stored values cover few samples' in text          # compressed: a warning
    check_invariants(rec)


def test_a_clean_grid_with_one_long_outage_stays_on_its_grid(tmp_path):
    # A logger on a 10 s scan lost 1 000 s in the middle: a third of the samples have
    # no row, which is an outage, not values stored on change.
    ks = np.r_[0:120, 220:300]
    rows = [[stamp(10 * k), f'{40 + 0.01 * k:.2f}', f'{60 - 0.02 * k:.2f}'] for k in ks]
    rec = load_record(write(tmp_path / 'outage.csv', ['Timestamp', 'OP', 'PV'], rows))
    assert rec.sample_time == 10.0 and rec.samples == 300
    assert rec.source['sampling'] == "the rows' spacing"
    assert not any(n.startswith('rows not on one sample grid') for n in rec.notes)
    assert '100 samples have no row (a gap in t); left as gaps' in rec.notes
    np.testing.assert_array_equal(np.isnan(rec.signals['op']), ~np.isin(np.arange(300), ks))
    np.testing.assert_allclose(rec.signals['op'][ks], 40 + 0.01 * ks, atol=1e-9)
    # A hole under a historian's exception maximum is still read as stored on change.
    short = np.r_[0:60, 62:64, 66:68, 70:72, 74:76, 78:80, 82:84, 86:88, 90:300:3]
    rows = [[stamp(10 * k), f'{40 + 0.01 * k:.2f}', f'{60 - 0.02 * k:.2f}'] for k in short]
    rec = load_record(write(tmp_path / 'sparse.csv', ['Timestamp', 'OP', 'PV'], rows))
    assert rec.source['sampling'].startswith('resampled at 10 s')
    check_invariants(rec)


# ---- tags and --columns --------------------------------------------------------------

def test_tag_prefixed_columns_are_matched_by_suffix(tmp_path):
    path = write(tmp_path / 'tags.csv', ['Timestamp', 'FIC101.OP', 'FIC101_PV', 'FIC101 SV',
                                         'FIC101.MV (%)', 'Status'],
                 [r + ['Good'] for r in rows_of([stamp(k) for k in K], OP, PV, SP, MV)])
    rec = load_record(path)
    assert rec.source['columns'] == {'op': 'FIC101.OP', 'mv': 'FIC101.MV (%)',
                                     'pv': 'FIC101_PV', 'sp': 'FIC101 SV'}
    for name, v in (('op', OP), ('mv', MV), ('pv', PV), ('sp', SP)):
        np.testing.assert_array_equal(rec.signals[name], v)
    assert 'ignored columns: Status' in rec.notes


def test_a_lone_tag_mv_is_the_controller_output_as_historians_name_it(tmp_path):
    path = write(tmp_path / 'mv.csv', ['Timestamp', 'LIC20.MV', 'LIC20.PV'],
                 rows_of([stamp(k) for k in K], OP, PV))
    rec = load_record(path)
    np.testing.assert_array_equal(rec.signals['op'], OP)
    assert not rec.has('mv')
    assert any("'LIC20.MV' read as the controller output (op)" in n
               and '--columns mv=LIC20.MV,op=COLUMN' in n for n in rec.notes)


def test_ambiguous_tags_are_refused_with_the_columns_fix(tmp_path):
    path = write(tmp_path / 'two.csv', ['Timestamp', 'FIC101.OP', 'FIC101.PV', 'FIC102.OP',
                                        'FIC102.PV'],
                 rows_of([stamp(k) for k in K], OP, PV, OP, PV))
    msg = refusal(path)
    assert msg.endswith("2 columns could be op: 'FIC101.OP', 'FIC102.OP'; choose with "
                        '--columns op=FIC101.OP,pv=FIC101.PV')
    # Following the fix reads the loop it names.
    rec = load_record(path, columns={'op': 'FIC102.OP', 'pv': 'FIC102.PV'})
    assert rec.source['columns'] == {'op': 'FIC102.OP', 'pv': 'FIC102.PV'}
    np.testing.assert_array_equal(rec.signals['pv'], PV)


def test_a_signal_two_tags_could_be_is_the_one_of_ops_tag(tmp_path):
    path = write(tmp_path / 'near.csv', ['Timestamp', 'TI200.PV', 'FIC101.OP', 'FIC101.PV'],
                 rows_of([stamp(k) for k in K], SP, OP, PV))
    rec = load_record(path)
    assert rec.source['columns'] == {'op': 'FIC101.OP', 'pv': 'FIC101.PV'}
    np.testing.assert_array_equal(rec.signals['pv'], PV)
    assert "pv: took 'FIC101.PV', of the same tag as op; ignored 'TI200.PV'" in rec.notes


def test_columns_option_maps_any_names_through_analyze_options(tmp_path):
    path = write(tmp_path / 'odd.csv', ['Zeit', 'Stellgroesse', 'Istwert', 'Sollwert'],
                 rows_of([f'{k * 10}' for k in K], OP, PV, SP))
    opts = AnalyzeOptions(path, columns='pv=Istwert, op=Stellgroesse,t=Zeit,sp=SOLLWERT')
    assert opts.columns == (('t', 'Zeit'), ('op', 'Stellgroesse'), ('pv', 'Istwert'),
                            ('sp', 'SOLLWERT'))
    assert pickle.loads(pickle.dumps(opts)) == opts
    assert dataclasses.replace(opts, jobs=1).columns == opts.columns
    assert AnalyzeOptions(path, columns=dict(opts.columns)).columns == opts.columns
    rec = load_record(path, columns=dict(opts.columns))
    assert rec.sample_time == 10.0
    for name, v in (('op', OP), ('pv', PV), ('sp', SP)):
        np.testing.assert_array_equal(rec.signals[name], v)
    msg = refusal(path, columns={'op': 'Stellgröße'})
    assert "--columns op=Stellgröße: no such column; columns: 'Zeit', 'Stellgroesse'" in msg


@pytest.mark.parametrize('value, words', [
    ('op=A,valve=B', ("'valve' is no signal", 't, op, mv, pv, sp')),
    ('op=A,op=B', ('op is given twice',)),
    ('op=A,pv=a', ("column 'a' is given for op and pv",)),
    ('op', ("'op' is not SIGNAL=COLUMN", '--columns op=FIC101.OP,pv=FIC101.PV')),
    ('op=', ('the column name is empty',)),
    (',', ('--columns is empty',)),
    (3, ('--columns must be SIGNAL=COLUMN pairs',)),
])
def test_bad_columns_option_fails_when_made(value, words):
    with pytest.raises(InputError) as err:
        AnalyzeOptions('loop.csv', columns=value)
    for w in words:
        assert w in str(err.value), (w, str(err.value))


def test_columns_on_the_command_line(tmp_path, capsys):
    path = write(tmp_path / 'odd.csv', ['Zeitpunkt', 'Stellgroesse', 'Istwert'],
                 rows_of([f'{k}' for k in range(200)],
                         50 + 8 * np.sign(np.sin(np.arange(200) / 8)),
                         20 + np.cos(np.arange(200) / 8)))
    assert main([str(path), '--columns', 'op=Stellgroesse,pv=Istwert,t=Zeitpunkt', '--json',
                 str(tmp_path / 'r.json'), '--no-hammerstein', '--quiet']) == 0
    report = json.loads((tmp_path / 'r.json').read_text())
    assert report['samples'] == 200 and report['signals'] == ['op', 'pv']
    assert report['input']['columns']['op'] == 'Stellgroesse'
    capsys.readouterr()
    assert main([str(path), '--columns', 'op=Stellgroesse', '--quiet']) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith('stiction-analyze: error: ') and len(err.splitlines()) == 1
    assert 'no time column' in err and '--columns t=COLUMN' in err
    assert main([str(path), '--columns', 'op:Stellgroesse', '--quiet']) == 2
    assert "'op:Stellgroesse' is not SIGNAL=COLUMN" in capsys.readouterr().err


def test_columns_in_a_historian_export(tmp_path):
    tag = '2411FIC20102'
    cols = [f'{tag}.OUT', f'{tag}.MEAS', f'{tag}.SV', f'{tag}.MODE']
    path = tmp_path / 'h.txt'
    path.write_text(historian_text(columns=cols), encoding='utf-8')
    msg = refusal(path)
    assert msg.endswith('name it with --columns op=TAG')
    rec = load_record(path, columns={'op': f'{tag}.OUT', 'pv': f'{tag}.MEAS'})
    assert rec.source['columns'] == {'op': f'{tag}.OUT', 'pv': f'{tag}.MEAS', 'sp': f'{tag}.SV',
                                     'mode': f'{tag}.MODE'}
    k = np.arange(60)
    np.testing.assert_allclose(rec.signals['op'], 25 + np.sin(k / 5), atol=1e-6)
    np.testing.assert_allclose(rec.signals['pv'], 100 + k * 0.01, atol=1e-9)


# ---- locales and encodings ------------------------------------------------------------

def test_semicolons_and_decimal_commas_as_european_excel_writes(tmp_path):
    rows = [[stamp(k, '%d.%m.%Y %H:%M:%S'), f'{OP[k]:.4f}'.replace('.', ','),
             f'{PV[k] * 100:,.2f}'.replace(',', ' ').replace('.', ',').replace(' ', '.')]
            for k in K]
    assert any('.' in r[2] and ',' in r[2] for r in rows)      # 2.012,34: grouped thousands
    rec = load_record(write(tmp_path / 'eu.csv', ['Zeit', 'FIC101.OP', 'FIC101.PV'], rows, ';'))
    np.testing.assert_array_equal(rec.signals['op'], OP)
    np.testing.assert_allclose(rec.signals['pv'], np.round(PV * 100, 2), rtol=0, atol=1e-9)
    assert rec.start_time == '2026-03-01T12:00:00'
    assert any(n.startswith('decimal commas: 120 cells such as') for n in rec.notes)


def test_decimal_commas_between_comma_separators_get_the_exact_hint(tmp_path):
    quoted = write(tmp_path / 'q.csv', ['t', 'op'], [['0', '"1,25"'], ['1', '"1,5"']])
    assert refusal(quoted).endswith("row 2, column 'op': '1,25' is not a number: with ',' "
                                    "between cells, write decimals with '.' (or save the "
                                    "file with ';' between cells)")
    bare = write(tmp_path / 'b.csv', ['t', 'op'], [['0', '1,25'], ['1', '1,5']])
    assert refusal(bare).endswith('row 2 has 3 cells; the header has 2: if its numbers have '
                                  "decimal commas (1,25), save the file with ';' between cells")


def test_utf16_unicode_text_with_tabs_and_trailing_separators(tmp_path):
    text = 'Time\tFIC101.OP\tFIC101.PV\t\n' + ''.join(
        f'{k}\t{OP[k]}\t{PV[k]}\t\n' for k in K)
    path = tmp_path / 'unicode.txt'
    path.write_bytes(codecs.BOM_UTF16_LE + text.encode('utf-16-le'))
    rec = load_record(path)
    np.testing.assert_array_equal(rec.signals['op'], OP)
    np.testing.assert_array_equal(rec.signals['pv'], PV)


# ---- spreadsheets, by their bytes -------------------------------------------------------

def test_an_xlsx_is_refused_with_the_fix_whatever_its_name(tmp_path):
    for name in ('book.xlsx', 'export.csv'):
        path = tmp_path / name
        with zipfile.ZipFile(path, 'w') as z:
            z.writestr('[Content_Types].xml', '<Types/>')
            z.writestr('xl/workbook.xml', '<workbook/>')
            z.writestr('xl/worksheets/sheet1.xml', '<worksheet/>')
        assert path.read_bytes()[:2] == b'PK'
        with pytest.raises(InputError) as err:
            detect_format(path)
        assert str(err.value) == f'{path} {EXCEL_FIX}'


def test_xls_ods_and_other_archives_are_refused_with_the_fix(tmp_path):
    xls = tmp_path / 'old.xls'
    xls.write_bytes(b'\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1' + bytes(504)
                    + 'Workbook'.encode('utf-16-le') + bytes(100))
    assert refusal(xls) == f'{xls} {EXCEL_FIX}'
    ods = tmp_path / 'sheet.ods'
    with zipfile.ZipFile(ods, 'w') as z:
        z.writestr('mimetype', 'application/vnd.oasis.opendocument.spreadsheet')
        z.writestr('content.xml', '<office/>')
    assert refusal(ods) == (f'{ods} is an OpenDocument spreadsheet: save the sheet as CSV '
                            '(File > Save As > Text CSV) and pass that file')
    other = tmp_path / 'loop.zip'
    with zipfile.ZipFile(other, 'w') as z:
        z.writestr('loop.csv', 't,op\n0,1\n')
    assert refusal(other).endswith('a zip archive, not a recording: extract it and pass the '
                                   'CSV or bag inside')

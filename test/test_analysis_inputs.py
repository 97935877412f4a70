"""
The analyzer's input layer: CSV, bag and historian files onto one sample grid.

Round trips through the project's own writers, the real plant-loop exports,
synthetic files with manual stretches, flags and gaps, and one clear
one-line error for each kind of bad input.  No ROS needed.
"""

import json
from pathlib import Path
import struct

from data_paths import plant_loops_dir
import numpy as np
import pytest
from stiction_ros.analysis.readers import detect_format, load_record
from stiction_ros.analysis.record import InputError
from stiction_ros.bag.metadata import qos_profile
from stiction_ros.bag.reader import read_bag
from stiction_ros.bag.writer import BagWriter
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop, write_csv
from stiction_ros.sim.loop_config import load_loop

PLANT = plant_loops_dir() or Path('/nonexistent')
PLANT_FILES = sorted(PLANT.glob('*/*.txt'))
PHASES = {'pv': 0.25, 'op': 0.5, 'sp': 0.5, 'mv': 0.75}   # the live loop's publishers
FLAGS = ('bOpOFL', 'bPvOFL', 'bSpOFL', 'bAutOFL')


@pytest.fixture(scope='module')
def loop():
    cfg = load_loop(config_file('concentration_loop.yaml'), 'undershoot')
    return simulate_loop(cfg, duration=300.0)


def f64(x):
    return b'\x00\x01\x00\x00' + struct.pack('<d', x)


def write_bag(path, data, ns='/loop1', ts=1.0, offset=0.0, drop=(), jitter=0.0, **kw):
    """Write ``data`` as the live loop publishes it; ``drop``: (signal, sample) pairs."""
    rng = np.random.default_rng(1)
    w = BagWriter(path, **kw)
    for name in PHASES:
        w.add_topic(f'{ns}/{name}', 'std_msgs/msg/Float64', [qos_profile(depth=100)])
    for k in range(len(data['op'])):
        for name in ('pv', 'op', 'sp', 'mv'):
            if (name, k) in drop:
                continue
            stamp = offset + (k + PHASES[name]) * ts + jitter * rng.uniform(-1, 1)
            w.write(f'{ns}/{name}', f64(data[name][k]), int(round(stamp * 1e9)))
    w.close()
    return path


def historian_text(n=60, mode=None, flags=None, period=10, columns=None):
    """Return a historian export like the plant's: CRLF, tabs, 5 header lines."""
    tag = '2411FIC20102'
    cols = columns or [f'{tag}.MV', f'{tag}.PV', f'{tag}.SV', f'{tag}.MODE', *FLAGS]
    lines = [f'PROCESSDATA\t{tag} Data\tyyyy-MM-dd HH:mm:ss',
             f'{len(cols)}\t{period}\t2024-06-09 07:50:00\t{n}',
             'tagname\t' + '\t'.join(cols),
             'desc\t反应器进料_OP\t反应器进料_PV\t反应器进料_SP\tAut\t' + '\t'.join(FLAGS),
             'fsMax=1.3\tfsMin=0\tfsGridNum=10\tL=24']
    for i in range(n):
        m, s = divmod(i * period, 60)
        h, m = divmod(50 + m, 60)
        f = (flags or {}).get(i, (0, 0, 0, 0))
        row = [f'2024-06-09 {7 + h:02d}:{m:02d}:{s:02d}', f'{25 + np.sin(i / 5):.6f}',
               f'{100 + i * 0.01:.4f}', '100', str((mode or {}).get(i, 1)), *map(str, f)]
        lines.append('\t'.join(row[:len(cols) + 1]))
    return '\r\n'.join(lines) + '\r\n'


def write_text(path, text):
    path.write_bytes(text.encode('utf-8'))
    return path


def check_invariants(rec):
    """Check that ``valid`` means no exclusion and every signal finite; segments are its runs."""
    finite = np.all([np.isfinite(v) for v in rec.signals.values()], axis=0)
    assert not np.any(rec.valid & ~finite)
    assert sum(b - a for a, b in rec.segments()) == np.count_nonzero(rec.valid)
    assert sum(e['samples'] for e in rec.excluded) == rec.samples - np.count_nonzero(rec.valid)
    assert np.allclose(rec.t, np.arange(rec.samples) * rec.sample_time)


# ---- CSV -----------------------------------------------------------------

def test_csv_round_trip_of_the_simulator(loop, tmp_path):
    write_csv(tmp_path / 'sim.csv', loop)
    rec = load_record(tmp_path / 'sim.csv')
    assert rec.source['format'] == 'csv' and rec.name == 'sim'
    assert rec.sample_time == 1.0 and rec.samples == len(loop['t']) and rec.time_origin == 0.0
    for name in ('op', 'mv', 'pv', 'sp'):
        np.testing.assert_allclose(rec.signals[name], loop[name], rtol=1e-9, atol=1e-8)
    assert rec.valid.all() and rec.segments() == [(0, rec.samples)] and not rec.notes
    check_invariants(rec)


def test_csv_names_case_spaces_extra_columns_missing_cells_and_gaps(tmp_path):
    rows = [' T , OP ,Pv, note ']
    for k in range(40):
        if k in (20, 21):
            continue                                   # two samples with no row: a gap
        pv = 'nan' if k == 5 else '' if k == 6 else f'{k * 0.5}'
        rows.append(f'{100 + 0.1 * k:.1f},{k},{pv},x')
    rec = load_record(write_text(tmp_path / 'm.csv', '\n'.join(rows) + '\n'))
    assert sorted(rec.signals) == ['op', 'pv'] and rec.has('pv') and not rec.has('sp')
    assert rec.sample_time == 0.1 and rec.samples == 40 and rec.time_origin == 100.0
    assert np.isnan(rec.signals['op'][20]) and rec.signals['op'][22] == 22
    assert rec.segments() == [(0, 5), (7, 20), (22, 40)]
    text = ' | '.join(rec.notes)
    assert 'ignored columns: note' in text and '2 empty or non-finite cells' in text
    assert '2 samples have no row' in text
    assert {e['reason'] for e in rec.excluded} == {'no pv value', 'no op, pv value'}
    check_invariants(rec)


@pytest.mark.parametrize('text, match', [
    ('', 'empty file'),
    (' \n' * 100, 'empty file'),
    # Blank lines before the header are no empty file: the CSV is read.
    ('\n' * 100 + 't,op\n0,1\n', 'only 1 data row'),
    ('clock,op\n0,1\n1,2\n', r"no time column .*columns: 'clock', 'op'; name it with "
     '--columns t=COLUMN'),
    ('t,pv,sp\n0,1,2\n1,2,3\n', r"no 'op' column .*columns: 't', 'pv', 'sp'"),
    ('0,1\n1,2\n', 'no header row'),
    ('t,op\n0,1\n1,2\n2,abc\n', r"row 4, column 'op': 'abc' is not a number"),
    ('t,op\n0,1\n1,2\n0.5,3\n', r'row 4: t = 0.5 does not increase \(row 3: t = 1\)'),
    ('t,op\n0,1\n1,2\n1,3\n', r'row 4: t = 1 does not increase'),
    ('t,op\n0,1\n1,2,3\n', 'row 3 has 3 cells; the header has 2'),
    ('t,op\n0,1\n,2\n', 'row 3: t is'),
    ('t,op\n0,1\n', 'only 1 data row'),
    ('t,op,OP\n0,1,1\n', "column 'op' appears 2 times"),
    ('t,op\n' + ''.join(f'{k},1\n' for k in range(8)), r'only 8 of 8 samples are valid'),
    ('t,op\n' + ''.join(f'{k},{"nan" if k > 3 else 1}\n' for k in range(30)),
     r'only 4 of 30 samples are valid .*26 no op value'),
])
def test_bad_csv_gives_one_line_input_error(tmp_path, text, match):
    path = write_text(tmp_path / 'bad.csv', text)
    with pytest.raises(InputError, match=match) as err:
        load_record(path)
    assert str(err.value).startswith(str(path)) and '\n' not in str(err.value)


def test_missing_file_and_unreadable_inputs(tmp_path):
    with pytest.raises(InputError, match='no such file or directory'):
        load_record(tmp_path / 'nope.csv')
    (tmp_path / 'dir').mkdir()
    with pytest.raises(InputError, match='directory without a bag'):
        load_record(tmp_path / 'dir')
    (tmp_path / 'bin.csv').write_bytes(b't,op\n\x00\x01\x02')
    with pytest.raises(InputError, match='not a text file'):
        load_record(tmp_path / 'bin.csv')
    (tmp_path / 'junk.mcap').write_bytes(b'not an mcap file')
    with pytest.raises(InputError, match='not a readable MCAP'):
        load_record(tmp_path / 'junk.mcap')


# ---- bags ----------------------------------------------------------------

def test_bag_round_trip_at_the_live_loop_phases(loop, tmp_path):
    bag = write_bag(tmp_path / 'live', loop)
    rec = load_record(bag)
    assert detect_format(bag) == 'bag' and rec.name == '/loop1'
    assert rec.sample_time == 1.0 and rec.samples == len(loop['t']) and rec.time_origin == 0.0
    for name in PHASES:
        assert np.array_equal(rec.signals[name], loop[name]), name   # sample-exact
    assert rec.source['phases'] == {'op': 0.0, 'mv': 0.25, 'pv': -0.25, 'sp': 0.0}
    assert rec.valid.all() and not rec.notes and rec.start_time is None
    same = load_record(bag / 'live_0.mcap', namespace='loop1')      # the bare .mcap file
    assert np.array_equal(same.signals['pv'], rec.signals['pv'])
    mapped = load_record(bag, columns={'op': 'FIC101.OP'})          # a bag has its topics
    assert mapped.notes[0].startswith('--columns ignored: a bag holds the topics op, mv')
    assert np.array_equal(mapped.signals['op'], rec.signals['op'])


def test_bag_gaps_are_invalid_samples_with_notes(loop, tmp_path):
    drop = {('op', 100), ('pv', 150), ('pv', 151), ('pv', 152)}
    rec = load_record(write_bag(tmp_path / 'gap', loop, drop=drop))
    assert rec.samples == len(loop['t'])
    assert np.isnan(rec.signals['op'][100]) and rec.signals['pv'][100] == loop['pv'][100]
    assert np.flatnonzero(~rec.valid).tolist() == [100, 150, 151, 152]
    assert rec.segments(min_samples=10) == [(0, 100), (101, 150), (153, rec.samples)]
    assert [(e['start_s'], e['samples'], e['reason']) for e in rec.excluded] == [
        (100.0, 1, 'no op value'), (150.0, 3, 'no pv value')]
    assert 'excluded 3 samples (3 s) at t = 150 to 152 s: no pv value' in rec.notes
    check_invariants(rec)


def test_bag_on_wall_clock_with_offset_and_jitter_bins_on_op(loop, tmp_path):
    start = 1.7e9 + 0.37                         # arbitrary phase, wall-clock stamps
    bag = write_bag(tmp_path / 'wall', loop, ns='', ts=0.5, offset=start, jitter=0.1)
    rec = load_record(bag)
    assert rec.name == 'wall' and rec.sample_time == 0.5
    assert rec.start_time.startswith('2023-11-14T22:13:20.3')
    for name in PHASES:
        assert np.array_equal(rec.signals[name], loop[name]), name


def test_truncated_bag_keeps_its_prefix_with_a_note(loop, tmp_path):
    bag = write_bag(tmp_path / 'cut', loop, chunk_size=1024)
    mcap = bag / 'cut_0.mcap'
    data = mcap.read_bytes()
    mcap.write_bytes(data[:len(data) // 2])
    rec = load_record(bag)
    n = np.count_nonzero(np.isfinite(rec.signals['op']))
    assert 10 < n < len(loop['t']) and rec.samples == n
    read = sum(t.count for t in read_bag(bag).topics.values())
    assert 4 * n <= read < 4 * n + 4 and rec.notes[0] == f'bag truncated: read {read} messages'
    assert 'ends early' in rec.notes[1]
    for name in PHASES:
        assert np.array_equal(rec.signals[name], loop[name][:n])


def test_bag_errors_name_the_topics_and_namespaces(loop, tmp_path):
    two = tmp_path / 'two'
    w = BagWriter(two)
    for topic in ('/a/op', '/b/op', '/a/pv'):
        w.add_topic(topic, 'std_msgs/msg/Float64', [qos_profile()])
        for k in range(20):
            w.write(topic, f64(k), k * 10**9)
    w.close()
    with pytest.raises(InputError, match=r"2 namespaces hold an 'op' topic \('/a', '/b'\)"):
        load_record(two)
    assert load_record(two, namespace='/b').has('op')
    with pytest.raises(InputError, match='no topic /c/op; op topics: /a/op, /b/op'):
        load_record(two, namespace='c')
    none = tmp_path / 'none'
    w = BagWriter(none)
    w.add_topic('/temperature', 'std_msgs/msg/Float64', [qos_profile()])
    w.write('/temperature', f64(1.0), 0)
    w.close()
    with pytest.raises(InputError, match=r"no 'op' topic .*topics: /temperature$"):
        load_record(none)


# ---- historian exports ---------------------------------------------------

@pytest.mark.parametrize('path', PLANT_FILES, ids=lambda p: p.name[5:30])
def test_every_plant_loop_file_loads(path):
    rec = load_record(path)
    announced = int(path.read_text(encoding='utf-8').splitlines()[1].split('\t')[3])
    assert rec.samples == announced and announced in (751, 126)
    assert rec.sample_time == (60.0 if announced == 126 else 10.0)
    assert path.name.startswith('stic_' + rec.name.replace('#', '_') + '_')
    assert sorted(rec.signals) == ['op', 'pv', 'sp'] and rec.source['format'] == 'historian'
    assert rec.source['columns']['op'].endswith('.MV')
    assert np.count_nonzero(rec.valid) >= 0.9 * rec.samples
    check_invariants(rec)


@pytest.mark.skipif(not PLANT_FILES, reason='plant data not present')
def test_plant_quirks_flags_and_shifted_stamps_are_reported():
    flagged = load_record(next(PLANT.glob('*/stic_2111PIC23001_*.txt')))
    assert not flagged.valid[0] and not flagged.valid[30] and flagged.valid[1]
    assert flagged.excluded[0]['reason'] == 'flagged bad: bOpOFL bPvOFL bSpOFL bAutOFL'
    assert np.isnan(flagged.signals['op'][0])
    shifted = load_record(next(PLANT.glob('*/stic_RHT.7050-342_FIC10112_0630_*.txt')))
    assert shifted.valid.all() and shifted.samples == 751
    assert any('repeat 25 times and skip a sample 25 times' in n for n in shifted.notes)
    assert 'pv is constant (3.503246e-44) over the whole record' in shifted.notes


def test_historian_manual_mode_and_flags_are_excluded(tmp_path):
    mode = dict.fromkeys(range(20, 32), 0)
    flags = {50: (0, 1, 0, 0), 51: (0, 0, 0, 1)}
    path = write_text(tmp_path / 'loop.csv', historian_text(mode=mode, flags=flags))
    assert detect_format(path) == 'historian'                 # by content, not extension
    rec = load_record(path)
    assert rec.name == '2411FIC20102' and rec.start_time == '2024-06-09T07:50:00'
    assert rec.source['descriptions']['op'] == '反应器进料_OP'
    assert [(e['start_s'], e['end_s'], e['samples'], e['reason']) for e in rec.excluded] == [
        (200.0, 310.0, 12, 'MODE = 0, not 1 (manual)'),
        (500.0, 500.0, 1, 'flagged bad: bPvOFL'), (510.0, 510.0, 1, 'flagged bad: bAutOFL')]
    assert ('excluded 12 samples (120 s) at t = 200 to 310 s (2024-06-09 07:53:20): '
            'MODE = 0, not 1 (manual)') in rec.notes
    assert np.isfinite(rec.signals['op'][20:32]).all()           # manual values are kept
    assert np.isnan(rec.signals['pv'][50]) and np.isfinite(rec.signals['op'][50])
    assert np.isfinite(rec.signals['pv'][51])                    # a MODE flag: values kept
    assert rec.segments() == [(0, 20), (32, 50), (52, 60)]
    check_invariants(rec)
    win = load_record(path, window=(250, 450))
    assert win.samples == 21 and win.start_time == '2024-06-09T07:54:10'
    assert win.excluded == [{'start_s': 0.0, 'end_s': 60.0, 'samples': 7,
                             'reason': 'MODE = 0, not 1 (manual)'}]
    assert win.notes[0] == 'window 250 to 450 s: samples 25 to 45 of 60'
    summary = json.loads(json.dumps(win.to_json_summary()))
    assert summary['valid_samples'] == 14 and summary['signals'] == ['op', 'pv', 'sp']
    with pytest.raises(InputError, match='window 900 to 1000 s holds no sample'):
        rec.window(900, 1000)


def test_historian_with_gaps_in_its_stamps_is_placed_by_stamp(tmp_path):
    lines = historian_text(n=40).splitlines()
    del lines[5 + 10:5 + 13]                                 # rows 10, 11, 12 lost
    rec = load_record(write_text(tmp_path / 'g.txt', '\r\n'.join(lines)))
    assert rec.samples == 40 and np.flatnonzero(~rec.valid).tolist() == [10, 11, 12]
    assert 'line 2 announces 40 rows; the file has 37' in rec.notes


@pytest.mark.parametrize('edit, match', [
    (lambda ls: ls[:7] + [ls[7].rsplit('\t', 1)[0]] + ls[8:],
     r'line 8 has 8 columns; line 3 names 9'),
    (lambda ls: ls[:9] + [ls[9].replace('\t100\t', '\t1O0\t', 1)] + ls[10:],
     r"line 10, column 4 \(2411FIC20102.SV\): '1O0' is not a number"),
    (lambda ls: ls[:6] + [ls[6].replace('2024-06-09', '09/06/2024')] + ls[7:],
     r"line 7: time stamp '09/06/2024 07:50:10' does not match yyyy-MM-dd HH:mm:ss"),
    (lambda ls: ls[:6] + [ls[7], ls[6]] + ls[8:], r'line 8: time stamp .* is before'),
    (lambda ls: [ls[0], '8\tten\t2024-06-09 07:50:00\t60'] + ls[2:], 'line 2 must be'),
    (lambda ls: [ls[0], ls[1], ls[2].replace('.MV', '.XX')] + ls[3:],
     r'no controller output column \(2411FIC20102.MV\)'),
    (lambda ls: ls[:5], 'no data rows'),
    # Past 64 blank bytes it is still found to be a historian export, and told so.
    (lambda ls: [''] * 40 + ls, r'40 blank line\(s\) before PROCESSDATA; .*delete the blank'),
])
def test_bad_historian_gives_one_line_input_error(tmp_path, edit, match):
    lines = edit(historian_text().splitlines())
    path = write_text(tmp_path / 'h.txt', '\r\n'.join(lines) + '\r\n')
    with pytest.raises(InputError, match=match) as err:
        load_record(path)
    assert str(err.value).startswith(str(path)) and '\n' not in str(err.value)


def test_a_historians_word_for_a_missing_value_is_one_in_its_own_export_too(tmp_path):
    lines = historian_text().splitlines()
    lines[9] = lines[9].replace('\t100\t', '\tI/O Timeout\t', 1)
    lines[12] = lines[12].replace('\t100\t', '\tBad\t', 1)
    rec = load_record(write_text(tmp_path / 'w.txt', '\r\n'.join(lines) + '\r\n'))
    # Rows 10 and 13 of the file are samples 4 and 7; only their SP is missing.
    assert np.isnan(rec.signals['sp'][[4, 7]]).all() and np.isfinite(rec.signals['pv']).all()
    assert ("2411FIC20102.SV: 2 cells marked bad ('I/O Timeout', 'Bad') read as missing "
            'values') in rec.notes


def test_all_manual_historian_is_too_few_valid_samples(tmp_path):
    path = write_text(tmp_path / 'm.txt', historian_text(mode=dict.fromkeys(range(60), 0)))
    with pytest.raises(InputError, match=r'only 0 of 60 .*60 MODE = 0, not 1 \(manual\)'):
        load_record(path)


def test_a_folder_run_keeps_the_warning_of_a_bag_read_in_part(loop, tmp_path):
    # An audit of many recordings must not drop what one file's reader said:
    # a bag cut short is analysed from its complete part, and the row says so.
    from stiction_ros.app.analyze import AnalyzeOptions
    from stiction_ros.app.batch import analyze_one
    from stiction_ros.app.report_text import batch_row_text
    bag = write_bag(tmp_path / 'cut', loop, chunk_size=1024)
    mcap = bag / 'cut_0.mcap'
    data = mcap.read_bytes()
    mcap.write_bytes(data[:len(data) // 2])
    row = analyze_one(bag, AnalyzeOptions(input=str(bag)))
    assert row['ok'] and any('ends early' in w for w in row['warnings'])
    assert '\n  warning: cut_0.mcap: file ends early' in batch_row_text(row)
    whole = write_bag(tmp_path / 'whole', loop)
    assert analyze_one(whole, AnalyzeOptions(input=str(whole)))['warnings'] == []

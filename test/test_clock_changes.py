"""
Local stamps without an offset across a change of summer time (``readers/daylight.py``).

The reference is the time zone database: real instants a step apart are
written as each zone's local clock reads them, without the offset, and the
reader must give back the true seconds between them.  Jumps that only look
like a change of clocks (a weekday, the afternoon, a Sunday in July) keep their
old reading:
a gap forward, a refusal back.
"""

from datetime import datetime, timedelta, timezone

import numpy as np
import pytest
from stiction_ros.analysis.readers import load_record
from stiction_ros.analysis.readers.daylight import clock_changes
from stiction_ros.errors import InputError
from test_analysis_inputs import historian_text, write_text

try:
    from zoneinfo import ZoneInfo
    ZoneInfo('Europe/Berlin')
except Exception:  # pragma: no cover - a machine without the zone database
    ZoneInfo = None
needs_zones = pytest.mark.skipif(ZoneInfo is None, reason='no time zone database here')

# Each zone's changes of 2026 (UTC instants a little before them): forward and back.
ZONES = {
    'Europe/Berlin': ('2026-03-29 00:50', '2026-10-25 00:50'),
    'Europe/London': ('2026-03-29 00:50', '2026-10-25 00:50'),
    'Europe/Helsinki': ('2026-03-29 00:50', '2026-10-25 00:50'),
    'America/New_York': ('2026-03-08 06:50', '2026-11-01 05:50'),
    'Australia/Sydney': ('2026-10-03 15:50', '2026-04-04 15:50'),
    'Pacific/Auckland': ('2026-09-26 13:50', '2026-04-04 13:50'),
    'America/Santiago': ('2026-09-06 03:50', '2026-04-05 02:50'),
    'Asia/Jerusalem': ('2026-03-26 23:50', '2026-10-24 22:50'),
}


def local_stamps(zone, utc_start, step, n):
    """Return ``n`` stamps ``step`` s apart from ``utc_start``, as the zone's clock reads them."""
    t0 = datetime.fromisoformat(utc_start).replace(tzinfo=timezone.utc)
    return [(t0 + timedelta(seconds=step * k)).astimezone(ZoneInfo(zone)).replace(tzinfo=None)
            for k in range(n)]


def csv_of(stamps, fmt='%Y-%m-%d %H:%M:%S'):
    n = len(stamps)
    op = 50 + 8 * np.sin(np.arange(n) / 6)
    rows = [f'{s.strftime(fmt)},{op[k]:.4f},{op[k] / 2:.4f}\n' for k, s in enumerate(stamps)]
    return 'Timestamp,op,pv\n' + ''.join(rows), np.round(op, 4)


@needs_zones
@pytest.mark.parametrize('zone', sorted(ZONES))
@pytest.mark.parametrize('which', [0, 1], ids=['forward', 'back'])
@pytest.mark.parametrize('step', [1.0, 10.0, 60.0])
def test_each_zones_change_of_clocks_gives_back_the_true_seconds(zone, which, step):
    stamps = local_stamps(zone, ZONES[zone][which], step, int(2 * 3600 / step))
    t = np.array([(s - stamps[0]).total_seconds() for s in stamps])
    assert np.any(np.abs(np.diff(t) - step) > 3000)  # the clock did change in the record
    out, notes = clock_changes(t, stamps[0])
    np.testing.assert_allclose(out, step * np.arange(len(t)))
    assert len(notes) == 1 and ('forward' if which == 0 else 'back') in notes[0]


@needs_zones
@pytest.mark.parametrize('which', [0, 1], ids=['forward', 'back'])
def test_a_csv_across_the_change_reads_every_row_as_one_stretch(tmp_path, which):
    stamps = local_stamps('Europe/Berlin', ZONES['Europe/Berlin'][which], 10.0, 720)
    text, op = csv_of(stamps)
    rec = load_record(write_text(tmp_path / 'local.csv', text))
    assert rec.samples == 720 and rec.valid.all() and rec.sample_time == 10.0
    np.testing.assert_array_equal(rec.signals['op'], op)
    assert any('clocks went' in n and 'none missing' in n for n in rec.notes)


def shifted(stamps, k, hours):
    return stamps[:k] + [s + timedelta(hours=hours) for s in stamps[k:]]


def plain(start, step, n):
    t0 = datetime.fromisoformat(start)
    return [t0 + timedelta(seconds=step * k) for k in range(n)]


# Each jump lands on a whole hour, as a change of clocks would: only the date and the
# hour tell them apart (no zone changes its clocks then).
@pytest.mark.parametrize('start, why', [
    ('2026-03-25 01:00:00', 'a Wednesday'),
    ('2026-03-29 13:00:00', 'the afternoon of a day clocks change'),
    ('2026-07-12 01:00:00', 'a Sunday in July'),
])
def test_an_hours_jump_where_no_clock_changes_stays_a_gap(tmp_path, start, why):
    stamps = shifted(plain(start, 10.0, 720), 360, 1)
    assert stamps[360] - stamps[359] == timedelta(seconds=3610)
    assert stamps[360].minute == stamps[360].second == 0
    text, op = csv_of(stamps)
    rec = load_record(write_text(tmp_path / 'gap.csv', text))
    assert rec.samples == 720 + 360, why
    assert not any('clocks went' in n for n in rec.notes)
    np.testing.assert_array_equal(rec.signals['op'][:360], op[:360])
    assert not rec.valid[360:720].any()


@pytest.mark.parametrize('start', ['2026-10-21 02:00:00', '2026-01-11 02:00:00'])
def test_an_hour_back_where_no_clock_changes_is_refused(tmp_path, start):
    # A Wednesday in October, a Sunday in January: two exports joined with an hour overlapping.
    stamps = shifted(plain(start, 10.0, 720), 360, -1)
    assert (stamps[359].minute, stamps[360].minute, stamps[360].second) == (59, 0, 0)
    text, _ = csv_of(stamps)
    with pytest.raises(InputError, match='does not increase.*export the stamps in UTC'):
        load_record(write_text(tmp_path / 'back.csv', text))


@needs_zones
def test_a_newest_first_export_across_the_autumn_change_is_read(tmp_path):
    stamps = local_stamps('Europe/Berlin', ZONES['Europe/Berlin'][1], 10.0, 720)
    text, op = csv_of(stamps)
    head, *rows = text.splitlines()
    rec = load_record(write_text(tmp_path / 'newest.csv', '\n'.join([head, *rows[::-1]]) + '\n'))
    assert rec.samples == 720 and rec.valid.all()
    np.testing.assert_array_equal(rec.signals['op'], op)
    assert any('newest first' in n for n in rec.notes)
    assert any('clocks went back' in n for n in rec.notes)


def test_a_jump_of_other_than_an_hour_is_no_change_of_clocks():
    stamps = shifted(plain('2026-03-29 01:30:00', 10.0, 720), 360, 1.5)
    t = np.array([(s - stamps[0]).total_seconds() for s in stamps])
    out, notes = clock_changes(t, stamps[0])
    assert np.array_equal(out, t) and not any('clocks went' in n for n in notes)
    # It is an outage across 03:00, when Helsinki's clocks go forward that day.
    assert len(notes) == 1 and 'may be an hour shorter' in notes[0]


def test_a_historian_export_across_the_change_is_read_on_its_grid(tmp_path):
    # 2024-03-31, a Sunday: a Chinese plant's export has no summer time, a European one has.
    text = historian_text(n=720, period=10).replace('2024-06-09', '2024-03-31')
    lines = text.split('\r\n')
    lines[1] = lines[1].replace('07:50:00', '01:20:00')
    for i in range(5, 5 + 720):
        k = i - 5
        t = datetime(2024, 3, 31, 1, 20) + timedelta(seconds=10 * k)
        t += timedelta(hours=1) if k >= 240 else timedelta(0)
        cells = lines[i].split('\t')
        cells[0] = f'{t:%Y-%m-%d %H:%M:%S}'
        lines[i] = '\t'.join(cells)
    rec = load_record(write_text(tmp_path / 'hist.txt', '\r\n'.join(lines)))
    assert rec.samples == 720 and rec.valid.all()
    assert any('clocks went forward an hour at 2024-03-31 02:00' in n for n in rec.notes)
    pv = np.array([float(line.split('\t')[2]) for line in lines[5:5 + 720]])
    np.testing.assert_array_equal(rec.signals['pv'], pv)


@needs_zones
def test_excel_serial_dates_across_the_change_read_every_row_as_one_stretch(tmp_path):
    stamps = local_stamps('America/New_York', ZONES['America/New_York'][0], 10.0, 720)
    epoch = datetime(1899, 12, 30)
    days = [f'{(s - epoch).total_seconds() / 86400:.8f}' for s in stamps]
    text, op = csv_of(stamps)
    rows = [f'{d},{line.split(",", 1)[1]}' for d, line in zip(days, text.splitlines()[1:])]
    rec = load_record(write_text(tmp_path / 'excel.csv', 'Time,op,pv\n' + '\n'.join(rows)))
    assert rec.samples == 720 and rec.valid.all()
    np.testing.assert_array_equal(rec.signals['op'], op)
    assert any('clocks went forward' in n for n in rec.notes)


@needs_zones
@pytest.mark.parametrize('which, how', [(0, 'an hour shorter'), (1, 'an hour longer')],
                         ids=['forward', 'back'])
def test_an_outage_across_the_change_is_kept_and_said_to_be_uncertain_by_an_hour(
        tmp_path, which, how):
    # Berlin's clocks change within rows 60-480 (10 s apart); rows 30-539 are missing.
    stamps = local_stamps('Europe/Berlin', ZONES['Europe/Berlin'][which], 10.0, 720)
    kept = stamps[:30] + stamps[540:]
    t = np.array([(s - kept[0]).total_seconds() for s in kept])
    out, notes = clock_changes(t, kept[0])
    # A zone without summer time writes these stamps too: nothing is moved.
    assert np.array_equal(out, t)
    assert len(notes) == 1 and 'outage' in notes[0] and how in notes[0]
    text, op = csv_of(kept)
    rec = load_record(write_text(tmp_path / 'outage.csv', text))
    assert any(how in n for n in rec.notes)
    np.testing.assert_array_equal(rec.signals['op'][:30], op[:30])


def test_an_outage_where_no_clock_changes_says_nothing_of_clocks():
    stamps = plain('2026-07-12 01:30:00', 10.0, 720)
    kept = stamps[:30] + stamps[540:]
    t = np.array([(s - kept[0]).total_seconds() for s in kept])
    out, notes = clock_changes(t, kept[0])
    assert notes == [] and np.array_equal(out, t)

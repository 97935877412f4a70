"""Dates as spreadsheets write them: month names, and an order of day and month given."""

from datetime import datetime, timedelta

import numpy as np
import pytest
from stiction_ros.analysis.readers import load_record
from stiction_ros.app.analyze import AnalyzeOptions
from stiction_ros.cli.analyze import EXIT_INPUT, main
from stiction_ros.errors import InputError
from test_analysis_inputs import historian_text, write_text

N = 240
OP = np.round(50 + 8 * np.sin(np.arange(N) / 6), 4)


def csv_file(path, stamps):
    rows = ''.join(f'"{s}",{OP[k]:.4f},{OP[k] / 2:.4f}\n' for k, s in enumerate(stamps))
    return write_text(path, 'Timestamp,op,pv\n' + rows)


def clock(start, fmt, step=10):
    t0 = datetime.fromisoformat(start)
    return [(t0 + timedelta(seconds=step * k)).strftime(fmt) for k in range(N)]


@pytest.mark.parametrize('fmt', ['%d-%b-%y %H:%M:%S', '%d-%b-%Y %H:%M:%S',
                                 '%d %b %Y %I:%M:%S %p', '%b %d, %Y %H:%M:%S',
                                 '%B %d, %Y %H:%M:%S', '%d-%B-%Y %H:%M'])
def test_dates_with_month_names_are_read(tmp_path, fmt):
    step = 60 if '%S' not in fmt else 10
    rec = load_record(csv_file(tmp_path / 'm.csv', clock('2024-06-09 23:50:00', fmt, step)))
    assert rec.start_time == '2024-06-09T23:50:00' and rec.samples == N
    assert rec.sample_time == step and rec.valid.all()
    np.testing.assert_array_equal(rec.signals['op'], OP)


# The English names strftime writes, and German Excel's for the months that differ.
GERMAN = {'Mar': 'Mär', 'May': 'Mai', 'Oct': 'Okt', 'Dec': 'Dez',
          'March': 'März', 'October': 'Oktober', 'December': 'Dezember'}


@pytest.mark.parametrize('start', ['2024-03-09 23:50:00', '2024-05-09 23:50:00',
                                   '2024-10-09 23:50:00', '2024-12-09 23:50:00'])
@pytest.mark.parametrize('fmt', ['%d. %b %Y %H:%M:%S', '%d.%b.%y %H:%M:%S', '%d-%b-%y %H:%M:%S',
                                 '%d. %B %Y %H:%M:%S'])
def test_german_month_names_are_read(tmp_path, start, fmt):
    def german(text):
        # Whole names first: 'March' holds 'Mar'.
        for en, de in sorted(GERMAN.items(), key=lambda kv: -len(kv[0])):
            text = text.replace(en, de)
        return text
    stamps = [german(s) for s in clock(start, fmt)]
    assert not any(m in stamps[0] for m in ('Mar ', 'May', 'Oct', 'Dec'))
    rec = load_record(csv_file(tmp_path / 'de.csv', stamps))
    assert rec.start_time == start.replace(' ', 'T') and rec.samples == N
    np.testing.assert_array_equal(rec.signals['op'], OP)


@pytest.mark.parametrize('word', ['Mrz', 'Maerz', 'März', 'Mär.'])
def test_march_as_german_exports_write_it(tmp_path, word):
    stamps = [f'{1 + k // 144:02d}. {word} 2024 {k % 144 // 6:02d}:{k % 6 * 10:02d}:00'
              for k in range(N)]
    rec = load_record(csv_file(tmp_path / 'mar.csv', stamps))
    assert rec.start_time == '2024-03-01T00:00:00' and rec.sample_time == 600.0


def test_a_two_digit_year_reads_as_excel_reads_it(tmp_path):
    rec = load_record(csv_file(tmp_path / 'y.csv', clock('1998-01-05 08:00:00',
                                                         '%d-%b-%y %H:%M:%S')))
    assert rec.start_time == '1998-01-05T08:00:00'


def test_a_word_that_is_no_month_is_refused(tmp_path):
    path = csv_file(tmp_path / 'x.csv', [f'13-Foo-24 14:00:{k % 60:02d}' for k in range(N)])
    with pytest.raises(InputError, match="'foo' is no month name"):
        load_record(path)


AMBIGUOUS = clock('2026-03-01 12:00:00', '%m/%d/%Y %H:%M:%S')   # no day over 12


def test_dates_no_day_orders_are_refused_with_the_option_that_orders_them(tmp_path):
    path = csv_file(tmp_path / 'a.csv', AMBIGUOUS)
    with pytest.raises(InputError, match='pass --date-order dmy .day first. or mdy'):
        load_record(path)


@pytest.mark.parametrize('order, start', [('mdy', '2026-03-01T12:00:00'),
                                          ('dmy', '2026-01-03T12:00:00')])
def test_the_order_given_reads_them(tmp_path, order, start):
    rec = load_record(csv_file(tmp_path / 'a.csv', AMBIGUOUS), date_order=order)
    assert rec.start_time == start and rec.samples == N
    np.testing.assert_array_equal(rec.signals['op'], OP)


def test_a_date_that_contradicts_the_order_given_is_refused(tmp_path):
    path = csv_file(tmp_path / 'd.csv', clock('2026-03-13 12:00:00', '%d/%m/%Y %H:%M:%S'))
    assert load_record(path).start_time == '2026-03-13T12:00:00'     # 13 proves day first
    with pytest.raises(InputError, match='13 is no month, as --date-order mdy reads it'):
        load_record(path, date_order='mdy')


def test_the_command_line_takes_the_order_and_checks_it(tmp_path, capsys):
    path = csv_file(tmp_path / 'a.csv', AMBIGUOUS)
    assert main([str(path), '--quiet', '--no-hammerstein']) == EXIT_INPUT
    assert '--date-order' in capsys.readouterr().err
    assert main([str(path), '--quiet', '--no-hammerstein', '--date-order', 'dmy',
                 '--json', str(tmp_path / 'r.json')]) == 0
    assert '"start_time": "2026-01-03T12:00:00' in (tmp_path / 'r.json').read_text()
    with pytest.raises(InputError, match=r"must be one of \('dmy', 'mdy'\)"):
        AnalyzeOptions(input=str(path), date_order='ymd')


def test_a_historian_export_says_the_order_given_is_not_used(tmp_path):
    rec = load_record(write_text(tmp_path / 'h.txt', historian_text(n=120)), date_order='dmy')
    assert any(n.startswith('--date-order ignored') for n in rec.notes)


def test_a_convention_reads_with_a_note_the_order_given_overrides_it_and_a_proof_wins(
        tmp_path):
    # Australian Excel: day first with AM/PM; a day over 12 proves it, whatever the AM/PM.
    au = csv_file(tmp_path / 'au.csv', clock('2024-06-13 14:00:00', '%d/%m/%Y %I:%M:%S %p'))
    rec = load_record(au)
    assert rec.start_time == '2024-06-13T14:00:00'
    assert not any('no day over 12' in n for n in rec.notes)
    with pytest.raises(InputError, match='13 is no month'):
        load_record(au, date_order='mdy')
    # 1 March in a UK export with AM/PM: nothing proves the order, so it is said.
    uk = csv_file(tmp_path / 'uk.csv', clock('2026-03-01 12:00:00', '%d/%m/%Y %I:%M:%S %p'))
    rec = load_record(uk)
    assert rec.start_time == '2026-01-03T12:00:00'
    assert any('read month first, as US Excel writes dates with AM/PM; pass --date-order dmy'
               in n for n in rec.notes)
    assert load_record(uk, date_order='dmy').start_time == '2026-03-01T12:00:00'
    dotted = csv_file(tmp_path / 'de.csv', clock('2026-01-03 12:00:00', '%d.%m.%Y %H:%M:%S'))
    rec = load_record(dotted)
    assert rec.start_time == '2026-01-03T12:00:00'
    assert any('read day first, as dotted dates are written' in n for n in rec.notes)
    assert load_record(dotted, date_order='mdy').start_time == '2026-03-01T12:00:00'


@pytest.mark.parametrize('fmt', ['%d-%b-%y %H:%M', '%Y-%m-%d %H:%M', '%m/%d/%Y %I:%M %p'])
def test_stamps_without_seconds_at_a_faster_sampling_name_the_cause(tmp_path, fmt):
    path = csv_file(tmp_path / 's.csv', clock('2024-06-13 14:00:00', fmt, step=10))
    with pytest.raises(InputError, match='does not increase.*the stamps have no seconds'):
        load_record(path)

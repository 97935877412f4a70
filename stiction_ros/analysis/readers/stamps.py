"""
Read a CSV's time column: numbers in a unit, or dates and times as historians write them.

Numbers are seconds unless the header names another unit (``time (ms)``,
``Time [min]``, ``t_h``).  Without a unit, numbers from 1e11 on are Unix
time in milliseconds (1e11 s is 3 000 years; 1e11 ms is 1973), and from 1e9
on Unix time in seconds: both give the record a start time in UTC.

Text is a date and time: ISO 8601 (``2026-03-01 12:00:00``,
``2026-03-01T12:00:00Z``, ``2026-03-01T12:00:00+01:00``, fractions of a
second), ``01.03.2026 12:00:00`` (day first, as German and most European
locales write), ``2026/03/01 12:00:00``, and ``03/01/2026 1:00:00 PM``
where a day over 12 proves the order of month and day or ``--date-order``
says it; where neither does, dots are read day first and an AM/PM month
first (US Excel), each with a note, and other dates are refused; ``13-Jun-24 14:00``,
``13 Jun 2024`` and ``Jun 13, 2024 2:00 PM`` (English or German month names, a
two-digit year as Excel reads it); or a time of day alone.  A zone in a header
(``Timestamp (UTC)``) applies to stamps that have none.  Stamps with
offsets are compared as instants, so a change of offset (summer time) is
no jump; local stamps without one skip or repeat an hour when clocks
change, which is read as contiguous rows where only a change of clocks fits
(``daylight.py``) and refused with the fix otherwise.
"""

from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone
import math
import re
from typing import Callable

import numpy as np
from stiction_ros.analysis.readers.daylight import clock_changes
from stiction_ros.errors import InputError

UNITS = {'s': 1.0, 'sec': 1.0, 'secs': 1.0, 'second': 1.0, 'seconds': 1.0,
         'ms': 1e-3, 'msec': 1e-3, 'us': 1e-6, 'µs': 1e-6, 'μs': 1e-6, 'ns': 1e-9,
         'min': 60.0, 'mins': 60.0, 'minute': 60.0, 'minutes': 60.0,
         'h': 3600.0, 'hr': 3600.0, 'hrs': 3600.0, 'hour': 3600.0, 'hours': 3600.0,
         'd': 86400.0, 'day': 86400.0, 'days': 86400.0}
ZONES = {'utc': timezone.utc, 'gmt': timezone.utc, 'z': timezone.utc}
UNIX_S = 1e9
UNIX_MS = 1e11
UNIX_END = 1e14
# Excel's serial dates (days since 1899-12-30) of the years 1954-2119, stepping by
# at least half a second and written with the decimals a second needs (1 s is
# 1.2e-5 days): a seconds clock there that steps by under 0.01 s is a fast logger's,
# written with fewer decimals.
EXCEL_DAYS = (20_000.0, 80_000.0)
EXCEL_DECIMALS = 5
EXCEL_EPOCH = datetime(1899, 12, 30)
# Whole-number stamps at least this far apart (s) without a unit are said to be
# read as seconds: a 1 s logger in milliseconds writes 1000.
MS_HINT_STEP = 100.0
_TIME = (r'(?P<H>\d{1,2}):(?P<M>\d{2})(?::(?P<S>\d{2})(?:[.,](?P<f>\d{1,9}))?)?'
         r'\s*(?P<ap>[AaPp][Mm])?')
_ZONE = r'\s*(?P<z>Z|UTC|GMT|[+-]\d{2}:?\d{2})?'
DATE_TIME = re.compile(r'(?P<a>\d{1,4})(?P<sep>[./-])(?P<b>\d{1,2})(?P=sep)(?P<c>\d{1,4})'
                       rf'(?:(?:[ T]+|,\s*){_TIME})?{_ZONE}')
TIME_OF_DAY = re.compile(_TIME + _ZONE)
# Excel's 13-Jun-24 and 13 Jun 2024, and the US Jun 13, 2024: English month names;
# German Excel's 13. Mai 2024 and 13-Okt-24 (no German abbreviation is another
# month's English one).
MONTHS = {m: i + 1 for i, m in enumerate(
    ('jan', 'feb', 'mar', 'apr', 'may', 'jun', 'jul', 'aug', 'sep', 'oct', 'nov', 'dec'))}
MONTHS.update({'mär': 3, 'mae': 3, 'mrz': 3, 'mai': 5, 'okt': 10, 'dez': 12})
_MON = r'(?P<mon>[^\W\d_]{3,9})\.?'
_SEP = r'(?:\.\s*|[- ])'
MONTH_DATE = re.compile(rf'(?:(?P<d>\d{{1,2}}){_SEP}{_MON}{_SEP}(?P<y>\d{{4}}|\d{{2}})'
                        rf'|{_MON.replace("mon", "mon2")} (?P<d2>\d{{1,2}}),? (?P<y2>\d{{4}}))'
                        rf'(?:(?:[ T]+|,\s*){_TIME})?{_ZONE}')
# A two-digit year as Excel reads it: 00-29 in this century, 30-99 in the last.
CENTURY_PIVOT = 30
DATE_ORDERS = ('dmy', 'mdy')
ISO_FIX = 'write the column as 2026-03-01 12:00:00 (ISO 8601) or in seconds'


@dataclass
class Stamps:
    """
    A time column read: seconds, and the clock time of ``seconds == 0`` if any.

    ``seconds`` are the column's own numbers (converted to s) for numbers,
    seconds from the first stamp for dates; ``start`` is the date and time
    of the first stamp (dates, Unix time) or None.  ``kind`` is ``'seconds'``, ``'unix'``,
    ``'datetime'`` or ``'time of day'``.
    """

    seconds: np.ndarray
    start: datetime | None
    kind: str
    notes: list = field(default_factory=list)
    name: str = ''


def read_stamps(path: object, name: str, unit: str | None, cells: list[str],
                rows: list[int], number: Callable[[int, str], float],
                is_number: Callable[[str], bool], date_order: str | None = None) -> Stamps:
    """
    Return the :class:`Stamps` of the time column ``name`` (``cells`` at file ``rows``).

    ``unit`` is what the header gave in brackets or after an underscore, if
    anything; ``number(row, text)`` reads a cell as the CSV reader reads numbers
    (decimal commas included) and raises its error for anything else;
    ``is_number(text)`` says whether it would read one.  ``date_order``
    (``'dmy'`` or ``'mdy'``, ``--date-order``) says which of day and month
    comes first where no date proves it, and overrides the conventions (dots
    day first, AM/PM month first, as US Excel writes); a day over 12 where it
    puts the month is refused.
    """
    first = next((c.strip() for c in cells if c.strip()), '')
    if not first or is_number(first):
        return _numbers(path, name, unit, cells, rows, number)
    zone = ZONES.get((unit or '').strip().lower())
    if unit and zone is None and unit.strip().lower() in UNITS:
        raise InputError(f'{path}: column {name!r} gives the unit {unit!r} but holds '
                         f'{first[:30]!r}, not a number: {ISO_FIX}')
    if TIME_OF_DAY.fullmatch(first):
        return _times_of_day(path, name, cells, rows, zone)
    return _dates(path, name, cells, rows, zone, date_order)


def _numbers(path, name, unit, cells, rows, number):
    factor = 1.0
    if unit is not None and unit.strip().lower() not in ZONES:
        factor = UNITS.get(unit.strip().lower())
        if factor is None:
            raise InputError(f'{path}: column {name!r}: unknown time unit {unit!r}; name the '
                             "column with one of s, ms, us, ns, min, h, d, e.g. 'time (s)'")
    t = np.array([number(r, c) for r, c in zip(rows, cells)], dtype=np.float64) * factor
    notes, kind, start = [], 'seconds', None
    first = t[0] if len(t) and math.isfinite(t[0]) else 0.0
    if factor == 1.0 and UNIX_MS <= first < UNIX_END and unit not in UNITS:
        t = t / 1000.0
        first /= 1000.0
        notes.append(f'{name}: numbers from {UNIX_MS:g} on read as Unix time in milliseconds '
                     "(name the column 'time (s)' if they are seconds)")
    elif unit is None and _excel_days(t, first, cells):
        start = EXCEL_EPOCH + timedelta(milliseconds=round(float(first) * 86_400_000.0))
        t = (t - first) * 86400.0
        notes.append(f'{name}: numbers near {first:.6g} stepping by under a hundredth read as '
                     f'Excel serial dates (days since 1899-12-30: {start:%Y-%m-%d %H:%M:%S} '
                     "on); name the column 'time (s)' if they are seconds")
        # Excel keeps the local clock's reading, summer time and all.
        t, changes = clock_changes(t, start)
        return Stamps(t, start, 'datetime', notes + changes)
    elif first >= UNIX_END:
        raise InputError(f'{path}: column {name!r}: {first:g} is no time in seconds; give its '
                         "unit in the header, e.g. 'time (us)' or 'time (ns)'")
    if UNIX_S <= first < UNIX_MS:
        kind = 'unix'
        start = datetime.fromtimestamp(first, timezone.utc)
    elif unit is None:
        notes += _milliseconds_hint(name, t)
    return Stamps(t, start, kind, notes)


def _milliseconds_hint(name: str, t: np.ndarray) -> list[str]:
    # A logger's milliseconds under a bare 't' read as seconds put every period
    # 1000 times too long; whole numbers a long sample apart may be either.
    steps = np.diff(t[np.isfinite(t)])
    steps = steps[steps > 0]
    if not len(steps):
        return []
    step = float(np.median(steps))
    if step < MS_HINT_STEP or not np.all(np.mod(t[np.isfinite(t)], 1.0) == 0.0):
        return []
    return [f'{name}: whole numbers {step:g} apart, read as seconds (a sample every '
            f"{_span(step)}); if they are milliseconds, name the column '{name} (ms)'"]


def _span(seconds: float) -> str:
    if seconds >= 3600.0:
        return f'{seconds / 3600.0:.3g} h'
    if seconds >= 60.0:
        return f'{seconds / 60.0:.3g} min'
    return f'{seconds:g} s'


def _excel_days(t: np.ndarray, first: float, cells: list[str]) -> bool:
    if not EXCEL_DAYS[0] <= first < EXCEL_DAYS[1]:
        return False
    text = next((c.strip() for c in cells if c.strip()), '').replace(',', '.')
    if len(text.partition('.')[2]) < EXCEL_DECIMALS:
        return False
    steps = np.diff(t[np.isfinite(t)])
    steps = steps[steps > 0]
    if not len(steps):
        return False
    step = float(np.median(steps))
    return step < 0.01 and step * 86400.0 >= 0.5


def _dates(path, name, cells, rows, zone, given=None):
    stamps, parsed = [], []
    for row, cell in zip(rows, cells):
        text = cell.strip()
        try:
            stamp = datetime.fromisoformat(text)
        except ValueError:
            m = DATE_TIME.fullmatch(text)
            if m is None:
                named = MONTH_DATE.fullmatch(text)
                if named is None:
                    _refuse(path, name, row, cell, 'not a date and time')
                stamps.append(_from_month_name(path, name, row, cell, named))
                continue
            parsed.append((row, cell, m))
            stamps.append(None)
            continue
        stamps.append(stamp)
    if parsed:
        order, note = _date_order(path, name, parsed, given)
        it = iter(parsed)
        stamps = [s if s is not None else _from_match(path, name, *next(it), order)
                  for s in stamps]
    out = _relative(path, name, stamps, rows, cells, zone, 'datetime')
    if parsed and note:
        out.notes.insert(0, note)
    return out


def _date_order(path, name, parsed, given=None):
    """Return the order of day and month, and a note where a convention chose it."""
    # Proven by a value over 12, or given (--date-order); else a convention, said so.
    if given is not None:
        return _given_order(path, name, parsed, given), ''
    dotted = day_first = month_first = ampm = False
    for _, _, m in parsed:
        if len(m['a']) == 4:
            continue
        dotted |= m['sep'] == '.'
        ampm |= bool(m['ap'])
        day_first |= int(m['a']) > 12
        month_first |= int(m['b']) > 12
    row, cell, _ = parsed[0]
    if day_first and month_first:
        _refuse(path, name, row, cell, 'its dates mix day/month and month/day orders')
    if day_first or month_first:
        return ('dmy' if day_first else 'mdy'), ''
    if dotted or ampm:
        order, how, other = (('dmy', 'day first, as dotted dates are written', 'mdy')
                             if dotted else
                             ('mdy', 'month first, as US Excel writes dates with AM/PM', 'dmy'))
        return order, (f'{name}: no day over 12 shows the order of day and month: read '
                       f'{how}; pass --date-order {other} if not')
    if all(len(m['a']) == 4 for _, _, m in parsed):
        return 'ymd', ''
    raise InputError(f'{path}: row {row}, column {name!r}: {cell.strip()[:40]!r}: no day over '
                     '12 shows whether the day or the month comes first; pass --date-order '
                     f'dmy (day first) or mdy (month first), or {ISO_FIX}')


def _given_order(path, name, parsed, given):
    if given not in DATE_ORDERS:
        raise InputError(f'date order must be one of {DATE_ORDERS}, got {given!r}')
    month = 'b' if given == 'dmy' else 'a'
    for row, cell, m in parsed:
        if len(m['a']) != 4 and int(m[month]) > 12:
            _refuse(path, name, row, cell, f'{m[month]} is no month, as --date-order '
                    f'{given} reads it')
    return given


def _from_month_name(path, name, row, cell, m):
    mon = (m['mon'] or m['mon2']).lower()
    month = MONTHS.get(mon[:3])
    if month is None or (len(mon) > 3 and not _month_word(mon)):
        _refuse(path, name, row, cell,
                f'{mon!r} is no month name (English: Jan ... Dec, or German: Jan ... Dez)')
    if m['d'] is not None:
        d, y = int(m['d']), int(m['y'])
        if len(m['y']) == 2:
            y += 2000 if y < CENTURY_PIVOT else 1900
    else:
        d, y = int(m['d2']), int(m['y2'])
    return _stamp(path, name, row, cell, m, (y, month, d))


def _month_word(mon):
    words = ('january', 'february', 'march', 'april', 'may', 'june', 'july', 'august',
             'september', 'october', 'november', 'december', 'sept',
             'januar', 'februar', 'märz', 'maerz', 'juni', 'juli', 'oktober', 'dezember')
    return mon in words


def _from_match(path, name, row, cell, m, order):
    a, b, c = int(m['a']), int(m['b']), int(m['c'])
    if len(m['a']) == 4:
        y, mo, d = a, b, c
    elif len(m['c']) != 4:
        _refuse(path, name, row, cell, 'the year must have four digits')
    elif order == 'dmy':
        d, mo, y = a, b, c
    else:
        mo, d, y = a, b, c
    return _stamp(path, name, row, cell, m, (y, mo, d))


def _stamp(path, name, row, cell, m, date):
    """Return the stamp of ``date`` (year, month, day) at the time of day ``m`` holds."""
    h, mi, s, us = _clock(path, name, row, cell, m) if m['H'] else (0, 0, 0, 0)
    try:
        stamp = datetime(*date, h, mi, s, us)
    except ValueError as err:
        _refuse(path, name, row, cell, str(err))
    return _zoned(stamp, m['z'])


def _clock(path, name, row, cell, m):
    h, mi, s = int(m['H']), int(m['M']), int(m['S'] or 0)
    us = int((m['f'] or '0').ljust(6, '0')[:6])
    if m['ap']:
        if not 1 <= h <= 12:
            _refuse(path, name, row, cell, f'hour {h} with {m["ap"]}')
        h = h % 12 + (12 if m['ap'].lower() == 'pm' else 0)
    return h, mi, s, us


def _zoned(stamp, z):
    if not z:
        return stamp
    if z.upper() in ('Z', 'UTC', 'GMT'):
        return stamp.replace(tzinfo=timezone.utc)
    sign = -1 if z[0] == '-' else 1
    hh, mm = int(z[1:3]), int(z[-2:])
    return stamp.replace(tzinfo=timezone(sign * timedelta(hours=hh, minutes=mm)))


def _times_of_day(path, name, cells, rows, zone):
    stamps = []
    day = datetime(1900, 1, 1)
    for row, cell in zip(rows, cells):
        m = TIME_OF_DAY.fullmatch(cell.strip())
        if m is None:
            _refuse(path, name, row, cell, 'not a time of day like the rows before')
        h, mi, s, us = _clock(path, name, row, cell, m)
        try:
            stamp = _zoned(day.replace(hour=h, minute=mi, second=s, microsecond=us), m['z'])
        except ValueError as err:
            _refuse(path, name, row, cell, str(err))
        if stamps and stamp.tzinfo == stamps[-1].tzinfo \
                and stamp < stamps[-1] - timedelta(hours=12):
            # Past midnight: a time of day far before the last is on the next day.
            day += timedelta(days=1)
            stamp += timedelta(days=1)
        stamps.append(stamp)
    out = _relative(path, name, stamps, rows, cells, zone, 'time of day')
    out.start = None
    out.notes.append(f'{name}: times of day without a date; the record has no start date')
    return out


def _relative(path, name, stamps, rows, cells, zone, kind):
    aware = [s.tzinfo is not None for s in stamps]
    if zone is not None:
        stamps = [s if s.tzinfo is not None else s.replace(tzinfo=zone) for s in stamps]
    elif any(aware) and not all(aware):
        i, j = aware.index(True), aware.index(False)
        raise InputError(f'{path}: column {name!r}: row {rows[i]} has a time zone '
                         f'({cells[i].strip()!r}), row {rows[j]} has none '
                         f'({cells[j].strip()!r}); give every stamp its offset, or none')
    t0 = stamps[0]
    t = np.array([(s - t0).total_seconds() for s in stamps], dtype=np.float64)
    notes = []
    if kind == 'datetime' and t0.tzinfo is None:
        t, notes = clock_changes(t, t0)
    return Stamps(t, t0, kind, notes)


def decrease_hint(stamps: Stamps, step: float) -> str:
    """Return a hint for time going back by ``step`` s (negative), or ''."""
    if stamps.kind == 'datetime' and stamps.start is not None and stamps.start.tzinfo is None \
            and -3600.0 - 1e-6 <= step < 0:
        return ('; local time without an offset repeats an hour when clocks go back: export '
                'the stamps in UTC or with their offset (2026-10-25T02:30:00+01:00)')
    return ''


def _refuse(path, name, row, cell, why):
    raise InputError(f'{path}: row {row}, column {name!r}: {cell.strip()[:40]!r}: {why}; '
                     + ISO_FIX)

"""
Read a CSV, or a historian's or spreadsheet's CSV export, into a :class:`Record`.

The columns (columns.py): a time column (``t``, ``time``, ``timestamp``,
``Time (s)`` ...; seconds or dates, stamps.py) and ``op``, plus any of
``mv``, ``pv``, ``sp``, or tag-prefixed names (``FIC101.OP``); ``columns``
(``--columns``) names them where the names do not say.  Other columns are
ignored (with a note).  The delimiter is whichever of ``,``, ``;`` or tab
the header uses most.  With ``;`` or tab between cells, a decimal comma
(``1,25``, also ``1.234,5``) is read as the European locales of Excel
write it.  Row numbers in messages are the file's line numbers, as a
spreadsheet shows them (the header is row 1).  An empty cell, ``nan``,
``inf`` or a historian's word for a bad value (``No Data``, ``I/O Timeout``,
``#N/A``) is a missing value (NaN, noted); any other text is an error.  A
units row and a description row under the header (no digit in the time cell,
no number among the signals, data after them) are skipped, and said so;
rows whose time falls on every row (a newest-first export) are read in reverse.
OP or MV in mA (``OP (mA)``, or ``mA`` in the units row) is read as % of
span, 4-20 mA being 0-100 %.

Rows on one sample grid are placed on it, and a sample without a row is a
gap.  Rows that are not (a historian's raw values, stored when they change;
a logger's jittered stamps) are resampled at a period the notes state, by
linear interpolation between stored values (align.py says why).
"""

import csv
from dataclasses import replace
from datetime import datetime, timedelta
import re

import numpy as np
from stiction_ros.analysis.readers import align
from stiction_ros.analysis.readers.bad_words import BAD_WORDS
from stiction_ros.analysis.readers.columns import match_columns, split_unit
from stiction_ros.analysis.readers.daylight import HOUR
from stiction_ros.analysis.readers.modes import EXCLUDED, held, read_modes
from stiction_ros.analysis.readers.stamps import decrease_hint, read_stamps, TIME_OF_DAY
from stiction_ros.analysis.record import assemble, InputError

DECIMAL_COMMA = re.compile(r'[+-]?(?:\d{1,3}(?:\.\d{3})+|\d*),\d+(?:[eE][+-]?\d+)?')
# Rows on one grid that cover fewer of its samples than this were stored on change,
# not logged every sample (a logger that lost a tenth of its rows is rare; a
# historian that stores on change skips most samples of a steady signal): they are
# resampled, not left with gaps.
COVERED = 0.9
# A historian's compression stores fewer values than this share of the samples: the
# stiction measures of the reconstruction may be artefacts of the compression.
COMPRESSED = 3.0
MAX_SAMPLES = 50_000_000
# A time of day without seconds ('14:00', '2:00 PM') at the end of a stamp.
NO_SECONDS = re.compile(r'(?<![:\d])\d{1,2}:\d{2}(\s*[AaPp][Mm])?$')
# A controller output given in mA ('OP (mA)') spans 4-20 mA.
MA_LOW, MA_HIGH = 4.0, 20.0


class _Cells:
    """Read the cells of one file as numbers; count decimal commas and words for bad."""

    def __init__(self, path, delim):
        self.path, self.comma_ok, self.delim = path, delim != ',', delim
        self.commas, self.comma_example, self.comma_whole = 0, None, True
        self.bad = {}

    def number(self, no, name, cell):
        text = cell.strip()
        if not text:
            return np.nan
        try:
            return float(text)
        except ValueError:
            pass
        if DECIMAL_COMMA.fullmatch(text):
            if self.comma_ok:
                self.commas += 1
                value = float(text.replace('.', '').replace(',', '.'))
                if self.comma_example is None or (self.comma_whole and not value.is_integer()):
                    # the note's example is one whose decimals show (1,25, not 0,0)
                    self.comma_example, self.comma_whole = text, value.is_integer()
                return value
            raise InputError(f'{self.path}: row {no}, column {name!r}: {_cell(cell)} is not a '
                             "number: with ',' between cells, write decimals with '.' (or "
                             "save the file with ';' between cells)")
        if text.lower() in BAD_WORDS:
            self.bad.setdefault(name, {}).setdefault(text, 0)
            self.bad[name][text] += 1
            return np.nan
        raise InputError(f'{self.path}: row {no}, column {name!r}: {_cell(cell)} is not a '
                         'number')

    def is_number(self, text):
        # a decimal comma between ',' separators is a number to refuse with the hint
        text = text.strip()
        return bool(DECIMAL_COMMA.fullmatch(text)) or _is_number(text)

    def notes(self):
        out = []
        if self.commas:
            value = float(self.comma_example.replace('.', '').replace(',', '.'))
            out.append(f'decimal commas: {self.commas} cells such as '
                       f'{self.comma_example!r} read as {value:g}')
        for name, words in self.bad.items():
            count = sum(words.values())
            out.append(f'{name}: {count} cell' + ('s' if count > 1 else '') + ' marked bad ('
                       + ', '.join(repr(w) for w in words) + ') read as missing values')
        return out


def read_csv_record(path, text, columns=None, date_order=None):
    """
    Return the :class:`Record` of CSV ``text`` read from ``path``.

    ``columns`` as ``--columns``; ``date_order`` (``'dmy'``, ``'mdy'``) as
    ``--date-order``, for dates no day over 12 orders.
    """
    lines = [(i + 1, line) for i, line in enumerate(text.splitlines())
             if line.strip() and not line.lstrip().startswith('#')]
    if not lines:
        raise InputError(f'{path}: no header row and no data')
    head_no, head = lines[0]
    delim = max((',', ';', '\t'), key=head.count)
    header = [c.strip() for c in _parse(path, [head], delim)[0]]
    if all(_is_number(c) or _is_date(c) for c in header):
        raise InputError(f'{path}: no header row; line {head_no} holds data. The first line '
                         'must name the columns: a time (t, time or timestamp), op and any of '
                         'mv, pv, sp')
    cols = match_columns(path, header, columns)
    rows = _parse(path, [line for _, line in lines[1:]], delim)
    if not rows:
        raise InputError(f'{path}: a header row but no data')
    nos = [no for no, _ in lines[1:]]
    rows, nos, label_notes, label_rows = _skip_label_rows(rows, nos, cols)
    for no, cells in zip(nos, rows):
        while len(cells) > len(header) and not cells[-1].strip():
            cells.pop()                  # a trailing delimiter, as some exports end rows
        if len(cells) != len(header):
            hint = (": if its numbers have decimal commas (1,25), save the file with ';' "
                    'between cells' if delim == ',' and len(cells) > len(header) else '')
            raise InputError(f'{path}: row {no} has {len(cells)} cells; the header has '
                             f'{len(header)}{hint}')
    reader = _Cells(path, delim)
    if _newest_first(path, header, cols, rows, nos, reader, date_order):
        # Some historians' web exports list the newest row first.
        rows, nos = rows[::-1], nos[::-1]
        label_notes.append('rows run newest first (time falls on every row): read oldest '
                           'first')
    stamps, notes = _time(path, header, cols, rows, nos, reader, date_order=date_order)
    values, stored, marked = {}, {}, {}
    for name, c in cols.signals.items():
        values[name] = np.array([reader.number(no, header[c], cells[c])
                                 for no, cells in zip(nos, rows)], dtype=np.float64)
        stored[name] = np.array([bool(cells[c].strip()) for cells in rows])
        marked[name] = sum(reader.bad.get(header[c], {}).values())
    notes += _milliamps(header, cols.signals, values, label_rows)
    mode = None
    if cols.mode is not None:
        mode, mode_notes = read_modes(header[cols.mode], [cells[cols.mode] for cells in rows])
        notes += mode_notes
    notes = label_notes + cols.notes + notes + reader.notes()
    names = {s: header[i] for s, i in cols.signals.items()}
    if mode is not None:
        names['mode'] = header[cols.mode]
    return _on_grid(path, stamps, (values, stored, marked, mode), cols.ignored, notes, names)


def _skip_label_rows(rows, nos, cols):
    """Return rows and their numbers without the units or description rows under the header."""
    used = [cols.time, *cols.signals.values()]

    def labels(cells):
        # No digit in the time cell and no number among the signals: '', '%', 'kg/h'.
        got = [cells[i].strip() if i < len(cells) else '' for i in used]
        return (not any(ch.isdigit() for ch in got[0])
                and not any(_is_number(c) or DECIMAL_COMMA.fullmatch(c) for c in got[1:]))

    # A units row and a description row at most, then data.
    k = 0
    while k < min(3, len(rows)) and labels(rows[k]):
        k += 1
    if not 0 < k <= 2 or k == len(rows):
        return rows, nos, [], []
    notes = []
    for no, cells in zip(nos[:k], rows[:k]):
        shown = ', '.join(repr(c.strip()) for c in cells if c.strip()) or 'empty cells'
        notes.append(f'row {no} read as units or descriptions, not data ({shown[:80]})')
    return rows[k:], nos[k:], notes, rows[:k]


def _parse(path, lines, delim):
    try:
        return list(csv.reader(lines, delimiter=delim))
    except csv.Error as err:
        # e.g. a cell over the csv module's 128 KiB limit: no recording has one
        raise InputError(f'{path}: not a readable CSV ({err})') from None


def _newest_first(path, header, cols, rows, nos, reader, date_order):
    """Return whether the time column falls on every row (a newest-first export)."""
    if len(rows) < 3:
        return False
    try:
        # A copy: reading the stamps notes an unused date column in ``ignored``.
        probe = replace(cols, ignored=list(cols.ignored))
        t = _time(path, header, probe, rows, nos, _Cells(path, reader.delim), check=False,
                  date_order=date_order)
    except InputError:
        return False
    steps = np.diff(t[0].seconds)
    back = steps < 0
    # Read newest first, the hour clocks repeat in autumn is one step forward of under an
    # hour among steps back; clock_changes reads it once the rows run oldest first.
    ahead = steps[~back]
    return bool(np.all(back) or (len(ahead) <= 2 and np.mean(back) > 0.9
                                 and np.all((ahead > 0) & (ahead < HOUR))))


def _time(path, header, cols, rows, nos, reader, check=True, date_order=None):
    name = header[cols.time]
    cells = [r[cols.time] for r in rows]
    notes = []
    if cols.date is not None:
        first = next((c.strip() for c in cells if c.strip()), '')
        if TIME_OF_DAY.fullmatch(first):
            cells = [f'{r[cols.date].strip()} {c.strip()}' for r, c in zip(rows, cells)]
            notes.append(f'time: {header[cols.date]!r} and {name!r} joined into one stamp')
            name = f'{header[cols.date]} {name}'
        else:
            cols.ignored.append(header[cols.date])
    stamps = read_stamps(path, name, cols.unit, cells, nos,
                         lambda no, text: reader.number(no, name, text), reader.is_number,
                         date_order)
    stamps.name = name
    t = stamps.seconds
    if not check:
        return stamps, notes
    bad = np.flatnonzero(~np.isfinite(t))
    if len(bad):
        raise InputError(f'{path}: row {nos[bad[0]]}: {name} is {_cell(cells[bad[0]])}; every '
                         'row needs a finite time')
    back = np.flatnonzero(np.diff(t) <= 0)
    if len(back):
        r = back[0] + 1
        now, before = _shown(stamps, t, cells, r), _shown(stamps, t, cells, r - 1)
        same = t[r] == t[r - 1] and NO_SECONDS.search(cells[r].strip())
        raise InputError(f'{path}: row {nos[r]}: {name} = {now} does not increase (row '
                         f'{nos[r - 1]}: {name} = {before}); time must increase'
                         + ('; the stamps have no seconds, so rows under a minute apart share '
                            'one: export them with seconds' if same else
                            decrease_hint(stamps, t[r] - t[r - 1])))
    return stamps, stamps.notes + notes


def _milliamps(header, signals, values, label_rows):
    """Read OP or MV given in mA (header or units row) as % of span; return the notes."""
    notes = []
    for name in ('op', 'mv'):
        c = signals.get(name)
        units = [(split_unit(header[c])[1] or '')] if c is not None else []
        units += [r[c] for r in label_rows if c is not None and c < len(r)]
        if not any(u.strip().lower() == 'ma' for u in units):
            continue
        # Every threshold reads OP and MV in % of span; 4-20 mA is that span.
        values[name] = (values[name] - MA_LOW) * (100.0 / (MA_HIGH - MA_LOW))
        notes.append(f'{header[c]}: {MA_LOW:g}-{MA_HIGH:g} mA read as 0-100 % of span')
    return notes


def _shown(stamps, t, cells, r):
    return f'{t[r]:g}' if stamps.kind in ('seconds', 'unix') else repr(cells[r].strip())


def _on_grid(path, stamps, cells, ignored, notes, names_used):
    values, stored, marked, mode = cells
    t = stamps.seconds
    rel = t - t[0]
    try:
        ts = align.sample_period(rel)
    except align.GridError:
        raise InputError(f'{path}: only {len(t)} data row; cannot tell the sample time') from None
    center = align.phase(rel, ts) * ts
    k = align.bins(rel, ts, center)
    k0 = int(k[0])
    k -= k0
    n = int(k[-1]) + 1
    _, crowded, dropped, _ = align.place(k, np.zeros(len(k)), n)
    stray = align.off_grid(rel, ts, center)
    covered = _covered(k, n, ts)
    if ignored:
        notes.append('ignored columns: ' + ', '.join(ignored))
    if stray <= align.STRAY and not len(crowded) and covered >= COVERED:
        _check_size(path, n, ts)
        signals = _binned(k, n, values, marked, notes)
        at = None if mode is None else align.place(k, mode, n)[0]
        sampling = "the rows' spacing"
        offset = center + k0 * ts
    else:
        best = ts
        ts, period_why = align.resample_period(rel)
        n = int(np.floor(rel[-1] / ts + 1e-9)) + 1
        _check_size(path, n, ts)
        if align.off_grid(rel, ts, 0.0) < 1e-3:
            why = f'rows for only {covered:.0%} of the samples outside outages'
        elif stray > align.STRAY:
            why = f'stamps up to {stray:.0%} of a sample off the best grid, {best:g} s'
        else:
            why = f'{dropped} rows share a sample of the best grid, {best:g} s'
        sampling = (f'resampled at {ts:g} s, {period_why}, by linear interpolation between '
                    'stored values')
        notes.append(f'rows not on one sample grid ({why}): {sampling}, as a historian '
                     'interpolates (holding each value would draw steps, which read as '
                     'stick-slip)')
        signals = _resampled(rel, n, ts, values, stored, notes)
        at = None if mode is None else held(rel, mode, np.arange(n) * ts)
        offset = 0.0
    source = {'path': str(path), 'format': 'csv', 'columns': names_used,
              'time': f'{stamps.name} ({stamps.kind})', 'sampling': sampling}
    start = None
    if stamps.start is not None:
        start = (stamps.start + timedelta(seconds=float(offset))).isoformat()
    origin = 0.0 if stamps.kind in ('datetime', 'time of day') else float(t[0] + offset)
    # A sample without a mode value of its own is not excluded for it.
    reasons = None if at is None else {EXCLUDED: at == 0.0}
    return assemble(signals, ts, reasons, notes=notes, source=source, start_time=start,
                    name=_stem(path), time_origin=origin)


def _covered(k, n, ts):
    """Return the share of the grid's samples that have a row, long outages left out."""
    rows = np.unique(k)
    missing = np.diff(rows) - 1
    # A silence longer than a historian ever keeps a steady value is an outage, not
    # values stored on change: a clean grid with one long hole stays on its grid.
    outage = missing[(missing + 1) * ts > max(align.BRIDGE_S, align.BRIDGE_SAMPLES * ts)]
    return len(rows) / max(1, n - int(outage.sum()))


def _check_size(path, n, ts):
    if n > MAX_SAMPLES:
        raise InputError(f'{path}: the time stamps span {n} samples of {ts:g} s; they are not '
                         'one recording (check the time column and its unit)')


def _binned(k, n, values, marked, notes):
    signals = {}
    for name, v in values.items():
        # cells with a word for bad have their own note
        bad = np.count_nonzero(~np.isfinite(v)) - marked[name]
        if bad:
            notes.append(f'{name}: {bad} empty or non-finite cell' + ('s' if bad > 1 else '')
                         + ' read as missing values')
        signals[name] = align.place(k, v, n)[0]
    gaps = n - len(np.unique(k))
    if gaps:
        notes.append(f'{gaps} sample' + ('s have' if gaps > 1 else ' has')
                     + ' no row (a gap in t); left as gaps')
    return signals


def _resampled(rel, n, ts, values, stored, notes):
    grid = np.arange(n) * ts
    longest = max(align.BRIDGE_S, align.BRIDGE_SAMPLES * ts)
    signals, sparse = {}, []
    for name, v in values.items():
        # An empty cell is no stored value (exports of several tags leave the others
        # empty); 'nan' or a word for bad is a bad value, which nothing is drawn across.
        keep = stored[name]
        signals[name], gaps = align.interpolate(rel[keep], v[keep], grid, longest)
        if gaps:
            at, length = max(gaps, key=lambda g: g[1])
            notes.append(f'{name}: {len(gaps)} interval' + ('s' if len(gaps) > 1 else '')
                         + f' longer than {longest:g} s without a stored value (the longest '
                         f'{length:g} s, from t = {at:g} s) left as gaps')
        count = int(np.count_nonzero(np.isfinite(v[keep])))
        if name != 'sp' and count and n / count > COMPRESSED:
            sparse.append(f'{name} 1 in {n / count:.3g}')
    if sparse:
        notes.append('stored values cover few samples (' + ', '.join(sparse) + '): the '
                     'historian compressed them or stored them on change, and stiction '
                     'measures of such data can be artefacts of the compression; if the '
                     'historian can, export interpolated values at the scan rate')
    return signals


def _is_date(text):
    try:
        datetime.fromisoformat(text)
    except ValueError:
        return False
    return True


def _is_number(text):
    try:
        float(text)
    except ValueError:
        return False
    return True


def _cell(cell):
    return repr(cell if len(cell) <= 40 else cell[:37] + '...')


def _stem(path):
    name = str(path).replace('\\', '/').rsplit('/', 1)[-1]
    return name.rsplit('.', 1)[0] if '.' in name else name

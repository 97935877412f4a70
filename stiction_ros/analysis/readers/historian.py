"""
Read a plant historian export (``PROCESSDATA`` first line, tab-separated).

Layout (see ``/work/shared/data/plant_loops/README.md``): line 1 ``PROCESSDATA``,
tag, time format; line 2 columns, sampling period (s), start time, rows;
line 3 ``tagname`` and the column tags; line 4 descriptions; line 5 the
publisher's own settings; then one row per sample.  The historian's
``<TAG>.MV`` is the controller output (``op``), ``.PV`` the process value,
``.SV`` the set point and ``.MODE`` 1 when the loop is in automatic.

Exclusions: a sample whose MODE is not 1, or whose MODE is flagged bad, is
excluded but keeps its values; a value whose flag (``bOpOFL``, ``bPvOFL``,
``bSpOFL``) is set becomes NaN.  Either way the sample is not valid.  A
historian's word for a value it does not have (``I/O Timeout``, ``Bad``:
the CSV reader's list) is a missing value, noted; any other text is an error.

When the file has the rows line 2 announces and each stamp is within one
period of its row's grid instant, row ``i`` is sample ``i``: some exports
stamp a row one period early or late (a repeated stamp next to a doubled
step), which is a labelling slip, not a lost sample.  Otherwise rows are
placed by their stamps like any other source.  Local stamps across a change
of summer time are read as the CSV reader reads them (``daylight.py``).
"""

from datetime import datetime, timedelta

import numpy as np
from stiction_ros.analysis.readers import align
from stiction_ros.analysis.readers.bad_words import BAD_WORDS
from stiction_ros.analysis.readers.daylight import clock_changes
from stiction_ros.analysis.record import assemble, InputError

ROLES = {'MV': 'op', 'OP': 'op', 'PV': 'pv', 'SV': 'sp', 'SP': 'sp', 'MODE': 'mode'}
FLAGS = {'bopofl': 'op', 'bpvofl': 'pv', 'bspofl': 'sp', 'bautofl': 'mode'}
TIME_TOKENS = (('yyyy', '%Y'), ('MM', '%m'), ('dd', '%d'), ('HH', '%H'), ('mm', '%M'),
               ('ss', '%S'), ('fff', '%f'))


def is_historian(text):
    """Return whether ``text`` starts like a historian export."""
    return text.lstrip('\ufeff').split('\n', 1)[0].split('\t', 1)[0].strip() == 'PROCESSDATA'


def read_historian_record(path, text, columns=None):
    """
    Return the :class:`Record` of historian export ``text`` read from ``path``.

    ``columns`` (``--columns``) maps ``op``, ``mv``, ``pv``, ``sp`` to line 3's
    tags where the suffixes do not say; the time is always the first column.
    """
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    blank = next((i for i, line in enumerate(lines) if line.strip()), 0)
    if blank:
        # The header's lines are read by their numbers, and so are the rows
        # an error names: refused rather than counted from somewhere else.
        raise InputError(f'{path}: {blank} blank line(s) before PROCESSDATA; a historian '
                         'export starts with it on line 1: delete the blank lines')
    if len(lines) < 3:
        raise InputError(f'{path}: historian export of {len(lines)} line(s); it needs 5 header '
                         'lines, then the data')
    first = _cells(lines[0])
    tag = first[1].strip() if len(first) > 1 else ''
    tag = tag[:-5] if tag.endswith(' Data') else tag
    fmt = first[2].strip() if len(first) > 2 and first[2].strip() else 'yyyy-MM-dd HH:mm:ss'
    pyfmt = _strptime_format(fmt)
    period, start, announced = _line2(path, lines[1], pyfmt, fmt)
    header = _cells(lines[2])
    if header[0].strip().lower() != 'tagname':
        raise InputError(f"{path}: line 3 must start with 'tagname' and name the columns; "
                         f'got {lines[2][:60]!r}')
    given, columns = columns or {}, [c.strip() for c in header[1:]]
    roles, flags, notes = _roles(path, columns, tag, given)
    desc = _cells(lines[3]) if len(lines) > 3 else ['']
    descs = desc[1:] if desc[0].strip().lower() == 'desc' else []
    first_row = 3
    while first_row < min(5, len(lines)) and _stamp(_cells(lines[first_row])[0], pyfmt) is None:
        first_row += 1
    used = [roles[r] for r in roles] + [flags[f] for f in flags]
    stamps, line_nos, data = _rows(path, lines, first_row, columns, pyfmt, fmt, used, notes)
    if not len(stamps):
        raise InputError(f'{path}: no data rows after the header')
    rel, clock_notes = clock_changes(np.array([(s - start).total_seconds() for s in stamps]),
                                     start)
    notes += clock_notes
    back = np.flatnonzero(np.diff(rel) < 0)
    if len(back):
        i = back[0] + 1
        raise InputError(f'{path}: line {line_nos[i]}: time stamp {stamps[i]:%Y-%m-%d %H:%M:%S}'
                         f" is before the previous line's {stamps[i - 1]:%Y-%m-%d %H:%M:%S}")
    values = dict(zip(list(roles) + [f'flag:{f}' for f in flags], data))
    k, n, align_notes = _grid(path, rel, period, announced, line_nos, stamps)
    notes += align_notes
    start += timedelta(seconds=float(k[0]) * period)
    k = k - k[0]
    signals = {r: align.place(k, values[r], n)[0] for r in roles if r != 'mode'}
    reasons = _exclusions(values, k, n, roles, flags, signals, notes)
    source = {'path': str(path), 'format': 'historian',
              'sampling': 'the sampling period line 2 announces',
              'columns': {r: columns[i] for r, i in roles.items()},
              'descriptions': {r: descs[i].strip() for r, i in roles.items()
                               if i < len(descs) and descs[i].strip()}}
    return assemble(signals, period, reasons, notes, source=source,
                    start_time=start.isoformat(), name=tag or _stem(columns), time_origin=0.0)


def _cells(line):
    return line.split('\t')


def _strptime_format(fmt):
    out = fmt
    for token, code in TIME_TOKENS:
        out = out.replace(token, code)
    return out


def _stamp(text, pyfmt):
    try:
        return datetime.strptime(text.strip(), pyfmt)
    except ValueError:
        return None


def _line2(path, line, pyfmt, fmt):
    cells = [c.strip() for c in _cells(line)]
    try:
        period = float(cells[1])
        announced = int(cells[3])
        start = datetime.strptime(cells[2], pyfmt)
    except (IndexError, ValueError):
        raise InputError(f'{path}: line 2 must be: columns, sampling period (s), start time '
                         f'({fmt}), rows; got {line[:80]!r}') from None
    if not period > 0:
        raise InputError(f'{path}: line 2: sampling period {cells[1]!r} is not positive')
    return period, start, announced


def _roles(path, columns, tag, given):
    roles, flags, notes, ignored = {}, {}, [], []
    for signal, name in given.items():
        if signal == 't':
            notes.append('--columns t ignored: the time of a historian export is its first '
                         'column')
            continue
        hits = [i for i, c in enumerate(columns) if c.lower() == name.strip().lower()]
        if len(hits) != 1:
            raise InputError(f'{path}: --columns {signal}={name}: '
                             + ('no such tag' if not hits else f'{len(hits)} tags are so named')
                             + f' in line 3; tags: {", ".join(repr(c) for c in columns)}')
        roles[signal] = hits[0]
    for i, col in enumerate(columns):
        if i in roles.values():
            continue
        role = FLAGS.get(col.lower())
        if role is not None:
            flags[col] = i
            continue
        role = ROLES.get(col.rsplit('.', 1)[-1].upper()) if '.' in col else None
        if role is None or role in given:
            ignored.append(col)
        elif role in roles:
            raise InputError(f'{path}: line 3: two {role} columns: '
                             f'{columns[roles[role]]!r} and {col!r}; choose with --columns '
                             f'{role}={columns[roles[role]]}')
        else:
            roles[role] = i
    if 'op' not in roles:
        raise InputError(f'{path}: no controller output column ({tag or "<TAG>"}.MV) in line 3; '
                         f'columns: {", ".join(repr(c) for c in columns)}; name it with '
                         '--columns op=TAG')
    if ignored:
        notes.append('ignored columns: ' + ', '.join(ignored))
    return roles, flags, notes


def _rows(path, lines, first_row, names, pyfmt, fmt, used, notes):
    ncols = len(names)
    stamps, line_nos, data = [], [], [[] for _ in used]
    bad: dict = {}
    for no, line in enumerate(lines[first_row:], start=first_row + 1):
        if not line.strip():
            continue
        cells = _cells(line)
        while len(cells) > ncols + 1 and not cells[-1].strip():
            cells.pop()
        if len(cells) != ncols + 1:
            raise InputError(f'{path}: line {no} has {len(cells)} columns; line 3 names '
                             f'{ncols + 1} (time and {ncols} values)')
        stamp = _stamp(cells[0], pyfmt)
        if stamp is None:
            raise InputError(f'{path}: line {no}: time stamp {cells[0][:40]!r} does not match '
                             f'{fmt}')
        stamps.append(stamp)
        line_nos.append(no)
        for j, i in enumerate(used):
            text = cells[i + 1].strip()
            try:
                data[j].append(float(text) if text else np.nan)
            except ValueError:
                if text.lower() not in BAD_WORDS:
                    raise InputError(f'{path}: line {no}, column {i + 2} ({names[i]}): '
                                     f'{text[:40]!r} is not a number') from None
                # The historian's word for a value it does not have, as in a CSV.
                data[j].append(np.nan)
                words = bad.setdefault(names[i], {})
                words[text] = words.get(text, 0) + 1
    for name, words in bad.items():
        count = sum(words.values())
        notes.append(f'{name}: {count} cell' + ('s' if count > 1 else '') + ' marked bad ('
                     + ', '.join(repr(w) for w in words) + ') read as missing values')
    return stamps, line_nos, [np.array(d, dtype=np.float64) for d in data]


def _grid(path, rel, period, announced, line_nos, stamps):
    notes = []
    k = np.round(rel / period).astype(np.int64)
    rows = np.arange(len(k))
    if len(k) == announced and np.all(np.abs(k - rows) <= 1):
        step = np.round(np.diff(rel) / period)
        repeats, doubles = np.flatnonzero(step == 0), np.flatnonzero(step == 2)
        off = np.count_nonzero(k != rows)
        if off:
            first = min(np.r_[repeats, doubles]) + 1 if len(repeats) + len(doubles) else 0
            notes.append(f'time stamps repeat {len(repeats)} times and skip a sample '
                         f'{len(doubles)} times (first at line {line_nos[first]}); {off} are '
                         f'one sample off the {period:g} s grid from the start time in line 2. '
                         f'Rows taken in order as the {announced} samples line 2 announces')
        return rows, len(k), notes
    if len(k) != announced:
        notes.append(f'line 2 announces {announced} rows; the file has {len(k)}')
    if k[0] != 0:
        notes.append(f'the first row is stamped {stamps[0]:%Y-%m-%d %H:%M:%S}, not at the '
                     'start time in line 2; the record starts there')
    n = int(k[-1] - k[0]) + 1
    _, crowded, dropped, _ = align.place(k - k[0], np.zeros(len(k)), n)
    note = align.crowding_note('rows', crowded, dropped, period)
    if note:
        notes.append(note)
    gaps = n - len(np.unique(k))
    if gaps:
        notes.append(f'{gaps} sample' + ('s have' if gaps > 1 else ' has') + ' no row; '
                     'left as gaps')
    return k, n, notes


def _exclusions(values, k, n, roles, flags, signals, notes):
    reasons = {}
    set_flags = {}
    for col in flags:
        v = align.place(k, values[f'flag:{col}'], n)[0]
        # a missing flag value is no evidence of a bad value
        set_flags[col] = np.nan_to_num(v, nan=0.0) != 0
    code = np.zeros(n, dtype=np.int64)
    for i, col in enumerate(flags):
        code |= set_flags[col].astype(np.int64) << i
        sig = FLAGS[col.lower()]
        if sig in signals:
            signals[sig][set_flags[col]] = np.nan
    for c in np.unique(code[code != 0]):
        names = [col for i, col in enumerate(flags) if c >> i & 1]
        reasons['flagged bad: ' + ' '.join(names)] = code == c
    if 'mode' in roles:
        mode = align.place(k, values['mode'], n)[0]
        for m in np.unique(mode[np.isfinite(mode) & (mode != 1)]):
            reasons[f'MODE = {m:g}, not 1 (manual)'] = mode == m
        missing = ~np.isfinite(mode) & np.isfinite(align.place(k, np.zeros(len(k)), n)[0])
        if np.any(missing):
            reasons['no MODE value'] = missing
    else:
        notes.append('no MODE column: every sample taken as automatic')
    return reasons


def _stem(columns):
    return columns[0].rsplit('.', 1)[0] if columns else ''

"""
Read a CSV with a header row: ``t`` (s, increasing), ``op`` and any of ``mv``, ``pv``, ``sp``.

Column names are matched case-insensitively with spaces stripped; other
columns are ignored (with a note).  The delimiter is whichever of ``,``,
``;`` or tab the header uses.  Row numbers in messages are the file's line
numbers, as a spreadsheet shows them (the header is row 1).  An empty cell
or ``nan``/``inf`` in a signal is a missing value (NaN, noted); anything
else that is not a number is an error.
"""

import csv

import numpy as np
from stiction_ros.analysis.readers import align
from stiction_ros.analysis.record import assemble, InputError, SIGNALS


def read_csv_record(path, text):
    """Return the :class:`Record` of CSV ``text`` read from ``path``."""
    lines = [(i + 1, line) for i, line in enumerate(text.splitlines())
             if line.strip() and not line.lstrip().startswith('#')]
    if not lines:
        raise InputError(f'{path}: no header row and no data')
    head_no, head = lines[0]
    delim = max((',', ';', '\t'), key=head.count)
    header = [c.strip().lower() for c in next(csv.reader([head], delimiter=delim))]
    if all(_is_number(c) for c in header):
        raise InputError(f'{path}: no header row; line {head_no} holds numbers. The first line '
                         'must name the columns: t, op and any of mv, pv, sp')
    for name in header:
        if name and header.count(name) > 1:
            raise InputError(f'{path}: column {name!r} appears {header.count(name)} times')
    if 't' not in header:
        raise InputError(f"{path}: no 't' column (time in seconds); columns: {_names(header)}")
    if 'op' not in header:
        raise InputError(f"{path}: no 'op' column (controller output); columns: "
                         f'{_names(header)}')
    used = ['t'] + [s for s in SIGNALS if s in header]
    cols = [header.index(c) for c in used]
    ignored = [c for c in header if c not in used]
    rows = list(csv.reader([line for _, line in lines[1:]], delimiter=delim))
    if not rows:
        raise InputError(f'{path}: a header row but no data')
    data = np.empty((len(rows), len(used)))
    for r, ((no, _), cells) in enumerate(zip(lines[1:], rows)):
        if len(cells) != len(header):
            raise InputError(f'{path}: row {no} has {len(cells)} cells; the header has '
                             f'{len(header)}')
        for j, c in enumerate(cols):
            data[r, j] = _number(path, no, used[j], cells[c])
    t = data[:, 0]
    bad_t = np.flatnonzero(~np.isfinite(t))
    if len(bad_t):
        no = lines[1 + bad_t[0]][0]
        raise InputError(f'{path}: row {no}: t is {_cell(rows[bad_t[0]][cols[0]])}; every row '
                         'needs a finite time')
    back = np.flatnonzero(np.diff(t) <= 0)
    if len(back):
        r = back[0] + 1
        raise InputError(f'{path}: row {lines[1 + r][0]}: t = {t[r]:g} does not increase (row '
                         f'{lines[r][0]}: t = {t[r - 1]:g}); time must increase')
    return _on_grid(path, t, {name: data[:, j + 1] for j, name in enumerate(used[1:])}, ignored)


def _on_grid(path, t, values, ignored):
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
    notes = [note for note in [align.stray_note('t', rel, ts, center)] if note]
    if ignored:
        notes.append('ignored columns: ' + ', '.join(c or '(unnamed)' for c in ignored))
    _, crowded, dropped, _ = align.place(k, np.zeros(len(k)), n)
    crowding = align.crowding_note('rows', crowded, dropped, ts)
    if crowding:
        notes.append(crowding)
    signals = {}
    for name, v in values.items():
        bad = np.count_nonzero(~np.isfinite(v))
        if bad:
            notes.append(f'{name}: {bad} empty or non-finite cell' + ('s' if bad > 1 else '')
                         + ' read as missing values')
        signals[name] = align.place(k, v, n)[0]
    gaps = n - len(np.unique(k))
    if gaps:
        notes.append(f'{gaps} sample' + ('s have' if gaps > 1 else ' has')
                     + ' no row (a gap in t); left as gaps')
    source = {'path': str(path), 'format': 'csv', 'columns': {s: s for s in values}}
    return assemble(signals, ts, notes=notes, source=source, start_time=None,
                    name=_stem(path), time_origin=float(t[0] + center + k0 * ts))


def _number(path, no, name, cell):
    text = cell.strip()
    if not text:
        return np.nan
    try:
        return float(text)
    except ValueError:
        raise InputError(f'{path}: row {no}, column {name!r}: {_cell(cell)} is not a '
                         'number') from None


def _is_number(text):
    try:
        float(text)
    except ValueError:
        return False
    return True


def _cell(cell):
    return repr(cell if len(cell) <= 40 else cell[:37] + '...')


def _names(header):
    return ', '.join(repr(c) for c in header)


def _stem(path):
    name = str(path).replace('\\', '/').rsplit('/', 1)[-1]
    return name.rsplit('.', 1)[0] if '.' in name else name

"""
Find the time and signal columns of a CSV header as exports name them.

Time: ``t``, ``time``, ``timestamp``, ``datetime`` (``Date/Time``,
``time_stamp`` ...; German ``Zeit``, ``Zeitstempel``), any case, with an
optional unit or zone in brackets or after an underscore (``Time (s)``,
``time [ms]``, ``t_min``, ``Timestamp (UTC)``); ``date`` if nothing else,
or joined to a ``time`` column of times of day.

Signals: ``op``, ``mv``, ``pv``, ``sp`` exactly (any case, a unit in
brackets allowed; ``Setpoint`` or ``Set point`` is sp too), or a tag with
the controller block's parameter after ``.``, ``_``, ``:``, ``/``, ``-`` or
a space: ``FIC101.OP`` is op, ``FIC101.PV`` pv, ``FIC101.SP``, ``FIC101.SV``
and ``FIC101.Setpoint`` sp, ``FIC101.MV`` mv (the valve position, as in this
package) unless nothing is op: then it is the controller output, as DCS
historians name it (historian.py reads ``<TAG>.MV`` so).  An exact name
beats a tag.  Where two tags could be one signal, the one of op's tag is
taken; else the refusal names them and the ``--columns`` fix.  ``columns``
(``--columns op=FIC101.OP,t=Zeit``) overrides all of this for the signals it names.

Mode: a column named ``mode``, or the ``MODE`` of op's tag (``FIC101.MODE``),
is the controller's mode (``modes.py``); another loop's mode is not taken.
"""

from dataclasses import dataclass, field
import re
import shlex

from stiction_ros.analysis.readers.stamps import UNITS, ZONES
from stiction_ros.analysis.record import SIGNALS
from stiction_ros.errors import InputError

TIME_NAMES = ('t', 'time', 'timestamp', 'time stamp', 'datetime', 'date time', 'date and time',
              'zeit', 'zeitstempel')
# A long export names the tag of each row in one of these, its value in 'value'.
LONG_TAGS = ('tag', 'tagname', 'tag name', 'tag_name', 'name', 'point', 'pointname')
SUFFIXES = {'op': 'op', 'pv': 'pv', 'sp': 'sp', 'sv': 'sp', 'mv': 'mv', 'setpoint': 'sp'}
# Whole names that mean a signal besides its own short name.
ALIASES = {'setpoint': 'sp', 'set point': 'sp', 'set_point': 'sp', 'set-point': 'sp'}
UNIT = re.compile(r'(?P<base>.*?)\s*[\(\[](?P<unit>[^\)\]]*)[\)\]]')
TAG = re.compile(r'(?P<tag>.*\S)\s*[._:/\\ -]\s*(?P<part>[A-Za-z]+)')
# Column lists in messages stop after this many names.
LISTED = 12


@dataclass
class Columns:
    """Where the time and the signals are: header indices and what the names said."""

    time: int
    unit: str | None
    date: int | None
    signals: dict
    ignored: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    # The controller's mode (``mode``, ``FIC101.MODE``): rows not in automatic are excluded.
    mode: int | None = None


def split_unit(name: str) -> tuple[str, str | None]:
    """Return ``(base, unit)`` of a header name: ``'Time (s)'`` -> ``('time', 's')``."""
    base = ' '.join(name.strip().lower().split())
    m = UNIT.fullmatch(base)
    if m:
        return m['base'].strip(), m['unit'].strip()
    words = re.split(r'[\s_/&-]+', base)
    if len(words) > 1 and ' '.join(words[:-1]) in TIME_NAMES and \
            (words[-1] in UNITS or words[-1] in ZONES):
        return ' '.join(words[:-1]), words[-1]
    return base, None


def _time_key(base):
    return ' '.join(re.split(r'[\s_/&-]+', base))


def match_columns(path: object, header: list[str], columns: dict | None = None) -> Columns:
    """
    Return the :class:`Columns` of ``header`` (names as written, stripped).

    ``columns`` maps ``t``, ``op``, ``mv``, ``pv``, ``sp``, ``mode`` to header names
    (case ignored); the rest are found by name.  Raises :class:`InputError`
    naming the fix when a needed column is missing or ambiguous.
    """
    given = {k: _find(path, header, k, v) for k, v in (columns or {}).items()}
    keys = [split_unit(h) for h in header]
    taken = set(given.values())
    notes = []
    time, unit, date = _time_column(path, header, keys, given)
    taken.add(time)
    if date is not None:
        taken.add(date)
    found = {s: given[s] for s in SIGNALS if s in given}
    modes = [] if 'mode' not in given else [(0, given['mode'])]
    candidates = {s: [] for s in SIGNALS}
    tags = {}
    for i, (base, _) in enumerate(keys):
        if i in taken:
            continue
        if base in SIGNALS or base in ALIASES:
            candidates[ALIASES.get(base, base)].append((0, i))
            continue
        m = TAG.fullmatch(base)
        if 'mode' not in given and (base == 'mode' or (m and m['part'] == 'mode')):
            modes.append((0 if base == 'mode' else 1, i))
            if m:
                tags[i] = m['tag']
            continue
        if m and m['part'] in SUFFIXES:
            tags[i] = m['tag']
            candidates[SUFFIXES[m['part']]].append((1, i))
    _pick('op', path, header, candidates, found, tags, notes)
    if 'op' not in found and not candidates['op']:
        mvs = [i for rank, i in candidates['mv'] if rank == 1]
        if len(mvs) == 1:
            found['op'] = mvs[0]
            candidates['mv'] = [c for c in candidates['mv'] if c[1] != mvs[0]]
            notes.append(f'{header[mvs[0]]!r} read as the controller output (op), as DCS '
                         f'historians name it; if it is the valve position, pass --columns '
                         f'mv={_quote(header[mvs[0]])},op=COLUMN')
    if 'op' not in found and 'value' in [base for base, _ in keys] and \
            any(base in LONG_TAGS for base, _ in keys):
        raise InputError(f'{path}: one row per tag and time (a long export: columns '
                         f'{names(header)}); export the tags side by side, one column each '
                         '(Timestamp,FIC101.OP,FIC101.PV), and pass that file')
    if 'op' not in found:
        raise InputError(f"{path}: no 'op' column (controller output, or a tag's OP such as "
                         f'FIC101.OP); columns: {names(header)}; name it with '
                         '--columns op=COLUMN')
    for s in SIGNALS[1:]:
        _pick(s, path, header, candidates, found, tags, notes)
    mode = _pick_mode(header, modes, found, tags, notes)
    used = {time, date, mode, *found.values()}
    ignored = [h or '(unnamed)' for i, h in enumerate(header) if i not in used]
    _check_duplicates(path, header, [i for i in used if i is not None])
    return Columns(time, unit, date, found, ignored, notes, mode)


def _pick_mode(header, modes, found, tags, notes):
    """Return the mode column: given, named ``mode``, or of op's tag; None when unclear."""
    if not modes:
        return None
    best = min(rank for rank, _ in modes)
    top = [i for rank, i in modes if rank == best]
    if best == 1:
        # Another loop's mode says nothing of this one's.
        op_tag = tags.get(found['op'])
        top = [i for i in top if tags.get(i) == op_tag] if op_tag else top
    if len(top) != 1:
        notes.append('mode: ' + ('no column is the mode of ' + repr(header[found['op']])
                                 if not top else 'several columns could be the mode')
                     + ' (' + ', '.join(repr(header[i]) for _, i in modes)
                     + '); none used: name it with --columns mode=COLUMN')
        return None
    return top[0]


def _find(path, header, key, name):
    want = name.strip().lower()
    hits = [i for i, h in enumerate(header) if h.strip().lower() == want]
    if not hits:
        hits = [i for i, h in enumerate(header) if split_unit(h)[0] == split_unit(name)[0]]
    if not hits:
        raise InputError(f'{path}: --columns {key}={name}: no such column; columns: '
                         f'{names(header)}')
    if len(hits) > 1:
        raise InputError(f'{path}: --columns {key}={name}: {len(hits)} columns are named so '
                         f'(columns {", ".join(str(i + 1) for i in hits)}); rename one in the '
                         'file')
    return hits[0]


def _time_column(path, header, keys, given):
    if 't' in given:
        i = given['t']
        return i, keys[i][1], None
    named = [i for i, (base, _) in enumerate(keys)
             if _time_key(base) in TIME_NAMES and i not in given.values()]
    dates = [i for i, (base, _) in enumerate(keys)
             if base == 'date' and i not in given.values()]
    if len(named) > 1:
        _check_duplicates(path, header, named)
        raise InputError(f'{path}: {len(named)} time columns: '
                         f'{", ".join(repr(header[i]) for i in named)}; pick one with '
                         f'--columns t={_quote(header[named[0]])}')
    if named:
        i = named[0]
        # A 'date' beside a 'time' may be its other half; the reader joins them if
        # the time column holds times of day.
        date = dates[0] if len(dates) == 1 and _time_key(keys[i][0]) == 'time' else None
        return i, keys[i][1], date
    if len(dates) == 1:
        return dates[0], keys[dates[0]][1], None
    raise InputError(f'{path}: no time column (t, time or timestamp: seconds or dates); '
                     f'columns: {names(header)}; name it with --columns t=COLUMN')


def _pick(signal, path, header, candidates, found, tags, notes):
    if signal in found:
        return
    used = set(found.values())
    cands = [(rank, i) for rank, i in candidates[signal] if i not in used]
    exact = [i for rank, i in cands if rank == 0]
    tagged = [i for rank, i in cands if rank == 1]
    if exact:
        found[signal] = exact[0]
        if tagged:
            notes.append(f'{signal}: took the column named {header[exact[0]]!r}, not '
                         + ', '.join(repr(header[i]) for i in tagged))
        return
    if len(tagged) == 1:
        found[signal] = tagged[0]
        return
    if not tagged:
        return
    op_tag = tags.get(found.get('op'))
    same = [i for i in tagged if op_tag is not None and tags[i] == op_tag]
    if len(same) == 1:
        found[signal] = same[0]
        notes.append(f'{signal}: took {header[same[0]]!r}, of the same tag as op; ignored '
                     + ', '.join(repr(header[i]) for i in tagged if i != same[0]))
        return
    _check_duplicates(path, header, tagged)
    raise InputError(f'{path}: {len(tagged)} columns could be {signal}: '
                     f'{", ".join(repr(header[i]) for i in tagged)}; choose with --columns '
                     + _suggest(header, candidates, found, tags, tags[tagged[0]]))


def _suggest(header, candidates, found, tags, tag):
    pairs = []
    for s in SIGNALS:
        if s in found:
            pairs.append(f'{s}={header[found[s]]}')
            continue
        mine = [i for rank, i in candidates[s] if rank == 1 and tags[i] == tag]
        if mine:
            pairs.append(f'{s}={header[mine[0]]}')
    return _quote(','.join(pairs))


def _check_duplicates(path, header, used):
    # Only a column the analysis reads must be unique: exports repeat 'Status' per tag.
    for i in sorted(used):
        same = [j for j, h in enumerate(header) if h.strip().lower() == header[i].strip().lower()]
        if len(same) > 1:
            raise InputError(f'{path}: column {header[i].strip().lower()!r} appears '
                             f'{len(same)} times; rename the one that is not the signal, or '
                             'delete it')


def _quote(text):
    return shlex.quote(text)


def names(header: list[str]) -> str:
    """Return the header's names for a message, the first ``LISTED`` of a long one."""
    shown = ', '.join(repr(h) for h in header[:LISTED])
    return shown + (f' ... ({len(header) - LISTED} more)' if len(header) > LISTED else '')

"""
One loop recording on a uniform sample grid, whatever file it came from.

The conventions every reader follows:

- ``t[k] = k * sample_time``: seconds from the first sample of the record.
- ``signals[name][k]`` is NaN where the file holds no trustworthy value:
  no sample in that bin (a gap), a non-finite number, or a value the
  historian flagged bad.  Gaps are never interpolated.
- Samples that have good values but must not be analysed (the loop was in
  manual) keep their values, so a plot still shows them, but are not valid.
- ``valid[k]`` is True exactly when no exclusion applies at ``k`` and every
  signal present is finite there; :meth:`Record.segments` are its runs.
- ``excluded`` lists every stretch of invalid samples: ``start_s`` and
  ``end_s`` (times of its first and last sample, so equal for one sample),
  ``samples`` and ``reason``; ``notes`` says the same in words, plus
  anything else worth knowing.
"""

from dataclasses import dataclass, field
from datetime import datetime, timedelta
import math

import numpy as np

from stiction_ros.errors import InputError

SIGNALS = ('op', 'mv', 'pv', 'sp')
MIN_VALID = 10
# No instrument reads a value this large in any unit; DCS and historian exports
# write such numbers (1e30, 9.99e37, float32's 3.4e38) as codes for a bad value,
# and squaring one overflows every sum the analysis forms.
NOT_A_MEASUREMENT = 1e15
# Notes itemise up to this many stretches of one reason, then summarise.
ITEMISED = 3


@dataclass(eq=False)
class Record:
    """
    Loop signals on one uniform sample grid, with what was left out and why.

    ``source`` holds at least ``path`` and ``format``; ``time_origin`` is the
    source's own clock at sample 0 in seconds (CSV ``t``, bag stamps, sim time
    included; 0 for a historian export, whose clock is ``start_time``).
    """

    t: np.ndarray
    sample_time: float
    signals: dict
    valid: np.ndarray
    notes: list = field(default_factory=list)
    excluded: list = field(default_factory=list)
    source: dict = field(default_factory=dict)
    start_time: str | None = None
    name: str = ''
    time_origin: float = 0.0
    # Samples left out of the loop analysis whose OP and MV are still the valve's true
    # input and output (a node after the valve acted on a held input): the valve fits
    # keep them.  None: the same as ``valid``.
    valve_ok: np.ndarray = None

    @property
    def samples(self):
        """Return the number of samples on the grid."""
        return len(self.t)

    @property
    def path(self):
        """Return the source file's path as text (for messages)."""
        return str(self.source.get('path', self.name or 'record'))

    def has(self, name):
        """Return whether the record holds signal ``name`` (``op``, ``mv``, ``pv``, ``sp``)."""
        return name in self.signals

    def segments(self, min_samples=1):
        """Return half-open ``(start, stop)`` index pairs of the valid runs at least this long."""
        return [(a, b) for a, b in runs(self.valid) if b - a >= min_samples]

    def valve_segments(self, min_samples=2):
        """Return the runs the valve models are fitted on: valid, or ``valve_ok``."""
        ok = self.valid if self.valve_ok is None else self.valid | self.valve_ok
        return [(a, b) for a, b in runs(ok) if b - a >= min_samples]

    def window(self, t0=None, t1=None):
        """
        Return a new record of the samples with ``t0 <= t <= t1`` (seconds; None: open).

        Time restarts at 0; ``start_time``, ``time_origin`` and the exclusions
        move with it.  Raises :class:`InputError` if no sample is inside.
        """
        ts, n = self.sample_time, self.samples
        lo = 0 if t0 is None else max(math.ceil(t0 / ts - 1e-9), 0)
        hi = n - 1 if t1 is None else min(math.floor(t1 / ts + 1e-9), n - 1)
        if t0 is not None and t1 is not None and t1 < t0:
            raise InputError(f'{self.path}: window {t0:g} to {t1:g} s ends before it starts')
        if hi < lo:
            raise InputError(f'{self.path}: window {_span(t0, t1)} holds no sample; the record '
                             f'runs from 0 to {(n - 1) * ts:g} s')
        general = _general_notes(self)
        excluded = []
        for e in self.excluded:
            a = int(round(e['start_s'] / ts))
            b = a + e['samples']
            a, b = max(a, lo), min(b, hi + 1)
            if a < b:
                excluded.append(_stretch(a - lo, b - lo, ts, e['reason']))
        start = self.start_time
        if start is not None and lo:
            start = (datetime.fromisoformat(start) + timedelta(seconds=lo * ts)).isoformat()
        out = Record(
            t=np.arange(hi + 1 - lo) * ts, sample_time=ts,
            signals={k: v[lo:hi + 1].copy() for k, v in self.signals.items()},
            valid=self.valid[lo:hi + 1].copy(), excluded=excluded, source=dict(self.source),
            valve_ok=None if self.valve_ok is None else self.valve_ok[lo:hi + 1].copy(),
            start_time=start, name=self.name, time_origin=self.time_origin + lo * ts)
        out.notes = general + [f'window {_span(t0, t1)}: samples {lo} to {hi} of {n}']
        out.notes += exclusion_notes(excluded, ts, start)
        return out

    def to_json_summary(self):
        """Return a JSON-able dict: size, signals, valid samples, notes and exclusions."""
        segs = self.segments()
        return {
            'name': self.name, 'source': self.source, 'start_time': self.start_time,
            'sample_time': self.sample_time, 'samples': self.samples,
            'duration_s': self.samples * self.sample_time,
            'signals': [s for s in SIGNALS if s in self.signals]
            + sorted(s for s in self.signals if s not in SIGNALS),
            'valid_samples': int(np.count_nonzero(self.valid)),
            'segments': len(segs),
            'longest_segment': max((b - a for a, b in segs), default=0),
            'notes': list(self.notes), 'excluded': [dict(e) for e in self.excluded],
        }


def runs(mask):
    """Return ``(start, stop)`` pairs of the runs of True in a boolean array."""
    m = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    edges = np.flatnonzero(m[1:] != m[:-1])
    return [(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def assemble(signals, sample_time, reasons=None, notes=(), **info):
    """
    Return a :class:`Record` from aligned signals and the reasons samples are excluded.

    ``reasons`` maps a reason (words) to a boolean mask of the samples it
    excludes.  NaN not explained by any reason is reported as a missing
    value.  A value beyond +-``NOT_A_MEASUREMENT`` is no value: it is read
    as missing and excluded, with the reason.  ``info`` gives the other
    :class:`Record` fields.
    """
    signals = {k: np.asarray(v, dtype=np.float64) for k, v in signals.items()}
    reasons = dict(reasons or {})
    huge = {k: np.isfinite(v) & (np.abs(v) > NOT_A_MEASUREMENT) for k, v in signals.items()}
    if any(h.any() for h in huge.values()):
        names = ', '.join(k for k, h in huge.items() if h.any())
        reasons[f'{names} beyond +-1e15, which no instrument reads (a code for a bad value, '
                'or no measurement)'] = np.any(list(huge.values()), axis=0)
        signals = {k: np.where(huge[k], np.nan, v) for k, v in signals.items()}
    n = len(signals['op'])
    labels = list((reasons or {}).keys())
    code = np.zeros(n, dtype=np.int64)
    for i, label in enumerate(labels):
        code |= np.asarray(reasons[label], dtype=np.int64) << i
    explained = code != 0
    for j, name in enumerate(signals):
        code |= (~np.isfinite(signals[name]) & ~explained).astype(np.int64) << (len(labels) + j)
    names = list(signals)
    excluded = []
    for a, b in runs(code != 0):
        # a stretch of exclusions may change reason inside; one entry per reason
        c = code[a:b]
        cut = np.flatnonzero(np.diff(c)) + 1
        for s, e in zip(np.r_[0, cut], np.r_[cut, b - a]):
            excluded.append(_stretch(a + s, a + e, sample_time, _words(int(c[s]), labels, names)))
    notes = list(notes) + _constant_notes(signals)
    start = info.get('start_time')
    return Record(t=np.arange(n) * float(sample_time), sample_time=float(sample_time),
                  signals=signals, valid=code == 0,
                  notes=notes + exclusion_notes(excluded, sample_time, start),
                  excluded=excluded, **info)


def check_enough(record, minimum=MIN_VALID):
    """Raise :class:`InputError` unless the record has at least ``minimum`` valid samples."""
    valid = int(np.count_nonzero(record.valid))
    if valid >= minimum:
        return record
    totals = {}
    for e in record.excluded:
        totals[e['reason']] = totals.get(e['reason'], 0) + e['samples']
    top = sorted(totals.items(), key=lambda kv: -kv[1])[:2]
    why = '; '.join(f'{n} {reason}' for reason, n in top)
    raise InputError(f'{record.path}: only {valid} of {record.samples} samples are valid '
                     f'(at least {minimum} needed)' + (f'; excluded: {why}' if why else ''))


def exclusion_notes(excluded, sample_time, start_time=None):
    """Return one note per reason: how many samples, where, and why."""
    by_reason = {}
    for e in excluded:
        by_reason.setdefault(e['reason'], []).append(e)
    notes = []
    for reason, stretches in by_reason.items():
        n = sum(e['samples'] for e in stretches)
        what = f'excluded {_count(n)} ({n * sample_time:g} s)'
        if len(stretches) <= ITEMISED:
            where = ', '.join(_at(e, start_time) for e in stretches)
            notes.append(f'{what} at {where}: {reason}')
        else:
            longest = max(e['samples'] for e in stretches)
            notes.append(f'{what} in {len(stretches)} stretches (longest {_count(longest)}) '
                         f'from {_at(stretches[0], start_time)} to '
                         f'{_at(stretches[-1], start_time)}: {reason}')
    return notes


def _general_notes(record):
    mine = set(exclusion_notes(record.excluded, record.sample_time, record.start_time))
    return [n for n in record.notes if n not in mine]


def _constant_notes(signals):
    notes = []
    for name, v in signals.items():
        if name == 'sp':
            continue  # a constant set point is the usual case, not news
        good = v[np.isfinite(v)]
        if len(good) > 1 and np.all(good == good[0]):
            notes.append(f'{name} is constant ({good[0]:.7g}) over the whole record')
    return notes


def _words(code, labels, names):
    said = [labels[i] for i in range(len(labels)) if code >> i & 1]
    missing = [n for j, n in enumerate(names) if code >> (len(labels) + j) & 1]
    if missing:
        said.append(f'no {", ".join(missing)} value')
    return '; '.join(said)


def _stretch(a, b, ts, reason):
    return {'start_s': float(a * ts), 'end_s': float((b - 1) * ts), 'samples': int(b - a),
            'reason': reason}


def _at(e, start_time):
    where = f't = {e["start_s"]:g} s'
    if e['samples'] > 1:
        where = f't = {e["start_s"]:g} to {e["end_s"]:g} s'
    if start_time is None:
        return where
    when = datetime.fromisoformat(start_time) + timedelta(seconds=e['start_s'])
    return f'{where} ({when.strftime("%Y-%m-%d %H:%M:%S")})'


def _count(n):
    return f'{n} sample' + ('' if n == 1 else 's')


def _span(t0, t1):
    return f'{"start" if t0 is None else f"{t0:g}"} to {"end" if t1 is None else f"{t1:g} s"}'

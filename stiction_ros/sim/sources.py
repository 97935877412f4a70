"""
Signal sources: set-point profiles and open-loop valve inputs.

A source is called with increasing times and returns a value; build one from a
config mapping with :func:`make_source`, e.g. ``{'type': 'sine', 'offset': 50,
'amplitude': 10, 'period': 200}``.
"""

import csv
import difflib
import inspect
import math

import numpy as np

from stiction_ros.errors import SourceError
from stiction_ros.models.base import check_finite


class Source:
    """Base of the sources: ``sample`` evaluates a whole time array at once."""

    def sample(self, times):
        """Return the values at the increasing ``times``, as calls one by one would."""
        return np.array([self(t) for t in times], dtype=np.float64)


class Constant(Source):
    """A fixed value."""

    def __init__(self, value=0.0):
        self.value = check_finite('value', value)

    def __call__(self, t):
        return self.value

    def sample(self, times):
        """Return the value at every time."""
        return np.full(len(times), self.value)


class Steps(Source):
    """Piecewise constant: ``steps = [[t0, v0], [t1, v1], ...]``; v0 before t0 too."""

    def __init__(self, steps):
        try:
            pts = sorted((float(t), float(v)) for t, v in steps)
        except (TypeError, ValueError):
            raise SourceError('steps must be a list of [time, value] pairs') from None
        if not pts or not all(math.isfinite(t) and math.isfinite(v) for t, v in pts):
            raise SourceError('steps must be a non-empty list of finite [time, value] pairs')
        self.times = np.array([p[0] for p in pts])
        self.values = np.array([p[1] for p in pts])

    def __call__(self, t):
        i = int(np.searchsorted(self.times, t + 1e-12, side='right')) - 1
        return float(self.values[max(i, 0)])

    def sample(self, times):
        """Return the held values at every time."""
        i = np.searchsorted(self.times, np.asarray(times) + 1e-12, side='right') - 1
        return self.values[np.maximum(i, 0)]


class Sine(Source):
    """``offset + amplitude sin(2 pi t / period + phase)``."""

    def __init__(self, offset=50.0, amplitude=10.0, period=100.0, phase=0.0):
        self.offset = check_finite('offset', offset)
        self.amplitude = check_finite('amplitude', amplitude)
        self.period = check_finite('period', period, 1e-12)
        self.phase = check_finite('phase', phase)

    def __call__(self, t):
        return self.offset + self.amplitude * math.sin(2 * math.pi * t / self.period + self.phase)

    def sample(self, times):
        """Return the wave at every time (the same expression, element-wise)."""
        t = np.asarray(times, dtype=np.float64)
        return self.offset + self.amplitude * np.sin(2 * math.pi * t / self.period + self.phase)


def triangle_wave(phase):
    """Return a unit triangle wave in step with ``sin(phase)``: 0 at 0, 1 at pi/2."""
    x = (np.asarray(phase) / (2 * np.pi) + 0.25) % 1.0
    return 1.0 - 4.0 * np.abs(x - 0.5)


class Triangle(Sine):
    """A symmetric triangle wave with the same parameters as :class:`Sine`."""

    def __call__(self, t):
        return self.offset + self.amplitude * float(
            triangle_wave(2 * math.pi * t / self.period + self.phase))

    def sample(self, times):
        """Return the wave at every time (the same expression, element-wise)."""
        t = np.asarray(times, dtype=np.float64)
        return self.offset + self.amplitude * triangle_wave(2 * math.pi * t / self.period
                                                            + self.phase)


class RandomWalk(Source):
    """A bounded Gaussian random walk, one increment of ``std`` per call; seeded."""

    def __init__(self, offset=50.0, std=0.5, low=0.0, high=100.0, seed=0):
        self.value = check_finite('offset', offset)
        self.std = check_finite('std', std, 0.0)
        self.low = check_finite('low', low)
        self.high = check_finite('high', high)
        if self.low >= self.high:
            raise SourceError(f'low ({low}) must be below high ({high})')
        self._rng = np.random.default_rng(seed)
        self._first = True

    def __call__(self, t):
        if not self._first:
            v = self.value + self.std * self._rng.standard_normal()
            # Reflect at the bounds so the walk keeps its spread.
            if v > self.high:
                v = 2 * self.high - v
            if v < self.low:
                v = 2 * self.low - v
            self.value = min(max(v, self.low), self.high)
        self._first = False
        return self.value


class Replay(Steps):
    """Replays column ``column`` of a CSV file against its ``time_column``, held between rows."""

    def __init__(self, file, column='op', time_column='t'):
        try:
            with open(file, newline='', encoding='utf-8') as f:
                rows = list(csv.DictReader(f))
        except OSError as err:
            raise SourceError(f'replay file {file!r}: {err.strerror}') from None
        if not rows:
            raise SourceError(f'replay file {file!r} has no data rows')
        for key in (column, time_column):
            if key not in rows[0]:
                raise SourceError(
                    f'replay file {file!r} has no column {key!r}; columns: {list(rows[0])}')
        pts = []
        for n, row in enumerate(rows, start=2):
            try:
                pts.append((float(row[time_column]), float(row[column])))
            except (TypeError, ValueError):
                raise SourceError(f'replay file {file!r} line {n}: not a number') from None
        super().__init__(pts)


SOURCES = {'constant': Constant, 'steps': Steps, 'sine': Sine, 'triangle': Triangle,
           'random_walk': RandomWalk, 'replay': Replay}


def make_source(spec, where='source'):
    """Build a source from a mapping with a ``type`` key; errors name ``where``."""
    if isinstance(spec, (int, float)):
        return Constant(spec)
    if not isinstance(spec, dict) or 'type' not in spec:
        raise SourceError(f"{where}: expected a number or a mapping with a 'type' key "
                          f'({", ".join(SOURCES)}), got {spec!r}')
    kind = spec['type']
    if kind not in SOURCES:
        hint = difflib.get_close_matches(str(kind), SOURCES, n=1)
        raise SourceError(f'{where}.type: unknown {kind!r}'
                          + (f"; did you mean '{hint[0]}'?" if hint else
                             f'; choose one of {list(SOURCES)}'))
    cls = SOURCES[kind]
    kwargs = {k: v for k, v in spec.items() if k != 'type'}
    allowed = [p for p in inspect.signature(cls.__init__).parameters if p != 'self']
    for key in kwargs:
        if key not in allowed:
            hint = difflib.get_close_matches(key, allowed, n=1)
            raise SourceError(f'{where}.{key}: unknown key for a {kind} source'
                              + (f"; did you mean '{hint[0]}'?" if hint else
                                 f'; valid keys: {allowed}'))
    try:
        return cls(**kwargs)
    except (TypeError, ValueError) as err:
        raise SourceError(f'{where}: {err}') from None

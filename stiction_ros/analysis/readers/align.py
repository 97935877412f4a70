"""
Put time-stamped values on one uniform sample grid.

The period is found where the stamps' phases agree best (a search around
the median spacing, narrowed on ever longer prefixes), then polished by least
squares and rounded to the shortest decimal the data cannot tell from it;
so gaps, jitter and a slightly fast clock do not drift off the grid over a
long record.  The grid's phase is the circular mean of the stamps' phases.
A stamp belongs to the nearest grid instant.  Two values in one bin: the
last wins.  A bin without a value stays NaN, never interpolated.

Rows that do not sit on one grid (a historian's raw values, stored when they
change or compressed; a logger's jittered rows) are resampled instead
(:func:`resample_period`, :func:`interpolate`): between two stored values
the value is interpolated linearly, as the historian's own interpolated
retrieval does.  Linear, not held: a compressing historian (swinging door)
stores exactly the points between which a straight line stays within its
deviation of the signal, and holding each value would draw steps into a
smooth OP, the stick-slip signature the analysis looks for.  A value marked
bad, or a silence longer than a historian leaves a live value unstored, is
never bridged.
"""

import numpy as np

from stiction_ros.errors import GridError

# The fitted period is replaced by the shortest decimal (1.0, not 0.99998)
# that the fit cannot tell from it, or that moves no stamp by more than this
# fraction of a sample over the record.
SNAP = 0.05
# Stamps further than this fraction of a sample from the grid get a warning.
STRAY = 0.3


def sample_period(t):
    """Return the sample period (s) of increasing stamps ``t`` (s)."""
    t = np.asarray(t, dtype=np.float64) - t[0]
    d = np.diff(t)
    d = d[d > 0]
    if not len(d):
        raise GridError('fewer than two distinct time stamps')
    ts = _coherent_period(t, float(np.median(d)))
    # Polish: with the index of every stamp now certain, least squares.
    k = np.round(t / ts - phase(t, ts))
    slope, at0 = np.polyfit(k, t, 1)
    res = t - (slope * k + at0)
    spread = float(np.sqrt(np.sum(res ** 2) / max(len(k) - 2, 1) / np.sum((k - k.mean()) ** 2)))
    ts = float(slope)
    samples = max(t[-1] / ts, 1.0)
    # Within the fit's own uncertainty, but never drifting a quarter sample.
    tol = min(max(SNAP * ts / samples, 3 * spread), 0.25 * ts / samples)
    for digits in range(1, 10):
        snapped = float(f'{ts:.{digits}g}')
        if abs(snapped - ts) <= tol:
            return snapped
    return ts


def _coherent_period(t, ts):
    # The period at which the stamps' phases agree best, searched on ever
    # longer prefixes so that the search stays narrow: robust to jitter and
    # gaps, where fitting rounded indices is not.
    m, width, points = min(len(t), 256), 0.05 * ts, 257
    while True:
        part = t[:m]
        trial = ts + np.linspace(-width, width, points)
        power = [abs(np.exp(2j * np.pi / p * part).sum()) for p in trial]
        ts = float(trial[int(np.argmax(power))])
        if m >= len(t):
            return ts
        m = min(2 * m, len(t))
        width, points = 2 * ts * ts / max(t[m - 1], ts), 33


def phase(t, ts):
    """Return the circular mean of ``t / ts`` modulo 1, in [-0.5, 0.5)."""
    z = np.mean(np.exp(2j * np.pi * (np.asarray(t, dtype=np.float64) / ts)))
    if abs(z) < 1e-9:
        return 0.0
    ph = float(np.angle(z) / (2 * np.pi))
    # rounded so that exact stamps give an exact phase (0.25, not 0.2500000000001)
    ph = round((ph + 0.5) % 1.0 - 0.5, 9) + 0.0
    return ph - 1.0 if ph >= 0.5 else ph


def bins(t, ts, center):
    """Return the grid index of each stamp: the nearest ``center + k ts`` (ties: later)."""
    return np.floor((np.asarray(t, dtype=np.float64) - center) / ts + 0.5 + 1e-9).astype(np.int64)


def place(k, values, n):
    """
    Return ``(grid, crowded, dropped, outside)`` for values at grid indices ``k``.

    ``k`` must be in time order.  ``grid`` has ``n`` samples, NaN where no
    value fell; ``crowded`` lists the indices that got more than one value
    (the last is kept), ``dropped`` counts the values that lost, ``outside``
    those beyond ``[0, n)``.
    """
    k = np.asarray(k, dtype=np.int64)
    values = np.asarray(values, dtype=np.float64)
    inside = (k >= 0) & (k < n)
    kk, vv = k[inside], values[inside]
    keep = np.append(kk[1:] != kk[:-1], True) if len(kk) else np.zeros(0, bool)
    grid = np.full(n, np.nan)
    grid[kk[keep]] = vv[keep]
    crowded = np.unique(kk[~keep])
    return grid, crowded, int(np.count_nonzero(~keep)), int(np.count_nonzero(~inside))


def stray_note(name, t, ts, center):
    """Return a warning if stamps ``t`` stray far from the grid ``center + k ts``, or None."""
    stray = off_grid(t, ts, center)
    if stray <= STRAY:
        return None
    return (f'{name} stamps stray up to {stray:.0%} of a sample from the {ts:g} s grid; '
            'which sample a value belongs to is uncertain')


def crowding_note(name, crowded, dropped, ts):
    """Return the note for samples that received more than one value, or None."""
    if not len(crowded):
        return None
    return (f'{name}: {len(crowded)} sample' + ('s' if len(crowded) > 1 else '')
            + f' held more than one value (first at t = {crowded[0] * ts:g} s); '
            f'kept the last, dropped {dropped}')


# ---- rows that do not sit on one grid: stored on change, compressed, or jittered ----------

# A historian stores a value at least this often even when it has not changed (the
# exception maximum, 600 s by default in OSIsoft PI), so a longer silence between two
# stored values is data that is missing, not a value that held.
BRIDGE_S = 600.0
# ... and never fewer samples than this, for slow records.
BRIDGE_SAMPLES = 10
# The stamps' common step is the grid when a median interval holds at most this many
# steps; a finer step is the stamps' resolution (milliseconds), not a scan.
STEPS_PER_MEDIAN = 20


def off_grid(t, ts, center):
    """Return the farthest the stamps ``t`` stray from the grid ``center + k ts``, in samples."""
    off = (np.asarray(t, dtype=np.float64) - center) / ts
    return float(np.max(np.abs(off - np.round(off)))) if len(off) else 0.0


def resample_period(t):
    """
    Return ``(period, why)`` for stamps ``t`` (s, increasing) that are not on one grid.

    The period is the step every stamp is a whole multiple of (a scan the
    historian stored on change or compressed) if a median interval spans at
    most ``STEPS_PER_MEDIAN`` of them; else the median interval itself, to
    two significant digits (jittered rows).  ``why`` says which, in words.
    """
    d = np.diff(np.asarray(t, dtype=np.float64))
    d = d[d > 0]
    if not len(d):
        raise GridError('fewer than two distinct time stamps')
    median = float(np.median(d))
    step = 0.0
    if d.max() < 1e12:
        # Stamps are written to a few decimals; microseconds are below any of them.
        step = float(np.gcd.reduce(np.round(d * 1e6).astype(np.int64))) / 1e6
    if step > 0 and median / step <= STEPS_PER_MEDIAN:
        return step, (f'the scan every stamp falls on (rows stored on change; median '
                      f'interval {median:g} s)')
    ts = float(f'{median:.2g}')
    return ts, f'the median interval between rows ({median:.4g} s) to two digits'


def interpolate(t, v, grid, longest):
    """
    Return ``(values, long_gaps)``: ``v`` at stamps ``t`` read at the instants ``grid``.

    Between two stored values the value is interpolated linearly, as a
    historian's interpolated retrieval does.  NaN in ``v`` is a value the
    source marked bad: no line is drawn to or from it.  Instants before the
    first or after the last value, and inside an interval longer than
    ``longest`` seconds, stay NaN; ``long_gaps`` lists those intervals as
    ``(start, length)`` pairs, in seconds.
    """
    t = np.asarray(t, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    grid = np.asarray(grid, dtype=np.float64)
    out = np.full(len(grid), np.nan)
    if not len(t):
        return out, []
    # The stored value whose interval holds each instant: t[i] <= g < t[i + 1].
    i = np.searchsorted(t, grid, side='right') - 1
    ic = np.clip(i, 0, len(t) - 1)
    nx = np.minimum(ic + 1, len(t) - 1)
    on = (i >= 0) & (grid - t[ic] <= 1e-9 * max(float(np.max(np.abs(t))), 1.0))
    span = t[nx] - t[ic]
    between = ((i >= 0) & (i < len(t) - 1) & ~on & (span <= longest)
               & np.isfinite(v[ic]) & np.isfinite(v[nx]))
    lo, hi, at = v[ic][between], v[nx][between], grid[between]
    out[between] = lo + (at - t[ic][between]) / span[between] * (hi - lo)
    out[on] = v[ic][on]
    gaps = np.flatnonzero((np.diff(t) > longest) & np.isfinite(v[:-1]) & np.isfinite(v[1:]))
    return out, [(float(t[g]), float(t[g + 1] - t[g])) for g in gaps]

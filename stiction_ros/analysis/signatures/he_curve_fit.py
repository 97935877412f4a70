"""
He's curve-fitting stiction index: is each half-cycle closer to a sine or a triangle.

He, Q.P., Wang, J., Pottmann, M., Qin, S.J. (2007), A curve fitting method for
detecting valve stiction in oscillating control loops, Industrial &
Engineering Chemistry Research 46(13), 4549-4560.

A sticky valve in a self-regulating loop under PI control makes OP ramp while
the valve is stuck (a triangle); in an integrating loop the same shows in PV.
Without stiction both are closer to a sine.  The signal (OP, or PV when
``integrating``) is detrended and cut into half-cycles at its zero crossings
(with a hysteresis of 0.2 standard deviations so noise does not add
crossings).  Each half-cycle is fitted by least squares with

* a sinusoid ``a cos(w (t - tm)) + b sin(w (t - tm)) + c`` with the frequency
  ``w`` free (grid search, then a finer grid around the best), and
* a triangle: two straight lines joined at a free peak time (grid search over
  the peak position), continuous, with free start, peak and end values,

four parameters each.  Summed over all half-cycles, ``MSE_sine`` and
``MSE_tri`` give the stiction index ``SI = MSE_sine / (MSE_sine + MSE_tri)``;
the paper's rule: SI <= 0.4 no stiction, SI >= 0.6 stiction, otherwise
undetermined.  Noise adds equally to both errors and pulls SI towards 0.5.
"""

import functools

import numpy as np

from stiction_ros.analysis.oscillation import detrend
from stiction_ros.analysis.signatures.result import Signature

REFERENCE = ('He, Q.P., Wang, J., Pottmann, M., Qin, S.J. (2007), A curve fitting method for '
             'detecting valve stiction in oscillating control loops, Ind. Eng. Chem. Res. 46, '
             '4549-4560')
STICTION_SI = 0.6
NO_STICTION_SI = 0.4
MIN_SEGMENT = 6
MAX_PEAKS = 60
CACHE_MAX_LENGTH = 400


def half_cycles(x, hysteresis):
    """Return sample indices where ``x`` crosses zero after leaving the opposite band."""
    edges = []
    state = 0
    for k in np.flatnonzero(np.abs(x) > hysteresis):
        side = 1 if x[k] > 0 else -1
        if side != state:
            if state != 0:
                # The crossing is the last sign change before x left the band.
                back = k
                while back > 0 and np.sign(x[back - 1]) == side:
                    back -= 1
                edges.append(back)
            state = side
    return np.array(edges, dtype=int)


def _candidates(kind, m, lo, hi, count):
    """Return (bases G x m x 3, inverse Gram matrices G x 3 x 3, grid) of one search stage."""
    if m <= CACHE_MAX_LENGTH:
        return _cached_candidates(kind, m, lo, hi, count)
    return _make_candidates(kind, m, lo, hi, count)


def _make_candidates(kind, m, lo, hi, count):
    grid = np.linspace(lo, hi, count)
    if kind == 'sine':
        ph = grid[:, None] * (np.arange(m) - (m - 1) / 2.0)[None, :]
        bases = np.stack([np.cos(ph), np.sin(ph), np.ones_like(ph)], axis=2)
    else:
        s = np.arange(m, dtype=np.float64)[None, :]
        p = grid[:, None]
        rise = np.clip(s / p, 0.0, 1.0)
        fall = np.clip((s - p) / (m - 1 - p), 0.0, 1.0)
        # Hat functions of the start, peak and end values of the two lines.
        bases = np.stack([1.0 - rise, rise - fall, fall], axis=2)
    gram = np.einsum('gmi,gmj->gij', bases, bases) + 1e-12 * np.eye(3)
    return bases, np.linalg.inv(gram), grid


# Half-cycles of one record have only a few distinct lengths, so their bases repeat.
_cached_candidates = functools.lru_cache(maxsize=256)(_make_candidates)


def _search(kind, y, lo, hi, count, fine):
    """Return (sse, fitted): a coarse grid search over the shape parameter, then a finer one."""
    m = len(y)
    for n in (count, fine):
        bases, inv, grid = _candidates(kind, m, lo, hi, n)
        rhs = np.einsum('gmi,m->gi', bases, y)
        coef = np.einsum('gij,gj->gi', inv, rhs)
        best = int(np.argmax(np.einsum('gi,gi->g', coef, rhs)))
        step = (hi - lo) / (n - 1)
        lo, hi = grid[best] - step, grid[best] + step
        if kind == 'triangle':
            lo, hi = max(lo, 0.5), min(hi, m - 1.5)
    fit = bases[best] @ coef[best]
    return float(((fit - y) ** 2).sum()), fit


def fit_sine(y):
    """Return (sse, fitted) of the best sinusoid with free frequency on one half-cycle."""
    w0 = np.pi / len(y)
    return _search('sine', y, 0.4 * w0, 2.0 * w0, 33, 21)


def fit_triangle(y):
    """Return (sse, fitted) of the best two-line fit with a free peak on one half-cycle."""
    m = len(y)
    return _search('triangle', y, 1.0, m - 2.0, min(m - 2, MAX_PEAKS), 11)


def he_curve_fit(op, pv, sample_time, integrating=False, period_s=None):
    """
    Return He's stiction index on OP (self-regulating) or PV (integrating).

    ``period_s``, when known, rejects half-cycles shorter than a quarter or
    longer than a whole period (noise glitches, pauses in the oscillation).
    """
    which = 'pv' if integrating else 'op'
    x = detrend(pv if integrating else op)
    edges = half_cycles(x, 0.2 * x.std()) if x.std() > 0 else np.array([], dtype=int)
    lo, hi = MIN_SEGMENT, len(x)
    if period_s:
        half = 0.5 * period_s / sample_time
        lo, hi = max(lo, 0.5 * half), 2.0 * half
    sse_sine = sse_tri = 0.0
    used = 0
    t_fit, y_sine, y_tri = [], [], []
    for a, b in zip(edges[:-1], edges[1:]):
        if not lo <= b - a <= hi:
            continue
        y = x[a:b]
        e_s, f_s = fit_sine(y)
        e_t, f_t = fit_triangle(y)
        sse_sine += e_s
        sse_tri += e_t
        used += 1
        t_fit.append(np.arange(a, b) * sample_time)
        y_sine.append(f_s)
        y_tri.append(f_t)
    details = {'signal': which, 'half_cycles': used}
    if used < 2 or sse_sine + sse_tri == 0:
        return Signature('he_curve_fit', None, STICTION_SI, None,
                         f'{used} usable half-cycles in {which}; at least 2 needed',
                         REFERENCE, details)
    n = sum(len(t) for t in t_fit)
    si = sse_sine / (sse_sine + sse_tri)
    details.update(mse_sine=sse_sine / n, mse_triangle=sse_tri / n,
                   no_stiction_below=NO_STICTION_SI)
    curves = {'t': np.arange(len(x)) * sample_time, 'x': x, 't_fit': np.concatenate(t_fit),
              'sine': np.concatenate(y_sine), 'triangle': np.concatenate(y_tri),
              'starts_s': np.array([t[0] for t in t_fit]), 'signal': which}
    if si >= STICTION_SI:
        verdict, reason = True, f'{which} triangular: SI = {si:.2f} >= {STICTION_SI}'
    elif si <= NO_STICTION_SI:
        verdict, reason = False, f'{which} sinusoidal: SI = {si:.2f} <= {NO_STICTION_SI}'
    else:
        verdict, reason = None, (f'{which} neither: {NO_STICTION_SI} < SI = {si:.2f} < '
                                 f'{STICTION_SI}')
    return Signature('he_curve_fit', float(si), STICTION_SI, verdict, reason, REFERENCE,
                     details, curves)

"""
Yamashita's qualitative-shape stiction index: OP moves while the valve does not.

Yamashita (2006), "An automatic method for detection of valve stiction in
process control loops", Control Engineering Practice 14, 503-510.  Each
sample of OP and of the valve's effect is turned into a symbol, I
(increasing), D (decreasing) or S (steady); a sticky valve spends long
stretches in the pairs IS and DS (OP changes, the valve stays).  The index

    rho = (n_IS + n_DS) / (n - n_SS)

is the share of the informative samples (not both steady) in those pairs;
rho > 0.25 indicates stiction.  It needs no oscillation, which suits
records of slow stick-slip events.

Without a valve position the valve's effect is PV for a self-regulating
(flow) loop and the rate of change of PV for an integrating (level) loop.
Both signals are smoothed with a centred moving average of ``SMOOTH``
samples before differencing, and a change counts as steady when it is below
``STEADY_SIGMAS`` standard deviations of the noise of the differenced signal,
estimated from the residual of the smoothing.  These two settings are ours
(the paper leaves the noise treatment to the user); they were chosen on
simulated loops, not on the plant records.
"""

import numpy as np

from stiction_ros.analysis.signatures.result import Signature

REFERENCE = ('Yamashita (2006), Control Engineering Practice 14, 503-510: '
             'qualitative shape analysis of the OP-valve map')
THRESHOLD = 0.25
SMOOTH = 5
STEADY_SIGMAS = 2.0


def _smooth(x, w):
    pad = w // 2
    xp = np.pad(x, pad, mode='edge')
    return np.convolve(xp, np.ones(w) / w, mode='valid')[: len(x)]


def symbols(x, w=SMOOTH, sigmas=STEADY_SIGMAS):
    """Return +1 (I), -1 (D) or 0 (S) per sample increment of ``x``."""
    x = np.asarray(x, dtype=np.float64)
    s = _smooth(x, w)
    noise = np.std(x - s) * np.sqrt(w / (w - 1.0))
    # Differencing a w-sample mean leaves about sqrt(2 / w) of the noise.
    band = sigmas * noise * np.sqrt(2.0 / w)
    d = np.diff(s)
    out = np.zeros(len(d), dtype=np.int8)
    out[d > band] = 1
    out[d < -band] = -1
    return out


def yamashita(op, pv, sample_time, integrating=False):
    """Return the :class:`Signature` of Yamashita's index on OP and PV."""
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    effect = np.diff(pv) if integrating else pv
    u = symbols(op[1:] if integrating else op)
    y = symbols(effect)
    n = len(u)
    both_steady = int(np.sum((u == 0) & (y == 0)))
    stuck = int(np.sum((u != 0) & (y == 0)))
    informative = n - both_steady
    if n < 20 or informative < 10:
        return Signature('yamashita', None, THRESHOLD, None,
                         'too few samples where OP or the valve moves', REFERENCE,
                         {'informative_samples': informative})
    rho = stuck / informative
    flag = rho > THRESHOLD
    what = 'dPV/dt' if integrating else 'PV'
    return Signature(
        'yamashita', float(rho), THRESHOLD, bool(flag),
        f'OP moved while {what} stayed in {stuck} of {informative} informative samples '
        f'(rho {rho:.2f} {">" if flag else "<="} {THRESHOLD})', REFERENCE,
        {'stuck_samples': stuck, 'informative_samples': informative,
         'both_steady': both_steady, 'smooth': SMOOTH, 'steady_sigmas': STEADY_SIGMAS},
        {'op_symbols': u, 'valve_symbols': y})

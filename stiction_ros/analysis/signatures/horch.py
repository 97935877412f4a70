"""
Horch's cross-correlation test between controller output and process value.

Horch, A. (1999), A simple method for detection of stiction in control valves,
Control Engineering Practice 7(10), 1221-1231.

In a self-regulating loop that oscillates because of valve stiction, the
cross-correlation function (CCF) of OP and PV is odd (zero near lag 0,
extremes of opposite sign symmetric about it); an oscillation from an
external disturbance or aggressive tuning gives an even CCF (an extreme at
lag 0).  The paper decides by eye; the automatic rule used here is the one
Horch gives in his thesis (Condition monitoring of control loops, KTH, 2000)
and the benchmark of Jelali and Huang (eds., Detection and Diagnosis of
Stiction in Control Loops, Springer 2010): with ``tau_l < 0 < tau_r`` the
zero crossings of the CCF nearest lag 0,

    dphi = pi (tau_r + tau_l) / (tau_r - tau_l),

``|dphi| >= 2 pi / 3`` (120 deg) means stiction, ``|dphi| <= pi / 3``
(60 deg) means no stiction, anything between is undetermined.  For a
sinusoidal CCF ``cos(w tau - phi)``, ``|dphi| = 2 |phi|``: 0 for an even CCF
and pi for an odd one.

The test does not apply to integrating processes (level loops), where a
stuck valve also gives an odd CCF; ``horch`` then returns stiction=None.
"""

import math

import numpy as np

from stiction_ros.analysis.oscillation import detrend, zero_crossings
from stiction_ros.analysis.signatures.result import Signature

REFERENCE = ('Horch, A. (1999), A simple method for detection of stiction in control valves, '
             'Control Engineering Practice 7, 1221-1231')
STICTION_DEG = 120.0
NO_STICTION_DEG = 60.0


def cross_correlation(op, pv, max_lag):
    """
    Return (lags, ccf): normalised ``r(k) = sum u(t) y(t+k) / (N su sy)``, |k| <= max_lag.

    ``u``, ``y`` are detrended OP and PV; a positive lag means PV after OP.
    """
    u, y = detrend(op), detrend(pv)
    n = len(u)
    scale = n * u.std() * y.std()
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    full = np.fft.irfft(np.conj(np.fft.rfft(u, nfft)) * np.fft.rfft(y, nfft), nfft)
    lags = np.arange(-max_lag, max_lag + 1)
    ccf = full[lags % nfft] / scale if scale > 0 else np.zeros(lags.shape)
    return lags, ccf


def horch(op, pv, sample_time, integrating=False, max_lag=None):
    """
    Return Horch's cross-correlation signature of a self-regulating loop.

    ``value`` is |dphi| in degrees, ``threshold`` the stiction bound (120);
    ``max_lag`` (samples) bounds the search for zero crossings, by default
    half the record.
    """
    if integrating:
        return Signature('horch', None, STICTION_DEG, None,
                         'not applicable to integrating processes (Horch 1999 covers '
                         'self-regulating loops)', REFERENCE)
    n = len(op)
    if len(pv) != n or n < 8:
        raise ValueError('op and pv must have the same length, at least 8 samples')
    max_lag = int(max_lag or n // 2)
    lags, ccf = cross_correlation(op, pv, max_lag)
    curves = {'lag_s': lags * sample_time, 'ccf': ccf}
    zc = zero_crossings(ccf) - max_lag
    right, left = zc[zc > 0], zc[zc <= 0]
    if len(right) == 0 or len(left) == 0:
        return Signature('horch', None, STICTION_DEG, None,
                         f'CCF has no zero crossing on both sides within {max_lag} lags',
                         REFERENCE, curves=curves)
    tau_r, tau_l = float(right[0]), float(left[-1])
    dphi = math.pi * (tau_r + tau_l) / (tau_r - tau_l)
    value = abs(math.degrees(dphi))
    centre = ccf[max_lag]
    details = {'tau_l_s': tau_l * sample_time, 'tau_r_s': tau_r * sample_time,
               'dphi_deg': math.degrees(dphi), 'ccf_at_lag0': float(centre),
               'ccf_max_abs': float(np.abs(ccf).max()), 'no_stiction_below_deg': NO_STICTION_DEG}
    curves.update(tau_l_s=tau_l * sample_time, tau_r_s=tau_r * sample_time)
    if value >= STICTION_DEG:
        verdict, reason = True, f'odd CCF: |dphi| = {value:.0f} deg >= {STICTION_DEG:.0f}'
    elif value <= NO_STICTION_DEG:
        verdict, reason = False, f'even CCF: |dphi| = {value:.0f} deg <= {NO_STICTION_DEG:.0f}'
    else:
        verdict, reason = None, (f'CCF neither odd nor even: {NO_STICTION_DEG:.0f} < |dphi| = '
                                 f'{value:.0f} < {STICTION_DEG:.0f} deg')
    return Signature('horch', value, STICTION_DEG, verdict, reason, REFERENCE, details, curves)

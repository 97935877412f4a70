"""
Higher-order-statistics nonlinearity test on the control error, by squared bicoherence.

Choudhury, M.A.A.S., Shah, S.L., Thornhill, N.F. (2004), Diagnosis of poor
control-loop performance using higher-order statistics, Automatica 40(10),
1719-1728; and the book of the same authors, Diagnosis of Process
Nonlinearities and Valve Stiction, Springer (2008).

Squared bicoherence (Kim and Powers normalisation, bounded by 1)::

    bic2(f1, f2) = |E[X(f1) X(f2) X*(f1+f2)]|^2
                   / (E[|X(f1) X(f2)|^2] E[|X(f1+f2)|^2])

estimated by the direct method: K segments of M samples, 50 % overlap, each
detrended and Hann-windowed, expectations as averages over segments, over
the principal domain ``0 < f2 <= f1``, ``f1 + f2 <= fs/2`` (L bifrequencies,
DC left out).  Indices as defined in the Automatica paper:

* NGI = mean(bic2) - c / (2 K L), c the (1 - alpha) quantile of the central
  chi-square distribution with 2L degrees of freedom, alpha = 0.05 (under
  the Gaussian null each ``2 K bic2`` is chi-square with 2 dof, so their sum
  over L bifrequencies has 2L).  NGI > 0: non-Gaussian.
* NLI = |max(bic2) - (mean(bic2) + 2 std(bic2))|.  NLI > 0: nonlinear.

With the practical margins of the book, the signal is non-Gaussian when
NGI > 0.001 and nonlinear when also NLI > 0.01.  TNLI, the sum of the bic2
values above their own 2-dof significance level c2 / (2 K), is reported as
well (the book's total nonlinearity index).

Segment length and band: the paper uses M = 128 (4096 samples, K = 63);
without a known period M = 128 is kept when that gives at least 20
segments, else M = 64 (at least 8 segments are required).  When the
oscillation period is known the error is first decimated (the FIR
anti-aliasing of ``scipy.signal.resample_poly``, see :mod:`dsp`) to about
16 to 32 samples per period and M = 64, so each segment holds 2 to 4 cycles and the fundamental
and its harmonics up to the new Nyquist frequency stay in the band while
the noise-only high frequencies, which would dilute the mean of bic2, are
cut.  This band-limiting replaces the book's Wiener filter.

Limits, measured here: on Gaussian noise the test (with the margins)
calls about 5 % of 4096-sample records nonlinear, but about 12 % at 2000
samples (M = 64) and 25 % at 751, because neighbouring bifrequencies are
correlated (Hann window, shared spectra) and the mean of bic2 spreads more
than the chi-square bound assumes.  A half-wave symmetric limit cycle
(a sticky valve with a linear characteristic in a linear loop at a constant
set point) has only odd harmonics, so its bispectrum vanishes and the test
reads the loop as linear; an asymmetric one (e.g. an equal-percentage
valve) is found.

A nonlinear loop is not yet a sticky valve: the paper then looks at the
PV-OP map (see :mod:`ellipse`); :func:`hos_with_pv_op` combines the two.
"""

import math

import numpy as np

from stiction_ros.analysis.dsp import chi2_ppf, decimate, detrend_linear
from stiction_ros.analysis.oscillation import as_signal
from stiction_ros.analysis.signatures.ellipse import no_ellipse
from stiction_ros.analysis.signatures.result import Signature

REFERENCE = ('Choudhury, M.A.A.S., Shah, S.L., Thornhill, N.F. (2004), Diagnosis of poor '
             'control-loop performance using higher-order statistics, Automatica 40, 1719-1728')
ALPHA = 0.05
NGI_MIN = 0.001
NLI_MIN = 0.01
MIN_SEGMENTS = 8
ENOUGH_SEGMENTS = 20
SAMPLES_PER_PERIOD = 16


def squared_bicoherence(x, nfft):
    """
    Return (bic2, K): the squared bicoherence of ``x`` over the principal domain.

    ``bic2[i, j]`` belongs to bins (f1, f2) = (i + 1, j + 1) of ``nfft``; cells
    outside the domain (f2 > f1 or f1 + f2 > nfft / 2) are NaN.
    """
    step = nfft // 2
    k = 1 + (len(x) - nfft) // step
    if k < 1:
        return np.full((step, step), np.nan), 0
    idx = np.arange(nfft)[None, :] + step * np.arange(k)[:, None]
    seg = detrend_linear(x[idx], axis=1) * np.hanning(nfft)[None, :]
    spec = np.fft.fft(seg, axis=1)
    b = np.arange(1, step + 1)
    f1, f2 = np.meshgrid(b, b, indexing='ij')
    inside = (f2 <= f1) & (f1 + f2 <= step)
    x1, x2 = spec[:, f1], spec[:, f2]
    x3 = spec[:, np.where(inside, f1 + f2, 0)]
    pair = x1 * x2
    num = np.abs((pair * np.conj(x3)).mean(axis=0)) ** 2
    den = (np.abs(pair) ** 2).mean(axis=0) * (np.abs(x3) ** 2).mean(axis=0)
    with np.errstate(invalid='ignore', divide='ignore'):
        bic2 = np.where(inside & (den > 0), num / den, np.nan)
    bic2[inside & ~(den > 0)] = 0.0
    return bic2, k


def nonlinearity_indices(bic2, k, alpha=ALPHA):
    """Return dict(ngi, nli, tnli, mean, max, ngi_threshold_bic2) from a bicoherence map."""
    vals = bic2[np.isfinite(bic2)]
    n_bf = vals.size
    crit_mean = chi2_ppf(1.0 - alpha, 2 * n_bf) / (2.0 * k * n_bf)
    crit_one = chi2_ppf(1.0 - alpha, 2) / (2.0 * k)
    mean = float(vals.mean())
    return {'ngi': mean - float(crit_mean),
            'nli': abs(float(vals.max()) - (mean + 2.0 * float(vals.std()))),
            'tnli': float(vals[vals > crit_one].sum()), 'mean_bic2': mean,
            'max_bic2': float(vals.max()), 'bic2_mean_critical': float(crit_mean),
            'bic2_critical': float(crit_one), 'bifrequencies': int(n_bf)}


def bicoherence(error, sample_time, period_s=None, nfft=None):
    """
    Return the bicoherence nonlinearity signature of the control error SP - PV.

    ``value`` is NLI against 0.01; NGI is in ``details``.  ``stiction`` is
    False for a Gaussian or linear error and None for a nonlinear one (the
    PV-OP map decides, see :func:`hos_with_pv_op`).
    """
    x = as_signal(error)
    q = 1
    if period_s:
        q = max(1, int(period_s / sample_time // SAMPLES_PER_PERIOD))
        nfft = nfft or 64
    if q > 1:
        x = decimate(x - x.mean(), q)
    if nfft is None:
        # The paper's 128 when the record allows enough segments, else 64.
        nfft = 128 if 1 + (len(x) - 128) // 64 >= ENOUGH_SEGMENTS else 64
    bic2, k = squared_bicoherence(x, nfft)
    details = {'segments': k, 'nfft': nfft, 'decimation': q, 'ngi_min': NGI_MIN}
    if k < MIN_SEGMENTS:
        return Signature('bicoherence', None, NLI_MIN, None,
                         f'record too short: {k} segments of {nfft}, {MIN_SEGMENTS} needed',
                         REFERENCE, details)
    if not np.isfinite(bic2).any():
        return Signature('bicoherence', None, NLI_MIN, None,
                         'no bifrequency could be computed (the error has no finite spectrum)',
                         REFERENCE, details)
    ind = nonlinearity_indices(bic2, k)
    details.update(ind)
    freq = np.arange(1, nfft // 2 + 1) / (nfft * sample_time * q)
    curves = {'bic2': bic2, 'freq_hz': freq}
    ngi, nli = ind['ngi'], ind['nli']
    details['nonlinear'] = bool(ngi > NGI_MIN and nli > NLI_MIN)
    if ngi <= NGI_MIN:
        verdict, reason = False, (f'no significant bicoherence (NGI = {ngi:.3g} <= {NGI_MIN}): '
                                  'Gaussian, linear loop by the paper')
    elif nli <= NLI_MIN:
        verdict, reason = False, (f'non-Gaussian but linear (NGI = {ngi:.3g}, '
                                  f'NLI = {nli:.3g} <= {NLI_MIN})')
    else:
        verdict, reason = None, (f'nonlinear loop (NGI = {ngi:.3g} > {NGI_MIN}, NLI = '
                                 f'{nli:.3g} > {NLI_MIN}): stiction if the PV-OP map shows it')
    return Signature('bicoherence', nli if math.isfinite(nli) else None, NLI_MIN, verdict,
                     reason, REFERENCE, details, curves)


def hos_with_pv_op(nonlinearity, pv_op):
    """
    Return the paper's stiction test: a nonlinear loop whose PV-OP map has an ellipse.

    ``nonlinearity`` is :func:`bicoherence`'s result, ``pv_op`` that of
    :func:`stiction_ros.analysis.signatures.ellipse.ellipse`.  The value is
    the apparent stiction (% OP) against the ellipse's significance bound.
    """
    nl = nonlinearity.details.get('nonlinear')
    details = {'ngi': nonlinearity.details.get('ngi'), 'nli': nonlinearity.details.get('nli'),
               'nonlinear': nl, 'apparent_stiction': pv_op.value,
               'apparent_stiction_threshold': pv_op.threshold}
    # A map the ellipse test rejects sizes nothing, so it cannot vote either way.
    rejected = no_ellipse(pv_op)
    wide = None if pv_op.value is None or pv_op.threshold is None or rejected else (
        pv_op.value >= pv_op.threshold)
    if nl is None:
        verdict, reason = None, f'bicoherence undetermined: {nonlinearity.reason}'
    elif not nl:
        verdict, reason = False, f'no valve nonlinearity: {nonlinearity.reason}'
    elif wide is None:
        verdict, reason = None, f'nonlinear, but PV-OP map undetermined: {pv_op.reason}'
        if rejected:
            details['apparent_stiction'] = None
    elif wide:
        verdict, reason = True, (f'nonlinear loop and PV-OP ellipse: apparent stiction '
                                 f'{pv_op.value:.3g} % >= {pv_op.threshold:.3g} %')
    else:
        verdict, reason = False, (f'nonlinear loop but thin PV-OP map: apparent stiction '
                                  f'{pv_op.value:.3g} % < {pv_op.threshold:.3g} %')
    return Signature('hos_pv_op', None if rejected else pv_op.value, pv_op.threshold,
                     verdict, reason,
                     REFERENCE + '; ' + pv_op.reference, details, {})

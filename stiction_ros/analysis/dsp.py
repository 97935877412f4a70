"""
The scipy.signal and scipy.stats operations of the default analysis, without their import.

``import scipy.signal`` pulls in scipy.stats and scipy.interpolate and takes
about 1.2 s on the project's machine, which is more than everything else one
``stiction-analyze`` run of a day's record does.  The analysis uses only a
linear detrend, a decimation by an integer factor and two quantiles of the
chi-square distribution, so they are computed here from numpy alone:

* :func:`detrend_linear` removes the least-squares line exactly as
  ``scipy.signal.detrend(x, type='linear')`` does, with the same design matrix
  and LAPACK's same least-squares driver (gelsd): equal to the bit;
* :func:`decimate` is ``scipy.signal.resample_poly(x, 1, q)``: its default
  Kaiser-windowed (beta 5) low-pass FIR of ``20 q + 1`` taps at the new
  Nyquist frequency, applied with zero padding and aligned so the output has
  no delay; equal to rounding (the convolution sums in another order);
* :func:`chi2_ppf` is ``scipy.stats.chi2.ppf`` for the even degrees of
  freedom the bicoherence test uses, where the chi-square survival function
  is a finite Poisson sum; equal to 1e-13 (relative) at the 95 % the test
  asks for, to 1e-11 in the far tails; other degrees go to scipy.special.

test/test_dsp.py compares each with its scipy original.
"""

import math

import numpy as np

# resample_poly's defaults: the filter spans 10 input periods of the slower
# rate on each side, under a Kaiser window of this beta.
HALF_LENGTH_PER_FACTOR = 10
KAISER_BETA = 5.0


def detrend_linear(x: np.ndarray, axis: int = -1) -> np.ndarray:
    """
    Return ``x`` less its least-squares straight line along ``axis``.

    Parameters
    ----------
    x : numpy.ndarray
        Real samples; any shape.
    axis : int
        The axis along which each line is fitted.

    Returns
    -------
    numpy.ndarray
        Float64 array of the shape of ``x``.

    """
    data = np.moveaxis(np.asarray(x, dtype=np.float64), axis, 0)
    shape = data.shape
    n = shape[0]
    columns = data.reshape(n, -1).copy()
    # The ramp is scaled to (0, 1] as scipy scales it: the same matrix gives
    # the same solution to the last bit.
    design = np.ones((n, 2))
    design[:, 0] = np.arange(1, n + 1, dtype=np.float64) / n
    coef = np.linalg.lstsq(design, columns, rcond=None)[0]
    columns = columns - design @ coef
    return np.moveaxis(columns.reshape(shape), 0, axis)


def lowpass_fir(factor: int) -> np.ndarray:
    """
    Return the anti-aliasing filter of a decimation by ``factor`` (unit gain at DC).

    A windowed sinc with its cut-off at the decimated Nyquist frequency,
    ``2 * 10 * factor + 1`` taps, Kaiser window of beta 5.
    """
    numtaps = 2 * HALF_LENGTH_PER_FACTOR * factor + 1
    cutoff = 1.0 / factor
    m = np.arange(numtaps) - 0.5 * (numtaps - 1)
    h = cutoff * np.sinc(cutoff * m)
    h *= np.kaiser(numtaps, KAISER_BETA)
    return h / h.sum()


def decimate(x: np.ndarray, factor: int) -> np.ndarray:
    """
    Return ``x`` low-pass filtered and kept every ``factor``-th sample, without delay.

    Parameters
    ----------
    x : numpy.ndarray
        1-D samples.
    factor : int
        Decimation factor, >= 1; the output has ``ceil(len(x) / factor)`` samples.

    Returns
    -------
    numpy.ndarray
        The decimated signal; the samples beyond each end count as zeros.

    """
    x = np.asarray(x, dtype=np.float64)
    if factor == 1:
        return x.copy()
    h = lowpass_fir(factor)
    half = HALF_LENGTH_PER_FACTOR * factor
    n_out = -(-len(x) // factor)
    # Pad the filter in front so that its centre tap falls on an output
    # sample: output k is then the filtered input at k * factor exactly.
    pre = factor - half % factor
    skip = (half + pre) // factor
    full = np.convolve(x, np.concatenate((np.zeros(pre), h)))
    kept = full[::factor][skip:skip + n_out]
    if len(kept) < n_out:
        kept = np.concatenate((kept, np.zeros(n_out - len(kept))))
    return kept


def chi2_sf_even(x: float, dof: int) -> float:
    """
    Return P(X > x) for X chi-square with an even ``dof``: a Poisson CDF, summed exactly.

    With ``dof = 2 m``, ``P(X > x) = P(Poisson(x / 2) <= m - 1)``; the terms
    are summed from the largest outwards in log scale, so thousands of
    degrees of freedom neither overflow nor lose the sum.
    """
    m, lam = dof // 2, 0.5 * x
    if lam <= 0.0:
        return 1.0
    k = np.arange(m, dtype=np.float64)
    log_terms = k * math.log(lam) - lam - np.array([math.lgamma(v + 1.0) for v in k])
    top = float(log_terms.max())
    return min(1.0, math.exp(top) * float(np.exp(log_terms - top).sum()))


def chi2_ppf(q: float, dof: float) -> float:
    """
    Return the ``q`` quantile of the central chi-square distribution with ``dof`` degrees.

    Even ``dof`` (all the bicoherence test uses) is solved here by Newton's
    method on :func:`chi2_sf_even`; any other ``dof`` asks scipy.special.
    """
    if dof != int(dof) or int(dof) % 2 or not 0.0 < q < 1.0:
        from scipy import special
        return 2.0 * float(special.gammaincinv(0.5 * dof, q))
    m = int(dof) // 2
    if m == 1:
        return -2.0 * math.log1p(-q)
    # Newton's method on the survival function (its derivative is minus the
    # density) from the mean; the step is halved where it would overshoot 0.
    x = float(dof)
    log_norm = m * math.log(2.0) + math.lgamma(m)
    for _ in range(60):
        density = math.exp((m - 1) * math.log(x) - 0.5 * x - log_norm)
        step = (chi2_sf_even(x, int(dof)) - (1.0 - q)) / density
        x = max(x + step, 0.5 * x)
        if abs(step) <= 1e-13 * x:
            break
    return x

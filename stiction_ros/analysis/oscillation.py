"""
Oscillation detection from the zero crossings of the autocorrelation function.

Thornhill, N.F., Huang, B., Zhang, H. (2003), Detection of multiple
oscillations in control loops, Journal of Process Control 13(1), 91-100.

The signal is detrended (mean and linear trend removed) and, optionally,
band-limited in the frequency domain as Thornhill et al. do to separate
oscillations.  Its autocorrelation function (ACF) is then the inverse
transform of the power spectrum.  The ACF of an oscillation is an oscillation
of the same period whose zero crossings are far cleaner than those of the
signal itself, because white noise only adds to lag zero.  From the first
(up to) eleven zero crossings ``z`` of the ACF, each interval gives one period
estimate ``Tp = 2 (z[i+1] - z[i])``; the period is ``mean(Tp)``, regularity is
``r = mean(Tp) / (3 std(Tp))`` and the oscillation is regular when ``r > 1``
(the paper's rules).  At least five crossings (four intervals) are required.
On white noise this rule calls about 1 % of records regular; a slowly
wandering signal (a random walk) fools it more often unless band-limited.
"""

from dataclasses import dataclass, field
import math

import numpy as np

from stiction_ros.analysis.dsp import detrend_linear

MAX_CROSSINGS = 11
MIN_CROSSINGS = 5
# A cycle's shape needs this many samples; a quarter record holds too few cycles.
MIN_PERIOD_SAMPLES = 10.0
MAX_PERIOD_FRACTION = 0.25


@dataclass
class OscillationResult:
    """
    What :func:`detect_oscillation` found in one signal.

    ``amplitude`` is that of the fundamental (least-squares sinusoid at the
    period), in the signal's units; ``n_cycles`` is record length / period.
    ``curves`` holds the ACF for figures and is never written to JSON.
    """

    oscillating: bool
    period_s: float | None
    regularity: float
    amplitude: float
    n_cycles: float
    reason: str = ''
    curves: dict = field(default_factory=dict)

    def to_json(self):
        """Return the JSON-able fields (no curves, no infinities)."""
        def finite(v):
            return None if v is None or not math.isfinite(v) else float(v)
        return {'oscillating': self.oscillating, 'period_s': finite(self.period_s),
                'regularity': finite(self.regularity), 'amplitude': finite(self.amplitude),
                'n_cycles': finite(self.n_cycles), 'reason': self.reason}


def as_signal(x):
    """Return ``x`` as a 1-D float array, raising ValueError on NaN or infinity."""
    x = np.asarray(x, dtype=np.float64).ravel()
    if not np.all(np.isfinite(x)):
        raise ValueError('signal contains NaN or infinite values; fill or cut them first')
    return x


def detrend(x):
    """Return ``x`` with its mean and linear trend removed."""
    x = as_signal(x)
    return detrend_linear(x) if len(x) > 1 else x - x.mean()


def bandpass(x, sample_time, low_hz=None, high_hz=None):
    """Return detrended ``x`` with Fourier components outside [low_hz, high_hz] set to zero."""
    x = detrend(x)
    spec = np.fft.rfft(x)
    f = np.fft.rfftfreq(len(x), sample_time)
    keep = np.ones(f.shape, dtype=bool)
    if low_hz is not None:
        keep &= f >= low_hz
    if high_hz is not None:
        keep &= f <= high_hz
    return np.fft.irfft(np.where(keep, spec, 0.0), n=len(x))


def autocorrelation(x):
    """Return the biased ACF of ``x`` (already zero-mean) for lags 0..N-1, with ACF[0] = 1."""
    n = len(x)
    spec = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(spec * np.conj(spec), 2 * n)[:n]
    return acf / acf[0] if acf[0] > 0 else np.zeros(n)


def zero_crossings(y):
    """Return the fractional indices where ``y`` changes sign, by linear interpolation."""
    s = np.signbit(y)
    k = np.flatnonzero(s[1:] != s[:-1])
    return k + y[k] / (y[k] - y[k + 1])


def fundamental_amplitude(x, period_samples):
    """Return the amplitude of the least-squares sinusoid of ``period_samples`` fitted to ``x``."""
    w = 2 * np.pi * np.arange(len(x)) / period_samples
    basis = np.column_stack([np.cos(w), np.sin(w), np.ones_like(w)])
    coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
    return float(math.hypot(coef[0], coef[1]))


def detect_oscillation(x, sample_time, band_hz=(None, None), max_lag_fraction=0.75):
    """
    Return an :class:`OscillationResult` for ``x`` sampled every ``sample_time`` s.

    ``band_hz`` = (low, high) band-limits the signal first (None: no limit).
    Only ACF lags below ``max_lag_fraction`` of the record are used, where the
    biased ACF still averages over enough products.
    """
    n = len(as_signal(x))
    if n < 8:
        return OscillationResult(False, None, 0.0, 0.0, 0.0, 'fewer than 8 samples')
    xf = bandpass(x, sample_time, *band_hz)
    if not np.any(xf):
        return OscillationResult(False, None, 0.0, 0.0, 0.0, 'signal is constant')
    acf = autocorrelation(xf)
    lags = np.arange(n) * sample_time
    curves = {'acf_lag_s': lags, 'acf': acf}
    z = zero_crossings(acf[:max(int(n * max_lag_fraction), 3)])[:MAX_CROSSINGS]
    curves['acf_zero_crossings_s'] = z * sample_time
    if len(z) < MIN_CROSSINGS:
        return OscillationResult(
            False, None, 0.0, 0.0, 0.0,
            f'ACF has {len(z)} zero crossings; at least {MIN_CROSSINGS} needed', curves)
    periods = 2.0 * np.diff(z)
    mean = float(periods.mean())
    # A floor on the spread keeps r finite (JSON) for a noise-free sine.
    spread = max(float(periods.std()), 1e-9 * mean)
    r = mean / (3.0 * spread)
    amp = fundamental_amplitude(xf, mean)
    regular = bool(r > 1.0)
    reason = (f'regular oscillation (r = {r:.3g} > 1)' if regular
              else f'irregular (r = {r:.3g} <= 1)')
    return OscillationResult(regular, mean * sample_time, float(r), amp, float(n / mean),
                             reason, curves)


def period_sanity(period_s: float | None, sample_time: float, samples: int) -> str:
    """
    Return '' when an oscillation of ``period_s`` can be resolved, else the reason.

    Shorter than ``MIN_PERIOD_SAMPLES`` samples, a cycle's shape (square,
    triangular, sticking at the peaks) is lost between samples; longer than
    a quarter of the record, fewer than four cycles say nothing about its
    regularity (a daily load cycle in a day's data is one such).
    """
    if period_s is None or not np.isfinite(period_s) or period_s <= 0:
        return ''
    per = period_s / sample_time
    if per < MIN_PERIOD_SAMPLES:
        return (f'cycle of {period_s:.4g} s is only {per:.1f} samples of {sample_time:g} s '
                f'(at least {MIN_PERIOD_SAMPLES:g} needed to see its shape)')
    if per > MAX_PERIOD_FRACTION * samples:
        return (f'cycle of {period_s:.4g} s is longer than a quarter of the record '
                f'({samples * sample_time:.4g} s): too few cycles to judge')
    return ''

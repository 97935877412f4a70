"""
Measure a sustained oscillation: is there one, its period, amplitude and regularity.

Periods come from mean-crossings with hysteresis (so noise does not add
crossings), interpolated between samples.  Regularity is Thornhill et al.'s
``r = mean(T) / (3 std(T))``: r > 1 means a regular oscillation.  An
oscillation counts as a limit cycle only if it is regular and does not decay
over the window (last cycles at least ``sustain`` times the first ones).
"""

from dataclasses import asdict, dataclass
import math

import numpy as np


@dataclass
class Oscillation:
    """What :func:`measure_oscillation` found in one signal."""

    oscillating: bool
    period: float
    amplitude: float
    regularity: float
    cycles: int
    decay_ratio: float

    def as_dict(self):
        """Return the fields as a plain dict (for JSON reports)."""
        return asdict(self)


def up_crossings(x, t, hysteresis):
    """Return interpolated times where ``x`` rises through 0 after being below -hysteresis."""
    times = []
    armed = False
    for k in range(1, len(x)):
        if x[k - 1] < -hysteresis:
            armed = True
        if armed and x[k - 1] < 0.0 <= x[k]:
            frac = -x[k - 1] / (x[k] - x[k - 1])
            times.append(t[k - 1] + frac * (t[k] - t[k - 1]))
            armed = False
    return np.array(times)


def measure_oscillation(x, sample_time, discard=0.5, min_amplitude=1e-3, sustain=0.8):
    """Measure the oscillation in the part of ``x`` after the first ``discard`` fraction."""
    x = np.asarray(x, dtype=np.float64)
    x = x[int(len(x) * discard):]
    t = np.arange(len(x)) * sample_time
    none = Oscillation(False, math.nan, 0.0, 0.0, 0, math.nan)
    if len(x) < 4:
        return none
    xc = x - x.mean()
    spread = xc.std()
    if spread == 0.0:
        return none
    ups = up_crossings(xc, t, 0.2 * spread)
    if len(ups) < 3:
        return Oscillation(False, math.nan, float(np.ptp(x) / 2), 0.0, max(len(ups) - 1, 0),
                           math.nan)
    periods = np.diff(ups)
    amps = []
    for a, b in zip(ups[:-1], ups[1:]):
        seg = xc[(t >= a) & (t < b)]
        amps.append(0.5 * float(np.ptp(seg)))
    amps = np.array(amps)
    sd = periods.std()
    reg = math.inf if sd == 0.0 else float(periods.mean() / (3.0 * sd))
    k = max(1, len(amps) // 3)
    decay = float(amps[-k:].mean() / amps[:k].mean()) if amps[:k].mean() > 0 else math.nan
    amplitude = float(np.median(amps))
    osc = bool(amplitude > min_amplitude and reg > 1.0 and decay >= sustain)
    return Oscillation(osc, float(np.median(periods)), amplitude, reg, len(periods), decay)

"""
Waveform shape of an oscillation: closer to a sine or to a triangle.

A sticky valve in a self-regulating loop with a PI controller makes OP ramp
at a constant rate while the valve is stuck, so OP looks triangular (He et
al. 2007, the chapter's Sect. 2.3.4).  Both shapes are fitted by least squares
at the measured period over a grid of phases; the ratio of residuals says
which fits better.
"""

import numpy as np

from stiction_ros.sim.sources import triangle_wave


def shape_fit(x, period, sample_time, phases=180):
    """
    Return dict(sine_residual, triangle_residual, ratio) for ``x`` at ``period``.

    Residuals are mean squared errors relative to the variance of ``x``;
    ``ratio = sine / triangle`` above 1 means the waveform is triangular.
    """
    x = np.asarray(x, dtype=np.float64)
    t = np.arange(len(x)) * sample_time
    var = float(np.var(x))
    if var == 0.0:
        return {'sine_residual': 0.0, 'triangle_residual': 0.0, 'ratio': 1.0}
    best = {}
    for name, shape in (('sine', np.sin), ('triangle', triangle_wave)):
        lowest = np.inf
        for phi in np.linspace(0, 2 * np.pi, phases, endpoint=False):
            basis = np.column_stack([shape(2 * np.pi * t / period + phi), np.ones_like(t)])
            coef, *_ = np.linalg.lstsq(basis, x, rcond=None)
            lowest = min(lowest, float(np.mean((basis @ coef - x) ** 2)))
        best[name] = lowest / var
    ratio = best['sine'] / best['triangle'] if best['triangle'] > 0 else np.inf
    return {'sine_residual': best['sine'], 'triangle_residual': best['triangle'],
            'ratio': float(ratio)}

"""
How much better a sticky valve explains PV than a linear one, in simulation (output error).

The ARX fit behind ``ham_variance_ratio`` scores one-step predictions, which
lean on the last measured PV, and on some plain stick-slip records it barely
prefers the sticky valve (a simulated calibration record with S 3.9 %: ARX
ratio 0.93, this one 0.61); on others the two agree.  Here the valve path
alone drives a linear plant over the whole record (an output-error
Hammerstein model), so a slip that the plant turns into a step in PV is
credited to the valve rather than to the last PV sample.

The plant is a sum of first-order lags of the valve path behind a dead time
(a fixed basis, so each fit is linear least squares), plus a few slow
cosines for load drifts; an integrating loop is fitted on PV's increments.
Kano's valve runs over a grid of S relative to OP's range and J / S.
"""

from typing import Iterator

import numpy as np

from stiction_ros.kernels.hammerstein import first_order_lag, segment_path

# Lag time constants and dead times, in samples: from a fast flow loop to a
# slow temperature loop at the sampling of our records.
LAG_TAUS = (0.7, 2.0, 5.0, 12.0, 30.0, 80.0)
DELAYS = (0, 1, 2, 4, 7, 11)
S_RELATIVE = tuple(np.geomspace(0.01, 0.5, 12))
J_OVER_S = (0.0, 0.5, 1.0)
# One slow cosine per 150 samples: drifts slower than that are loads, not valve.
SAMPLES_PER_DRIFT_TERM = 150


def _lags(u: np.ndarray) -> np.ndarray:
    u = np.ascontiguousarray(u - u.mean())
    return np.column_stack([first_order_lag(u, float(np.exp(-1.0 / tau)))
                            for tau in LAG_TAUS])


class _Fit:
    """The record's target with the drift basis projected out, and the fit of a valve path."""

    def __init__(self, y: np.ndarray):
        n = len(y)
        t = (np.arange(n) + 0.5) / n
        terms = max(1, n // SAMPLES_PER_DRIFT_TERM)
        drift = np.column_stack([np.ones(n)] + [np.cos(np.pi * j * t)
                                                for j in range(1, terms + 1)])
        self.q = np.linalg.qr(drift)[0]
        self.y = y - self.q @ (self.q.T @ y)
        self.drift_only = float(self.y @ self.y)

    def rss(self, valve_path: np.ndarray) -> float:
        """Return the least residual sum of squares over the dead times."""
        lag = _lags(valve_path)
        n = len(lag)
        best = self.drift_only
        for d in DELAYS:
            if d >= n:
                break
            shifted = np.zeros_like(lag)
            shifted[d:] = lag[:n - d]
            b = shifted - self.q @ (self.q.T @ shifted)
            coef = np.linalg.lstsq(b, self.y, rcond=None)[0]
            r = self.y - b @ coef
            best = min(best, float(r @ r))
        return best


def target(op: np.ndarray, pv: np.ndarray,
           integrating: bool) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(y, u)``: PV about its mean and OP, or a level's increments and the OP before."""
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    y, u = (np.diff(pv), op[:-1]) if integrating else (pv - pv.mean(), op)
    return y, np.ascontiguousarray(u)


def sticky_paths(u: np.ndarray, op: np.ndarray) -> Iterator[tuple[float, np.ndarray]]:
    """Yield ``(S over OP's range, valve path)`` for every Kano valve of the grid."""
    span = float(np.ptp(op)) or 1.0
    for s_rel in S_RELATIVE:
        for j_over_s in J_OVER_S:
            s = s_rel * span
            yield float(s_rel), segment_path(u, s, j_over_s * s, 0, 0.5)


def output_error_figures(op: np.ndarray, pv: np.ndarray,
                         integrating: bool) -> tuple[float, float]:
    """
    Return ``(oe_ratio, oe_S_rel)`` of one contiguous record.

    Parameters
    ----------
    op, pv : numpy.ndarray
        Controller output (%) and process value, equally long, finite.
    integrating : bool
        Fit PV's increments (a level) rather than PV.

    Returns
    -------
    tuple of float
        ``oe_ratio``: the best sticky valve's residual over the linear valve's
        (below 1 when stiction explains PV better; NaN when the linear valve
        leaves nothing to explain); ``oe_S_rel``: that valve's S over OP's range.

    """
    y, u = target(op, pv, integrating)
    if len(y) < 2 * max(DELAYS):
        return float('nan'), float('nan')
    fit = _Fit(y)
    linear = fit.rss(u)
    if not linear > 0:
        return float('nan'), float('nan')
    best, best_s = np.inf, float('nan')
    for s_rel, path in sticky_paths(u, np.asarray(op)):
        r = fit.rss(path)
        if r < best:
            best, best_s = r, s_rel
    return best / linear, best_s

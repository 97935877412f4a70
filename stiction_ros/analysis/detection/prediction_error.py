"""
How much better a sticky valve predicts PV than a linear one, with loads that wander.

The output-error fit (``output_error``) leaves loads in its residual apart
from slow cosines, but simulated and plant loads are random walks and steps:
on simulated calibration records whose stiction shows at 1-2 noise widths in
PV, 39 % were missed.  Here the disturbance is an integrated noise,
``H(q) = (1 - c q^-1) / (1 - q^-1)``, so the valve path is judged by
one-step prediction errors of PV's filtered increments, where a random-walk
load is white and a slip stands out.  ``c`` runs over a short grid (0: a
pure random walk; 0.95: close to white measurement noise) and the smallest
prediction error wins, for the linear and for each sticky valve alike.

The plant is the output-error fit's basis of first-order lags, behind a dead
time of at least one sample: the controller computes OP[k] from PV[k], so a
fit allowed to use OP[k] for PV[k] learns the controller, not the plant.
The rule does not remove all of it: an increment PV[k] - PV[k-1] still holds
PV[k-1], which OP[k-1] saw, and a level's increments are taken forward
(PV[k+1] - PV[k] against OP[k]), so a level's own dead time counts one
sample more.  Neither was tuned; the figures below are of the rule as it stands.

Alone, ``pe_ratio`` separates the simulated training records with an AUC of
0.82 (``oe_ratio``: 0.55); a sticky valve may also predict worse than OP
itself (ratio above 1), when its slips in the grid fall a sample off.  Both
parts count: on every third calibration record (352) the AUC is 0.86 as built, 0.52 with
a dead time of zero allowed, 0.58 with ``c`` held at 0.95 and 0.77 with ``c``
held at 0.  In open loop with white noise the output-error fit is the
sharper of the two; in closed loop it is this one (``test_prediction_error``).
"""

import numpy as np

from stiction_ros.analysis.detection.output_error import LAG_TAUS, sticky_paths, target
from stiction_ros.kernels.hammerstein import first_order_lag

NOISE_C = (0.0, 0.5, 0.8, 0.95)
PE_DELAYS = (1, 2, 3, 5, 8, 12)
# The longest dead time's rows have no regressor, and the first increment is
# the zero that ``prepend`` makes: every fit drops them all.
SKIP = max(PE_DELAYS) + 1
# Eigenvalues of a window's Gram matrix under this share of its largest are no direction
# (singular values of the regressors under 3e-7 of theirs): a flat valve path's lags.
RANK_FLOOR = 1e-13


def _noise_filter(x: np.ndarray, c: float) -> np.ndarray:
    """Return ``(1 - q^-1) / (1 - c q^-1) x``, the inverse of the disturbance model."""
    d = np.ascontiguousarray(np.diff(x, prepend=x[0]))
    if c == 0.0:
        return d
    return first_order_lag(d, c) / (1.0 - c)


def _lags(u: np.ndarray) -> np.ndarray:
    u = np.ascontiguousarray(u)
    return np.column_stack([first_order_lag(u, float(np.exp(-1.0 / t))) for t in LAG_TAUS])


def _window_rss(x: np.ndarray, y: np.ndarray, first: int, lo: int, hi: int,
                g_mid: np.ndarray) -> float:
    """
    Return the least-squares RSS of ``y`` on ``x[first:first + len(y)]``.

    The Gram matrix is that of the rows every delay shares (``g_mid``, rows
    ``lo:hi``) plus this window's own rows before and after them: one product
    over the record serves every delay, summed, never differenced.  Directions
    with an eigenvalue under ``RANK_FLOOR`` of the largest are left out, as a
    rank-revealing least-squares solver leaves out a flat valve's empty lags.
    """
    rows = x[first:first + len(y)]
    head, tail = x[first:lo], x[hi:first + len(y)]
    w, v = np.linalg.eigh(g_mid + head.T @ head + tail.T @ tail)
    keep = w > w[-1] * RANK_FLOOR
    vk = v[:, keep]
    coef = vk @ ((vk.T @ (rows.T @ y)) / w[keep])
    r = y - rows @ coef
    return float(r @ r)


class _Predictor:
    """PV's filtered increments per noise model, and the best fit of a valve path."""

    def __init__(self, y: np.ndarray):
        self.ys = {c: _noise_filter(y, c)[SKIP:] for c in NOISE_C}
        self.n = len(y)

    def rss(self, path: np.ndarray) -> tuple[float, float]:
        """Return the least residual sum of squares and its ``c``, over ``c`` and dead time."""
        best, best_c = np.inf, float('nan')
        path = path - path.mean()
        n = self.n
        # Rows every delay's window holds: the Gram matrix of these is shared.
        lo, hi = SKIP - min(PE_DELAYS), n - max(PE_DELAYS)
        for c in NOISE_C:
            x = np.column_stack([_lags(_noise_filter(path, c)), np.ones(n)])
            g_mid = x[lo:hi].T @ x[lo:hi]
            yc = self.ys[c]
            for d in PE_DELAYS:
                rr = _window_rss(x, yc, SKIP - d, lo, hi, g_mid)
                if rr < best:
                    best, best_c = rr, c
        return best, best_c


def prediction_error_figures(op: np.ndarray, pv: np.ndarray,
                             integrating: bool) -> tuple[float, float]:
    """
    Return ``(pe_ratio, pe_c)`` of one contiguous record.

    Parameters
    ----------
    op, pv, integrating
        As for :func:`~stiction_ros.analysis.detection.output_error.output_error_figures`.

    Returns
    -------
    tuple of float
        ``pe_ratio``: the best sticky valve's prediction error over the linear
        valve's (below 1 when stiction predicts PV better; NaN when fewer than
        ``4 * SKIP`` samples are fitted or the linear valve predicts PV
        exactly; 1 for a constant OP, which no valve can tell apart);
        ``pe_c``: the noise model's ``c`` the linear valve chose.

    """
    y, u = target(op, pv, integrating)
    if len(y) < 4 * SKIP:
        return float('nan'), float('nan')
    fit = _Predictor(y)
    linear, c_linear = fit.rss(u)
    if not linear > 0:
        return float('nan'), float('nan')
    best = min(fit.rss(path)[0] for _, path in sticky_paths(u, np.asarray(op)))
    return best / linear, c_linear

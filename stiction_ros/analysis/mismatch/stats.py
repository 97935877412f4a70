"""The tests behind every claim of ``--explain``: likelihood ratios and the held-out bootstrap."""

import math

import numpy as np

# Chi-square 99.9 % points by degrees of freedom.
CHI2_999 = {1: 10.83, 2: 13.82, 3: 16.27, 4: 18.47, 5: 20.52}
P_HELDOUT = 0.01
BOOT = 400


def acf1(r: np.ndarray) -> float:
    """Return the lag-1 autocorrelation of ``r`` (finite samples), clipped to [0, 0.95]."""
    r = np.asarray(r, dtype=np.float64)
    r = r[np.isfinite(r)]
    if len(r) < 3:
        return 0.0
    r = r - r.mean()
    d = float(r @ r)
    return min(max(float(r[1:] @ r[:-1]) / d, 0.0), 0.95) if d > 0 else 0.0


def lr_eff(simple_sse: float, rich_sse: float, n: int, rho: float) -> float:
    """
    Return the likelihood ratio counted on the effective sample size.

    A residual of lag-1 autocorrelation ``rho`` carries about
    n (1 - rho) / (1 + rho) independent samples; counting all n would make
    any structured misfit look significant.
    """
    if rich_sse <= 0 or simple_sse <= 0:
        return 0.0
    return n * (1.0 - rho) / (1.0 + rho) * math.log(simple_sse / rich_sse)


def chi2_999(dof: int) -> float:
    """Return the chi-square 99.9 % point for 1 to 5 degrees of freedom (clipped)."""
    return CHI2_999[min(max(int(dof), 1), 5)]


def heldout_test(e_simple: np.ndarray, e_rich: np.ndarray, seed: int = 0) -> dict:
    """
    Return whether the richer model's held-out errors are smaller, by a block bootstrap.

    The per-sample loss difference is resampled in blocks of about sqrt(n)
    samples (residuals of a valve model are autocorrelated); ``p`` is the share
    of resampled mean differences at or below zero, ``gain`` the relative
    reduction of the held-out MSE.
    """
    m = np.isfinite(e_simple) & np.isfinite(e_rich)
    d = e_simple[m] ** 2 - e_rich[m] ** 2
    n = len(d)
    if n < 20:
        return {'samples': n, 'gain': float('nan'), 'p': 1.0}
    block = max(10, int(math.sqrt(n)))
    blocks = math.ceil(n / block)
    rng = np.random.default_rng(seed)
    starts = rng.integers(0, n - block + 1, size=(BOOT, blocks))
    csum = np.concatenate([[0.0], np.cumsum(d)])
    means = (csum[starts + block] - csum[starts]).sum(axis=1) / (blocks * block)
    simple = float(np.mean(e_simple[m] ** 2))
    return {'samples': n, 'gain': float(np.mean(d)) / simple if simple > 0 else 0.0,
            'p': float(np.mean(means <= 0.0))}


def earns(test: dict) -> bool:
    """
    Return whether a stage earns its place: significant on the fitted part, no loss held out.

    Stages are weighed less strictly than friction itself: a held-out part of
    a few breakaways cannot make a dead time significant on its own, but must
    not get worse with it.
    """
    return test['lr'] > test['threshold'] and test.get('heldout_gain', 0.0) >= 0.0


def curvature_errors(sse, theta, steps, sigma2: float) -> list:
    """
    Return each parameter's standard error from the joint curvature of ``sse`` at ``theta``.

    ``sse(theta)`` is the residual sum of squares; its Hessian, by central
    differences of ``steps``, is inverted whole, so a parameter that trades
    off against another (a calibration's offset against its gain, a dead
    time against a lag) gets the wider, marginal error that its correlation
    implies, not the error it would have with the others known.  Where the
    joint Hessian is not positive definite (a kink, a flat direction) each
    parameter keeps its own curvature's error, and one with none gets inf.

    ``theta`` may lie off the minimum: a search stopped at its tolerance, or
    kept a grid point.  The quadratic through the same points then has its
    minimum ``-H^-1 g`` away (``g`` the central-difference gradient), and each
    parameter's distance to it is added to its error in quadrature, so that
    the error also covers where the search stopped.  At the minimum ``g`` is
    zero and nothing is added.
    """
    theta = np.asarray(theta, dtype=np.float64)
    h = np.asarray(steps, dtype=np.float64)
    k = len(theta)
    f0 = sse(theta)
    cache = {}

    def at(*moves):
        # moves: (index, sign) pairs; memoised, as the diagonal shares its points
        key = tuple(sorted(moves))
        if key not in cache:
            t = theta.copy()
            for i, s in key:
                t[i] += s * h[i]
            cache[key] = sse(t)
        return cache[key]

    hess = np.zeros((k, k))
    for i in range(k):
        hess[i, i] = (at((i, 1)) - 2.0 * f0 + at((i, -1))) / (h[i] * h[i])
        for j in range(i):
            hess[i, j] = hess[j, i] = (at((i, 1), (j, 1)) - at((i, 1), (j, -1))
                                       - at((i, -1), (j, 1)) + at((i, -1), (j, -1))) / (
                4.0 * h[i] * h[j])
    grad = np.array([(at((i, 1)) - at((i, -1))) / (2.0 * h[i]) for i in range(k)])
    # sse ~ f0 + g' d + d' H d / 2, and the noise variance sigma2: cov = 2 sigma2 H^-1
    if k > 1 and np.all(np.isfinite(hess)) and np.all(np.diag(hess) > 0):
        scale = 1.0 / np.sqrt(np.diag(hess))
        corr = hess * np.outer(scale, scale)
        if np.linalg.eigvalsh(corr).min() > 1e-9:
            inv = np.linalg.inv(corr) * np.outer(scale, scale)
            miss = inv @ grad
            return [math.sqrt(max(v, 0.0) + m * m)
                    for v, m in zip(np.diag(2.0 * sigma2 * inv), miss)]
    return [math.sqrt(2.0 * sigma2 / c + (g / c) ** 2) if c > 0 else math.inf
            for c, g in zip(np.diag(hess), grad)]

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

"""
Compiled sum-of-squared-errors kernels for identifying S and J.

Identification evaluates a model thousands of times on the same record, so
these kernels fuse the model and the error sum (no output array), and stop as
soon as the sum passes ``limit``: a candidate already worse than the ones kept
needs no exact score.  The friction logic is the one of
``stiction_ros.models.kano`` and ``stiction_ros.models.choudhury`` (percent
input, linear characteristic), started at rest at the first measured position
of every valid segment; ``test_identify.py`` checks that both give the same
numbers.  Without numba the same functions run as plain Python, slowly.
"""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats, Ints


@njit(cache=True)
def _clip(x: float) -> float:
    return 0.0 if x < 0.0 else 100.0 if x > 100.0 else x


@njit(cache=True)
def _breakaway(d: float, rel: float, S: float, J: float) -> float:
    # Same rule as stiction_ros.models.breakaway, compiled.
    if d == 0.0:
        if abs(rel) > 0.5 * (S + J):
            return 1.0 if rel > 0.0 else -1.0
        return 0.0
    if -d * rel > S:
        return -d
    if d * rel > J:
        return d
    return 0.0


@njit(cache=True)
def _kano_step(uraw: float, a: float, S: float, J: float, fd: float, uf: float, u1: float,
               u2: float, us: float, resting: bool, d: float,
               yk: float) -> tuple[float, float, float, float, bool, float, float]:
    # One sample of Kano's model; the state travels as a tuple so that numba
    # keeps it in registers.  Returns the new (uf, u1, u2, us, resting, d, yk).
    uf = a * uf + (1.0 - a) * uraw
    uk = _clip(uf)
    if not resting and (uk - u1) * (u1 - u2) <= 0.0:
        us = u1
        resting = True
    if resting:
        nd = _breakaway(d, uk - us, S, J)
        if nd != 0.0:
            d = nd
            resting = False
    if not resting:
        yk = _clip(uk - d * fd)
    return uf, uk, u1, us, resting, d, yk


@njit(cache=True, nogil=True)
def kano_sse(u: Floats, y: Floats, starts: Ints, stops: Ints, S: float, J: float, a: float,
             limit: float) -> float:
    """Return the SSE of Kano's model (air-chamber pole ``a``) against ``y``, or > ``limit``."""
    fd = 0.5 * (S - J)
    sse = 0.0
    for s in range(starts.shape[0]):
        i0 = starts[s]
        uf = u[i0]
        u1 = _clip(uf)
        u2, us, resting, d, yk = u1, u1, True, 0.0, y[i0]
        for k in range(i0, stops[s]):
            uf, u1, u2, us, resting, d, yk = _kano_step(u[k], a, S, J, fd, uf, u1, u2, us,
                                                        resting, d, yk)
            e = yk - y[k]
            sse += e * e
            if sse > limit:
                return sse
    return sse


@njit(cache=True, nogil=True)
def choudhury_sse(u: Floats, y: Floats, starts: Ints, stops: Ints, S: float, J: float,
                  lam: float, limit: float) -> float:
    """Return the SSE of Choudhury's model (EWMA weight ``lam``) against ``y``, or > ``limit``."""
    fd = 0.5 * (S - J)
    sse = 0.0
    for s in range(starts.shape[0]):
        i0 = starts[s]
        pos = y[i0]
        x = u[i0]
        xprev = x
        sprev = 0.0
        xss = x
        stuck = True
        d = 0.0
        for k in range(i0, stops[s]):
            x = lam * u[k] + (1.0 - lam) * x
            dx = x - xprev
            sl = 0.0 if dx == 0.0 else (1.0 if dx > 0.0 else -1.0)
            if x <= 0.0 or x >= 100.0:
                d = -1.0 if x <= 0.0 else 1.0
                pos = 0.0 if x <= 0.0 else 100.0
                stuck = True
                xss = pos + d * fd
            else:
                if not stuck and sl != sprev:
                    stuck = True
                    xss = xprev
                if stuck:
                    nd = _breakaway(d, x - xss, S, J)
                    if nd != 0.0:
                        d = nd
                        stuck = False
                if not stuck:
                    pos = _clip(x - d * fd)
            sprev = sl
            xprev = x
            e = pos - y[k]
            sse += e * e
            if sse > limit:
                return sse
    return sse


@njit(cache=True, nogil=True)
def grid_sse(kernel_id: int, u: Floats, y: Floats, starts: Ints, stops: Ints, s_values: Floats,
             j_values: Floats, f: float, limit: float) -> Floats:
    """Return the SSE of every (S, J) pair on a grid, each abandoned past ``limit``."""
    out = np.empty((s_values.shape[0], j_values.shape[0]))
    for i in range(s_values.shape[0]):
        for j in range(j_values.shape[0]):
            if kernel_id == 0:
                out[i, j] = kano_sse(u, y, starts, stops, s_values[i], j_values[j], f, limit)
            else:
                out[i, j] = choudhury_sse(u, y, starts, stops, s_values[i], j_values[j], f,
                                          limit)
    return out


def spread_order(n: int) -> Ints:
    """
    Return a permutation of ``range(n)`` that visits a grid evenly from the start.

    A stride near ``n`` times the golden ratio, coprime with ``n``: the first
    points scored are spread over the whole grid, so the running bound of
    :func:`points_sse_best` is tight after a few of them.
    """
    if n <= 2:
        return np.arange(n)
    stride = int(n * 0.6180339887498949)
    while np.gcd(stride, n) != 1:
        stride += 1
    return (np.arange(n, dtype=np.int64) * stride) % n


@njit(cache=True, nogil=True)
def points_sse_best(kernel_id: int, u: Floats, y: Floats, starts: Ints, stops: Ints,
                    s_pts: Floats, j_pts: Floats, f: float, best: Floats) -> Floats:
    """
    Score (S, J) pairs in order; exact for the best ones, only bounded from below elsewhere.

    ``best`` holds the ``keep`` best sums known so far, ascending (padded with
    the limit), and is updated in place.  Each pair is abandoned as soon as
    its sum passes the ``keep``-th of them, the bound the final ``keep`` best
    all stay under: they are scored exactly and the rest cost a fraction of
    the record each.
    """
    keep = best.shape[0]
    out = np.empty(s_pts.shape[0])
    for idx in range(s_pts.shape[0]):
        bound = best[keep - 1]
        if kernel_id == 0:
            e = kano_sse(u, y, starts, stops, s_pts[idx], j_pts[idx], f, bound)
        else:
            e = choudhury_sse(u, y, starts, stops, s_pts[idx], j_pts[idx], f, bound)
        out[idx] = e
        if e < bound:
            insert_best(best, e)
    return out


@njit(cache=True, inline='always')
def insert_best(best: Floats, e: float) -> None:
    """Put ``e`` into the ascending ``best`` in its place, dropping the last."""
    m = best.shape[0] - 1
    while m > 0 and best[m - 1] > e:
        best[m] = best[m - 1]
        m -= 1
    best[m] = e


@njit(cache=True)
def kano_output(u: Floats, y0: float, S: float, J: float, a: float) -> Floats:
    """Return Kano's output for input ``u``, at rest at ``y0`` before the first sample."""
    y = np.empty(u.shape[0])
    fd = 0.5 * (S - J)
    uf = u[0]
    u1 = _clip(uf)
    u2, us, resting, d, yk = u1, u1, True, 0.0, y0
    for k in range(u.shape[0]):
        uf, u1, u2, us, resting, d, yk = _kano_step(u[k], a, S, J, fd, uf, u1, u2, us,
                                                    resting, d, yk)
        y[k] = yk
    return y

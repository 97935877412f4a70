"""
Compiled sum-of-squared-errors kernels for identifying S and J.

Identification evaluates a model thousands of times on the same record, so
these kernels fuse the model and the error sum (no output array), and stop as
soon as the sum passes ``limit``: a candidate already worse than the ones kept
needs no exact score.  The friction logic is the one of
``stiction_ros.models.kano`` and ``stiction_ros.models.choudhury`` (percent
input, linear characteristic; :mod:`stiction_ros.kernels.valve_steps`);
``test_identify.py`` checks that both give the same numbers.  Without numba
the same functions run as plain Python, slowly.

Only the samples of the valid segments are scored, but the valve runs on
between them wherever its input is known (``input_known``): a gap in MV
alone costs its own samples and nothing else, unless it falls in the first
rest, whose start is the mean of the rest's scored samples.  Where OP is
unknown, the next segment starts from the best of four states at its first
measured position (:mod:`stiction_ros.kernels.valve_starts` says where the
valve starts, and ``stiction_ros.analysis.fit_core`` why).
:func:`valve_output` writes the position these kernels score.
"""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats, Ints
from stiction_ros.kernels.valve_starts import advance, first_rest, first_state, restart, \
    restart_position, restart_state, STATE
from stiction_ros.kernels.valve_steps import _choudhury_step, _clip, _kano_step, input_known


@njit(cache=True, nogil=True)
def kano_sse(u: Floats, y: Floats, starts: Ints, stops: Ints, S: float, J: float, a: float,
             limit: float) -> float:
    """Return the SSE of Kano's model (air-chamber pole ``a``) against ``y``, or > ``limit``."""
    fd = 0.5 * (S - J)
    sse = 0.0
    if starts.shape[0] == 0:
        return sse
    st = np.empty(STATE)
    s0, k1, _, sse = first_rest(0, u, y, starts, stops, S, J, a, limit, st)
    if sse > limit:
        return sse
    uf, u1, u2, us, resting, d, yk = st[0], st[1], st[2], st[3], st[4] > 0.5, st[5], st[6]
    for s in range(s0, starts.shape[0]):
        i0 = starts[s]
        k0 = i0
        if s == s0 and k1 >= 0:
            # Where the first move left off: the rest of a gap unscored, then the segment.
            for k in range(k1, i0):
                uf, u1, u2, us, resting, d, yk = _kano_step(u[k], a, S, J, fd, uf, u1, u2,
                                                            us, resting, d, yk)
            k0 = max(k1, i0)
        elif input_known(u, stops[s - 1], i0):
            # OP known through the gap: the valve ran on; its samples are not scored.
            for k in range(stops[s - 1], i0):
                uf, u1, u2, us, resting, d, yk = _kano_step(u[k], a, S, J, fd, uf, u1, u2,
                                                            us, resting, d, yk)
        else:
            st = np.empty(STATE)
            e, k0, _ = restart(0, u, y, i0, stops[s], S, J, a, limit - sse, st)
            sse += e
            if sse > limit:
                return sse
            uf, u1, u2, us, resting, d, yk = (st[0], st[1], st[2], st[3], st[4] > 0.5, st[5],
                                              st[6])
        for k in range(k0, stops[s]):
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
    if starts.shape[0] == 0:
        return sse
    st = np.empty(STATE)
    s0, k1, _, sse = first_rest(1, u, y, starts, stops, S, J, lam, limit, st)
    if sse > limit:
        return sse
    x, xprev, sprev, xss, stuck, d, pos = st[0], st[1], st[2], st[3], st[4] > 0.5, st[5], st[6]
    for s in range(s0, starts.shape[0]):
        i0 = starts[s]
        k0 = i0
        if s == s0 and k1 >= 0:
            # Where the first move left off: the rest of a gap unscored, then the segment.
            for k in range(k1, i0):
                x, xprev, sprev, xss, stuck, d, pos = _choudhury_step(
                    u[k], lam, S, J, fd, x, xprev, sprev, xss, stuck, d, pos)
            k0 = max(k1, i0)
        elif input_known(u, stops[s - 1], i0):
            # OP known through the gap: the valve ran on; its samples are not scored.
            for k in range(stops[s - 1], i0):
                x, xprev, sprev, xss, stuck, d, pos = _choudhury_step(
                    u[k], lam, S, J, fd, x, xprev, sprev, xss, stuck, d, pos)
        else:
            st = np.empty(STATE)
            e, k0, _ = restart(1, u, y, i0, stops[s], S, J, lam, limit - sse, st)
            sse += e
            if sse > limit:
                return sse
            x, xprev, sprev, xss, stuck, d, pos = (st[0], st[1], st[2], st[3], st[4] > 0.5,
                                                   st[5], st[6])
        for k in range(k0, stops[s]):
            x, xprev, sprev, xss, stuck, d, pos = _choudhury_step(
                u[k], lam, S, J, fd, x, xprev, sprev, xss, stuck, d, pos)
            e = pos - y[k]
            sse += e * e
            if sse > limit:
                return sse
    return sse


@njit(cache=True, nogil=True,
      aot='f8[:, ::1](i8, f8[::1], f8[::1], i8[::1], i8[::1], f8[::1], f8[::1], f8, f8)')
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


@njit(cache=True, nogil=True,
      aot='f8[::1](i8, f8[::1], f8[::1], i8[::1], i8[::1], f8[::1], f8[::1], f8, f8[::1])')
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


@njit(cache=True, nogil=True,
      aot='void(i8, f8[::1], f8[::1], i8[::1], i8[::1], f8, f8, f8, f8[::1])')
def valve_output(kernel_id: int, u: Floats, y: Floats, starts: Ints, stops: Ints, S: float,
                 J: float, f: float, out: Floats) -> None:
    """
    Write into ``out`` the position that :func:`grid_sse` scores, sample for sample.

    Over the segments and the gaps the valve runs on through; after a gap in
    OP from the restart that scores best on its segment.
    """
    fd = 0.5 * (S - J)
    st = np.empty(STATE)
    for s in range(starts.shape[0]):
        i0 = starts[s]
        k0 = i0
        if s == 0:
            y0 = first_rest(kernel_id, u, y, starts, stops, S, J, f, np.inf, st)[2]
            first_state(kernel_id, u[i0], y0, st)
        elif input_known(u, stops[s - 1], i0):
            k0 = stops[s - 1]
        else:
            c = restart(kernel_id, u, y, i0, stops[s], S, J, f, np.inf, st)[2]
            restart_state(kernel_id, c, u[i0], restart_position(y, i0, stops[s], c), st)
        for k in range(k0, stops[s]):
            out[k] = advance(kernel_id, st, u[k], S, J, f, fd)

"""
Compiled sum-of-squared-errors kernels for identifying S and J.

Identification evaluates a model thousands of times on the same record, so
these kernels fuse the model and the error sum (no output array), and stop as
soon as the sum passes ``limit``: a candidate already worse than the ones kept
needs no exact score.  The friction logic is the one of
``stiction_ros.models.kano`` and ``stiction_ros.models.choudhury`` (percent
input, linear characteristic); ``test_identify.py`` checks that both give the
same numbers.  Without numba the same functions run as plain Python, slowly.

Only the samples of the valid segments are scored, but the valve runs on
between them wherever its input is known (:func:`input_known`): a gap in MV
alone costs its own samples and nothing else.  Where OP is unknown, the next
segment starts from the best of four states at its first measured position
(:func:`restart`; ``stiction_ros.analysis.fit_core`` says why).  The
record's valve starts at rest at the mean of the samples of its first
segment before its first move (:func:`first_rest`), the start that fits
them best, not at the first sample alone.  :func:`valve_output` writes the
position these kernels score.
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


@njit(cache=True, inline='always')
def input_known(u: Floats, a: int, b: int) -> bool:
    """Return whether the input is finite on ``[a, b)``: a valve ran on through that gap."""
    for k in range(a, b):
        if not np.isfinite(u[k]):
            return False
    return True


@njit(cache=True, inline='always')
def _choudhury_step(uk: float, lam: float, S: float, J: float, fd: float, x: float,
                    xprev: float, sprev: float, xss: float, stuck: bool, d: float,
                    pos: float) -> tuple[float, float, float, float, bool, float, float]:
    # One sample of Choudhury's model; returns the new (x, xprev, sprev, xss, stuck, d, pos).
    x = lam * uk + (1.0 - lam) * x
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
    return x, x, sl, xss, stuck, d, pos


# A restart after a gap in OP tries four states (fit_core says why): stuck at the
# measured position, or moving up or down through it.  A state is 7 floats: Kano's
# (uf, u1, u2, us, resting, d, yk) or Choudhury's (x, xprev, sprev, xss, stuck, d, pos);
# entry 3, the stick point, matters only while entry 4 says stuck.
RESTARTS = 4
STATE = 7
# Samples whose median is a stuck valve's position (as mismatch.fit.start_positions): it
# holds still, and one sample's noise would move its band with it.  The first sample
# alone is the other estimate: the median misplaces a valve that slips within them.
RESTART_SAMPLES = 10


@njit(cache=True)
def restart_position(y: Floats, i0: int, i1: int, c: int) -> float:
    """Return the position of restart ``c`` on ``[i0, i1)``: 0, a median, else ``y[i0]``."""
    if c != 0:
        return y[i0]
    # np.median of at most RESTART_SAMPLES values, by insertion sort: numba's own
    # median took 10 s to compile into the scan kernels, this takes a fraction of one.
    n = min(i1, i0 + RESTART_SAMPLES) - i0
    v = np.empty(n)
    for i in range(n):
        x = y[i0 + i]
        j = i
        while j > 0 and v[j - 1] > x:
            v[j] = v[j - 1]
            j -= 1
        v[j] = x
    h = n // 2
    return v[h] if n % 2 else 0.5 * (v[h - 1] + v[h])


@njit(cache=True)
def first_state(kernel_id: int, u0: float, y0: float, st: Floats) -> None:
    """Fill ``st``: the record's first segment, at rest at ``y0`` under its first input ``u0``."""
    if kernel_id == 0:
        st[0], st[1], st[2], st[3], st[4], st[5], st[6] = (u0, _clip(u0), _clip(u0), _clip(u0),
                                                           1.0, 0.0, y0)
    else:
        st[0], st[1], st[2], st[3], st[4], st[5], st[6] = u0, u0, 0.0, u0, 1.0, 0.0, y0


# Samples of the first rest between checks of its error against the caller's limit.
REST_CHECK = 64


@njit(cache=True)
def first_rest(kernel_id: int, u: Floats, y: Floats, i0: int, i1: int, S: float, J: float,
               f: float, limit: float, st: Floats) -> tuple[int, float, float]:
    """
    Run the record's valve on ``[i0, i1)`` until it first moves; return where, and its rest.

    Until its first move a model holds its start, and after it its position
    no longer depends on where it started: so the start that fits best is the
    mean of the samples before that move.  Return (first sample not yet scored,
    that mean, the rest's SSE about it); ``st`` receives the state there, the
    valve at rest at the mean or just moved.  Scoring stops once the SSE
    passes ``limit`` (then only a lower bound).  A pass of its own, so that
    the scoring loops run as they did without it.
    """
    fd = 0.5 * (S - J)
    c = y[i0]
    first_state(kernel_id, u[i0], c, st)
    # Sums of deviations from the first sample: exact where MV holds still.
    m, t1, t2, pos = 0, 0.0, 0.0, c
    k = i0
    while k < i1:
        pos = advance(kernel_id, st, u[k], S, J, f, fd)
        # Entry 5 of both models' states is the direction, 0 until the first move.
        if st[5] != 0.0:
            break
        e = y[k] - c
        m += 1
        t1 += e
        t2 += e * e
        k += 1
        if m % REST_CHECK == 0 and t2 - t1 * t1 / m > limit:
            return k, c + t1 / m, t2 - t1 * t1 / m
    mean = c + t1 / m if m else c
    sse = max(t2 - t1 * t1 / m, 0.0) if m else 0.0
    if k < i1:
        # The sample it moved on, scored here: its position no longer depends on the start.
        e = pos - y[k]
        sse += e * e
        k += 1
    else:
        st[6] = mean
    return k, mean, sse


@njit(cache=True)
def restart_state(kernel_id: int, c: int, u0: float, y0: float, st: Floats) -> None:
    """
    Fill ``st`` with restart ``c`` before a first input ``u0`` and measured position ``y0``.

    0, 1: stuck at ``y0`` with no friction force stored (the stick point at
    ``y0``, so breakaway at OP = y0 +- (S + J) / 2); 2, 3: moving up or down
    (the last input a step behind ``u0``).  The input filter has settled at
    ``u0`` in all of them, so that they can merge.
    """
    if c < 2:
        if kernel_id == 0:
            st[0], st[1], st[2], st[3], st[4], st[5], st[6] = (u0, _clip(u0), _clip(u0),
                                                               _clip(y0), 1.0, 0.0, y0)
        else:
            st[0], st[1], st[2], st[3], st[4], st[5], st[6] = u0, u0, 0.0, y0, 1.0, 0.0, y0
        return
    d = 1.0 if c == 2 else -1.0
    if kernel_id == 0:
        u1 = _clip(u0) - d
        st[0], st[1], st[2], st[3], st[4], st[5], st[6] = u0, u1, u1 - d, u1, 0.0, d, y0
    else:
        st[0], st[1], st[2], st[3], st[4], st[5], st[6] = u0, u0 - d, d, u0, 0.0, d, y0


@njit(cache=True)
def advance(kernel_id: int, st: Floats, uk: float, S: float, J: float, f: float,
            fd: float) -> float:
    """Advance the state ``st`` by one input ``uk`` (in place); return the position."""
    if kernel_id == 0:
        uf, u1, u2, us, resting, d, yk = _kano_step(uk, f, S, J, fd, st[0], st[1], st[2], st[3],
                                                    st[4] > 0.5, st[5], st[6])
        st[0], st[1], st[2], st[3], st[4], st[5], st[6] = (uf, u1, u2, us,
                                                           1.0 if resting else 0.0, d, yk)
        return yk
    x, xprev, sprev, xss, stuck, d, pos = _choudhury_step(uk, f, S, J, fd, st[0], st[1], st[2],
                                                          st[3], st[4] > 0.5, st[5], st[6])
    st[0], st[1], st[2], st[3], st[4], st[5], st[6] = (x, xprev, sprev, xss,
                                                       1.0 if stuck else 0.0, d, pos)
    return pos


# Of a state, the stick point (entry 3) counts only while stuck (entry 4).
_REST_ONLY = np.array([False, False, False, True, False, False, False])


@njit(cache=True)
def prune(cand: Floats, sse: Floats, alive: np.ndarray, rest: int, rest_only: np.ndarray) -> int:
    """
    Drop the worse of every two live restarts that merged; return the best one still alive.

    Two states merge when they will never differ again: equal in every entry but
    the ``rest_only`` ones (a stick point and the like), which count only while
    either state is at rest (entry ``rest`` > 0.5).  Shared by every model's
    restart (``kano_effects`` too), each with its own state layout.
    """
    n = cand.shape[0]
    for c in range(n):
        for c2 in range(c + 1, n):
            if not (alive[c] and alive[c2]):
                continue
            at_rest = cand[c, rest] > 0.5 or cand[c2, rest] > 0.5
            same = True
            for i in range(cand.shape[1]):
                if cand[c, i] != cand[c2, i] and (at_rest or not rest_only[i]):
                    same = False
                    break
            if same:
                alive[c2 if sse[c] <= sse[c2] else c] = False
    best = -1
    for c in range(n):
        if alive[c] and (best < 0 or sse[c] < sse[best]):
            best = c
    return best


@njit(cache=True)
def restart(kernel_id: int, u: Floats, y: Floats, i0: int, i1: int, S: float, J: float,
            f: float, bound: float, st: Floats) -> tuple[float, int, int]:
    """
    Score the restarts on ``[i0, i1)`` side by side until they merge into one.

    Return (SSE of the best so far, first sample not yet scored, its number);
    ``st`` receives its state there.  Of two merged restarts the one with the
    larger SSE can never win and is dropped; scoring stops once the best
    passes ``bound``.
    """
    fd = 0.5 * (S - J)
    cand = np.empty((RESTARTS, STATE))
    sse = np.zeros(RESTARTS)
    alive = np.ones(RESTARTS, dtype=np.bool_)
    for c in range(RESTARTS):
        restart_state(kernel_id, c, u[i0], restart_position(y, i0, i1, c), cand[c])
    best, k = 0, i0
    while k < i1 and alive.sum() > 1:
        for c in range(RESTARTS):
            if alive[c]:
                e = advance(kernel_id, cand[c], u[k], S, J, f, fd) - y[k]
                sse[c] += e * e
        best = prune(cand, sse, alive, 4, _REST_ONLY)
        k += 1
        if sse[best] > bound:
            break
    # Element by element: the slice assignment st[:] = cand[best] alone took 3.4 s to compile.
    for i in range(STATE):
        st[i] = cand[best, i]
    return sse[best], k, best


@njit(cache=True, nogil=True)
def kano_sse(u: Floats, y: Floats, starts: Ints, stops: Ints, S: float, J: float, a: float,
             limit: float) -> float:
    """Return the SSE of Kano's model (air-chamber pole ``a``) against ``y``, or > ``limit``."""
    fd = 0.5 * (S - J)
    sse = 0.0
    uf, u1, u2, us, resting, d, yk = 0.0, 0.0, 0.0, 0.0, True, 0.0, 0.0
    for s in range(starts.shape[0]):
        i0 = starts[s]
        k0 = i0
        if s == 0:
            st = np.empty(STATE)
            k0, _, sse = first_rest(0, u, y, i0, stops[0], S, J, a, limit, st)
            if sse > limit:
                return sse
            uf, u1, u2, us, resting, d, yk = (st[0], st[1], st[2], st[3], st[4] > 0.5, st[5],
                                              st[6])
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
    x, xprev, sprev, xss, stuck, d, pos = 0.0, 0.0, 0.0, 0.0, True, 0.0, 0.0
    for s in range(starts.shape[0]):
        i0 = starts[s]
        k0 = i0
        if s == 0:
            st = np.empty(STATE)
            k0, _, sse = first_rest(1, u, y, i0, stops[0], S, J, lam, limit, st)
            if sse > limit:
                return sse
            x, xprev, sprev, xss, stuck, d, pos = (st[0], st[1], st[2], st[3], st[4] > 0.5,
                                                   st[5], st[6])
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
            y0 = first_rest(kernel_id, u, y, i0, stops[0], S, J, f, np.inf, st)[1]
            first_state(kernel_id, u[i0], y0, st)
        elif input_known(u, stops[s - 1], i0):
            k0 = stops[s - 1]
        else:
            c = restart(kernel_id, u, y, i0, stops[s], S, J, f, np.inf, st)[2]
            restart_state(kernel_id, c, u[i0], restart_position(y, i0, stops[s], c), st)
        for k in range(k0, stops[s]):
            out[k] = advance(kernel_id, st, u[k], S, J, f, fd)

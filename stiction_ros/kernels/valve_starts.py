"""
Where the fits start a valve: the record's first rest, and restarts after a gap in OP.

A model at rest holds its start until its first move and forgets it after,
so the record's valve is started at the mean of the scored samples of that
first rest (:func:`first_rest`), the start that fits them best.  After a gap
in OP nothing carries the valve's state, and the next segment starts from
the best of four states at its first measured position (:func:`restart`;
``stiction_ros.analysis.fit_core`` says why).  A state is an array here
(:func:`advance`), which the scoring loops of :mod:`stiction_ros.kernels.sse`
unpack.
"""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats, Ints
from stiction_ros.kernels.valve_steps import _choudhury_step, _clip, _kano_step, input_known

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
def first_rest(kernel_id: int, u: Floats, y: Floats, starts: Ints, stops: Ints, S: float,
               J: float, f: float, limit: float, st: Floats) -> tuple[int, int, float, float]:
    """
    Run the record's valve until it first moves; return where, and the start that fits best.

    Until its first move a model holds its start, and after it its position
    no longer depends on where it started: so the start that fits best is the
    mean of the scored samples before that move, over the segments the valve
    runs on through (gaps where OP is known), up to a gap in OP (a restart).
    Return (segment to go on in, sample to go on from there, or -1 where that
    segment starts after a gap in OP, that mean, the SSE so far: the rest
    about its mean and the sample the valve moved on, if scored); ``st``
    receives the state there.  The SSE stops once past ``limit`` (then only
    a lower bound, and ``st`` halfway).  A pass of its own, so that the
    scoring loops run as they did without it.
    """
    n = starts.shape[0]
    fd = 0.5 * (S - J)
    c = y[starts[0]]
    first_state(kernel_id, u[starts[0]], c, st)
    # Sums of deviations from the first sample: exact where MV holds still.
    m, t1, t2, moved = 0, 0.0, 0.0, 0.0
    s_next, k_next, done = n, -1, False
    for s in range(n):
        if s > 0:
            if not input_known(u, stops[s - 1], starts[s]):
                s_next = s
                break
            for k in range(stops[s - 1], starts[s]):
                advance(kernel_id, st, u[k], S, J, f, fd)
                # Entry 5 of both models' states is the direction, 0 until the first move.
                if st[5] != 0.0:
                    s_next, k_next, done = s, k + 1, True
                    break
            if done:
                break
        for k in range(starts[s], stops[s]):
            pos = advance(kernel_id, st, u[k], S, J, f, fd)
            if st[5] != 0.0:
                # The sample it moved on, scored here: its position no longer depends on the start.
                s_next, k_next, done, moved = s, k + 1, True, (pos - y[k]) ** 2
                break
            e = y[k] - c
            m += 1
            t1 += e
            t2 += e * e
            if m % REST_CHECK == 0 and t2 - t1 * t1 / m > limit:
                return s, k + 1, c + t1 / m, t2 - t1 * t1 / m
        if done:
            break
    mean = c + t1 / m if m else c
    if st[5] == 0.0:
        st[6] = mean
    return s_next, k_next, mean, (max(t2 - t1 * t1 / m, 0.0) if m else 0.0) + moved


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

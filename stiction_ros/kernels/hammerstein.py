"""
Compiled kernels of the Hammerstein quantification (``analysis.hammerstein``).

A Kano valve's path before an ARX plant, scored for every (S, J) of a grid
and every dead time in one pass: the plant's regression is reduced once per
valve path by a rank-``nb`` update of a projection computed outside.  The
cross products behind it, most of the detector's time, are summed lag by lag,
each sum in a register (four regressors and two valve lags a pass), in the
order of the rows: the bits of the row-by-row loop
(:func:`lag_sums_reference`) in about 0.6 of its time as built ahead of
time, 0.35 under numba's build for the processor.  Each grid cell also gets
a bound on its SSE's rounding error (``_reduction``); the caller scores the
rare cells where it is large again by plain least squares.
"""

import math

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats, Ints
from stiction_ros.kernels.sse import kano_output


# The relative rounding of a reduced system's entry, in units of its column's sum of
# squares before the projection: 64 roundings of a double, a generous count of the
# terms that cancel into it.
ROUNDING = 64 * 2.0 ** -52

# (qv, tv, vv, sv) of (v, rows, row_seg, qy, tres, dlo, nl, nb, nseg).
LAG_SUMS_SIGNATURE = ('Tuple((f8[:, ::1], f8[::1], f8[:, ::1], f8[:, ::1]))'
                      '(f8[::1], i8[::1], i8[::1], f8[:, ::1], f8[::1], i8, i8, i8, i8)')


@njit(cache=True)
def _reduction(h: Floats, g: Floats, raw: Floats) -> tuple[float, float]:
    # g' H^-1 g by Cholesky; a pivot lost to round-off marks a column that
    # repeats the others (a valve that never moves), which explains nothing.
    # Also a bound on that sum's rounding error.  H is what is left of each
    # column's sum of squares before the projection (``raw``) after terms of
    # its size are subtracted, so a pivot holds about ROUNDING * raw of
    # rounding, and the share of its column's z^2 that is noise is that over
    # the pivot.  A valve path that the plant's own regressors nearly repeat
    # (a stuck valve integrated into a ramp, beside the ramp regressors) can
    # keep a pivot of pure rounding: z^2 then exceeded the whole sum of
    # squares, an SSE of 0 where least squares gives 58.5.
    m = g.shape[0]
    err = 0.0
    low = np.zeros((m, m))
    z = np.zeros(m)
    for i in range(m):
        for j in range(i + 1):
            s = h[i, j]
            for k in range(j):
                s -= low[i, k] * low[j, k]
            if i == j:
                if s <= 1e-10 * max(h[i, i], 1e-300):
                    low[i, i] = 0.0
                else:
                    low[i, i] = math.sqrt(s)
            elif low[j, j] > 0.0:
                low[i, j] = s / low[j, j]
        if low[i, i] > 0.0:
            s = g[i]
            for k in range(i):
                s -= low[i, k] * z[k]
            z[i] = s / low[i, i]
            err += z[i] * z[i] * min(1.0, ROUNDING * raw[i] / (low[i, i] * low[i, i]))
    return np.sum(z * z), err


@njit(cache=True, aot='f8[:](f8[::1], f8)')
def first_order_lag(u: Floats, a: float) -> Floats:
    """
    Return ``y[k] = (1 - a) u[k] + a y[k - 1]`` from rest: a unit-gain first-order lag.

    The same sums in the same order as ``scipy.signal.lfilter([1 - a], [1, -a], u)``,
    without importing scipy into the default analysis.
    """
    y = np.empty(u.shape[0])
    b = 1.0 - a
    prev = 0.0
    for k in range(u.shape[0]):
        prev = b * u[k] + a * prev
        y[k] = prev
    return y


@njit(cache=True, aot='f8[:](f8[::1], f8, f8, i8, f8)')
def segment_path(u: Floats, S: float, J: float, direction: int, fraction: float) -> Floats:
    """
    Return Kano's output for ``u`` from the start state (``direction``, ``fraction``).

    ``direction`` 0: at rest at ``u[0]`` with no direction, so breakaway
    needs (S + J) / 2 either way.  +1 or -1: at rest after moving that way,
    so it breaks away J onwards or S back from the OP where it stuck; that
    OP lies ``fraction`` (0 to 1) of the way across the band of stick points
    from which ``u[0]`` does not break it away.  Two samples of history in
    front of ``u`` put the model in that state.
    """
    if direction == 0:
        return kano_output(u, u[0], S, J, 0.0)
    stuck_at = u[0] - (J if direction > 0 else S) + fraction * (S + J)
    w = np.empty(u.shape[0] + 2)
    w[0] = stuck_at - direction * (S + J + 1.0)
    w[1] = stuck_at
    w[2:] = u
    return kano_output(w, w[0], S, J, 0.0)[2:]


@njit(cache=True)
def _valve_path(u: Floats, starts: Ints, stops: Ints, S: float, J: float, ubar: float,
                integrate: bool, start_dir: Ints, start_frac: Floats, v: Floats) -> None:
    # Centred so that the cross products below do not cancel catastrophically.
    for s in range(starts.shape[0]):
        a = starts[s]
        b = stops[s]
        v[a:b] = segment_path(u[a:b], S, J, start_dir[s], start_frac[s]) - ubar
        if integrate:
            v[a:b] = np.cumsum(v[a:b])


@njit(cache=True, aot=LAG_SUMS_SIGNATURE)
def lag_sums_reference(v: Floats, rows: Ints, row_seg: Ints, qy: Floats, tres: Floats,
                       dlo: int, nl: int, nb: int,
                       nseg: int) -> tuple[Floats, Floats, Floats, Floats]:
    """
    Return the cross products of the lags of ``v`` one row at a time, as first written.

    ``(qv, tv, vv, sv)``: each lag ``i`` of ``v`` (from ``dlo``) times each
    projected regressor, times the target's residual, times lags ``i`` to
    ``i + nb - 1`` (itself first), and summed over each segment's rows.
    Not used by the fits: the reference that :func:`lag_sums` gives to the
    bit (tests) and is timed against (``make bench-detector``).
    """
    p = qy.shape[1]
    qv = np.zeros((nl, p))
    tv = np.zeros(nl)
    vv = np.zeros((nl, nb))
    sv = np.zeros((nseg, nl))
    for r in range(rows.shape[0]):
        k = rows[r] - dlo
        s = row_seg[r]
        for i in range(nl):
            x = v[k - i]
            sv[s, i] += x
            tv[i] += x * tres[r]
            for c in range(p):
                qv[i, c] += x * qy[r, c]
            for m in range(min(nb, nl - i)):
                vv[i, m] += x * v[k - i - m]
    return qv, tv, vv, sv


@njit(cache=True, aot=LAG_SUMS_SIGNATURE)
def lag_sums(v: Floats, rows: Ints, row_seg: Ints, qy: Floats, tres: Floats, dlo: int, nl: int,
             nb: int, nseg: int) -> tuple[Floats, Floats, Floats, Floats]:
    """Return :func:`lag_sums_reference`'s sums, the same bits, as the fits compute them."""
    p = qy.shape[1]
    qv = np.zeros((nl, p))
    tv = np.zeros(nl)
    vv = np.zeros((nl, nb))
    sv = np.zeros((nseg, nl))
    # Four regressors and two valve lags a pass, each sum in a register (the
    # default orders take one pass); the first pass also sums tv and sv.
    for block in range(max(-(-p // 4), -(-nb // 2), 1)):
        _lag_sums_block(v, rows, row_seg, qy, tres, dlo, nl, nb, 4 * block, 2 * block,
                        qv, tv, vv, sv)
    return qv, tv, vv, sv


@njit(cache=True)
def _lag_sums_block(v: Floats, rows: Ints, row_seg: Ints, qy: Floats, tres: Floats, dlo: int,
                    nl: int, nb: int, c0: int, m0: int, qv: Floats, tv: Floats, vv: Floats,
                    sv: Floats) -> None:
    # Lag by lag, each sum over the rows in a local: every sum still adds its terms
    # in the order of the rows, from zero, as the loop over rows outside does.
    pb = min(qy.shape[1] - c0, 4)
    n = rows.shape[0]
    first = c0 == 0 and m0 == 0
    for i in range(nl):
        mb = min(nb, nl - i) - m0
        t, sa, q0, q1, q2, q3, w0, w1 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        seg = row_seg[0] if n > 0 else 0
        for r in range(n):
            k = rows[r] - dlo - i
            x = v[k]
            if first:
                if row_seg[r] != seg:
                    sv[seg, i] = sa
                    seg = row_seg[r]
                    sa = sv[seg, i]
                sa += x
                t += x * tres[r]
            if pb > 0:
                q0 += x * qy[r, c0]
                if pb > 1:
                    q1 += x * qy[r, c0 + 1]
                    if pb > 2:
                        q2 += x * qy[r, c0 + 2]
                        if pb > 3:
                            q3 += x * qy[r, c0 + 3]
            if mb > 0:
                w0 += x * v[k - m0]
                if mb > 1:
                    w1 += x * v[k - m0 - 1]
        if first:
            if n > 0:
                sv[seg, i] = sa
            tv[i] = t
        for c, value in enumerate((q0, q1, q2, q3)):
            if c < pb:
                qv[i, c0 + c] = value
        if mb > 0:
            vv[i, m0] = w0
        if mb > 1:
            vv[i, m0 + 1] = w1


@njit(cache=True)
def _best_delay(v: Floats, rows: Ints, row_seg: Ints, seg_rows: Floats, qy: Floats,
                tres: Floats, tt: float, dlo: int, dhi: int,
                nb: int) -> tuple[float, int, float]:
    # Cross products of every lag of v with the projected regressors, then
    # the SSE of each dead time from a small (nb x nb) system, and the largest
    # rounding bound of any dead time's SSE (_reduction).
    nl = dhi - dlo + nb
    p = qy.shape[1]
    nseg = seg_rows.shape[0]
    qv, tv, vv, sv = lag_sums(v, rows, row_seg, qy, tres, dlo, nl, nb, nseg)
    best = np.inf
    best_d = dlo
    h = np.empty((nb, nb))
    g = np.empty(nb)
    raw = np.empty(nb)
    doubt = 0.0
    for d in range(dhi - dlo + 1):
        for a in range(nb):
            g[a] = tv[d + a]
            raw[a] = vv[d + a, 0]
            for b in range(a, nb):
                x = vv[d + a, b - a]
                for s in range(nseg):
                    if seg_rows[s] > 0.0:
                        x -= sv[s, d + a] * sv[s, d + b] / seg_rows[s]
                for c in range(p):
                    x -= qv[d + a, c] * qv[d + b, c]
                h[a, b] = x
                h[b, a] = x
        reduction, err = _reduction(h, g, raw)
        doubt = max(doubt, err)
        sse = tt - reduction
        if sse < best:
            best = sse
            best_d = d + dlo
    return max(best, 0.0), best_d, doubt


@njit(cache=True, aot='Tuple((f8[:, ::1], i8[:, ::1], f8[:, ::1]))(f8[::1], f8, b1, '
                      'i8[::1], f8[::1], i8[::1], i8[::1], i8[::1], i8[::1], f8[::1], '
                      'f8[:, ::1], f8[::1], f8, f8[::1], f8[::1], i8, i8, i8)')
def _grid_sse(u: Floats, ubar: float, integrate: bool, start_dir: Ints, start_frac: Floats,
              starts: Ints, stops: Ints, rows: Ints, row_seg: Ints, seg_rows: Floats,
              qy: Floats, tres: Floats, tt: float, s_values: Floats, j_values: Floats, dlo: int,
              dhi: int, nb: int) -> tuple[Floats, Ints, Floats]:
    v = np.zeros(u.shape[0])
    sse = np.empty((s_values.shape[0], j_values.shape[0]))
    delay = np.empty((s_values.shape[0], j_values.shape[0]), dtype=np.int64)
    doubt = np.empty((s_values.shape[0], j_values.shape[0]))
    for i in range(s_values.shape[0]):
        for j in range(j_values.shape[0]):
            _valve_path(u, starts, stops, s_values[i], j_values[j], ubar, integrate, start_dir,
                        start_frac, v)
            sse[i, j], delay[i, j], doubt[i, j] = _best_delay(
                v, rows, row_seg, seg_rows, qy, tres, tt, dlo, dhi, nb)
    return sse, delay, doubt

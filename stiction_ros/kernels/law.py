"""
The R² of the controller's velocity-form law, fitted at a run of shifts (the timing check).

``analysis.detection.timing`` fits ``dOP = a dE + b E + c`` by least squares
at every shift of PV against OP and through every lag of its grid: a few
dozen fits of three columns on every record, and tens of thousands when the
check's thresholds are chosen again (``study.lag``, ``study.skew``).  As
``numpy.linalg.lstsq`` calls, the overhead of each call was most of that
time.  Here the rows that count at a shift are gathered once, then summed
for their means and again for the centred cross-products, and the
two-column projection gives the explained share in closed form.  The fitted
values of least squares are unique even where the columns are dependent, so
R² is too; the fallback below keeps that where the two centred columns are
(nearly) parallel.  test/test_law_kernel.py holds this to ``lstsq``.
"""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats

# Below this share of the product of their norms the centred columns count as
# parallel: the normal equations would then amplify rounding, and one column
# spans what both do.
_PARALLEL = 1e-12


@njit(cache=True, nogil=True,
      aot='f8[:](f8[::1], f8[::1], f8[::1], b1[::1], b1[::1], i8, i8, i8)')
def law_r2_shifts(d_op: Floats, d_e: Floats, e: Floats, free: np.ndarray, known: np.ndarray,
                  first: int, last: int, min_rows: int) -> Floats:
    """
    Return the law's R² with E taken ``k`` rows after OP, for ``k`` = ``first`` .. ``last``.

    A row counts where ``free`` holds for OP's row and ``known`` for E's.  NaN
    where fewer than ``min_rows`` rows count, or ``dOP`` does not vary on them.
    """
    n = d_op.shape[0]
    out = np.full(last - first + 1, np.nan)
    # The rows that count at a shift, gathered once: both passes read them.
    ys = np.empty(n)
    xa = np.empty(n)
    xb = np.empty(n)
    for k in range(first, last + 1):
        lo = max(0, -k)
        hi = min(n, n - k)
        if hi - lo < min_rows:
            continue
        m = 0
        for i in range(lo, hi):
            if free[i] and known[i + k]:
                ys[m] = d_op[i]
                xa[m] = d_e[i + k]
                xb[m] = e[i + k]
                m += 1
        if m < min_rows:
            continue
        my = 0.0
        m1 = 0.0
        m2 = 0.0
        for j in range(m):
            my += ys[j]
            m1 += xa[j]
            m2 += xb[j]
        my /= m
        m1 /= m
        m2 /= m
        syy = 0.0
        s11 = 0.0
        s12 = 0.0
        s22 = 0.0
        s1y = 0.0
        s2y = 0.0
        for j in range(m):
            y = ys[j] - my
            a = xa[j] - m1
            b = xb[j] - m2
            syy += y * y
            s11 += a * a
            s12 += a * b
            s22 += b * b
            s1y += a * y
            s2y += b * y
        if not syy > 0.0:
            continue
        det = s11 * s22 - s12 * s12
        if s11 > 0.0 and s22 > 0.0 and det > _PARALLEL * s11 * s22:
            explained = (s22 * s1y * s1y - 2.0 * s12 * s1y * s2y + s11 * s2y * s2y) / det
        else:
            explained = 0.0
            if s11 > 0.0:
                explained = s1y * s1y / s11
            if s22 > 0.0:
                explained = max(explained, s2y * s2y / s22)
        out[k - first] = max(0.0, min(1.0, explained / syy))
    return out

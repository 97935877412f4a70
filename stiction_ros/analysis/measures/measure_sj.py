"""
Read S and J off an MV-OP record the way an engineer reads the MV-OP map.

S is the input travel from where the valve stopped to where it broke away
after a reversal (the width of the stuck segment, chapter Fig. 1.5); J is the
jump of the output at breakaway.  The kinetic band ``fd`` is the lag of the
output behind the input while moving, so ``S - 2 fd`` must equal J for the
two-parameter models.  Sampling makes each breakaway overshoot its threshold
by less than one input increment, which bounds the error of S and J.
"""

import numpy as np


def stuck_runs(mv, tol):
    """Return (start, end) index pairs of runs where mv does not change (end inclusive)."""
    still = np.abs(np.diff(mv)) <= tol
    runs = []
    k = 0
    n = len(still)
    while k < n:
        if still[k]:
            j = k
            while j + 1 < n and still[j + 1]:
                j += 1
            runs.append((k + 1, j + 1))
            k = j + 1
        else:
            k += 1
    return runs


def measure_sj(op, mv, tol=1e-9):
    """
    Return dict(S, J, J_bands, fd, reversals, max_step) measured from reversals.

    ``J`` is the output jump at breakaway; ``J_bands = S - 2 fd`` reads it off
    the bands instead, which also works for a valve whose slip takes several
    samples (the physical model).  ``fd`` is the signed lag of the output
    behind the input while moving (negative when it overshoots, J > S).
    ``max_step`` is the largest input increment, the resolution of S and J.
    NaN values are returned when no stick-slip reversal is found.
    """
    op = np.asarray(op, dtype=np.float64)
    mv = np.asarray(mv, dtype=np.float64)
    s_vals, j_vals = [], []
    for a, b in stuck_runs(mv, tol):
        if a < 2 or b + 1 >= len(mv):
            continue
        before = np.sign(mv[a - 1] - mv[a - 2])
        after = np.sign(mv[b + 1] - mv[b])
        if before == 0 or after == 0 or before == after:
            continue
        u_s = op[a - 1]
        s_vals.append(abs(op[b + 1] - u_s))
        j_vals.append(abs(mv[b + 1] - mv[b]))
    moving = np.zeros(len(mv), dtype=bool)
    moving[1:] = np.abs(np.diff(mv)) > tol
    # Skip the first moving sample after each stop: it holds the jump.
    settled = moving.copy()
    settled[1:] &= moving[:-1]
    direction = np.zeros(len(mv))
    direction[1:] = np.sign(np.diff(mv))
    lag = direction[settled] * (op[settled] - mv[settled])
    fd = float(np.median(lag)) if settled.any() else np.nan
    s_med = float(np.median(s_vals)) if s_vals else np.nan
    return {
        'S': s_med,
        'J_bands': s_med - 2.0 * fd,
        'J': float(np.median(j_vals)) if j_vals else np.nan,
        'fd': fd,
        'reversals': len(s_vals),
        'max_step': float(np.max(np.abs(np.diff(op)))) if len(op) > 1 else 0.0,
    }

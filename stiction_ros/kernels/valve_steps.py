"""
One sample of the valve models the fits score, compiled: Kano's and Choudhury's.

The friction logic of ``stiction_ros.models.kano`` and
``stiction_ros.models.choudhury`` (percent input, linear characteristic),
written as functions of a state that travels as a tuple, so that numba keeps
it in registers in the scoring loops of :mod:`stiction_ros.kernels.sse`.
"""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats


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

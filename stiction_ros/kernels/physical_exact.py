"""
Compiled event-driven exact integrator of the physical valve (``integrator='exact'``).

Between friction events the stem, the I/P lag and the held input obey a
linear ODE with constant coefficients, so one sample of sliding is one
product with a tabulated matrix exponential, whatever the stiffness; stuck,
the breakaway instant is solved in closed form.  This is
``physical._run_exact`` (the pure-Python reference that the tests compare it
with) with the state in locals and the 5x5 product written out: rows 3 and 4
of every propagator are the identity (held pressure command, constant
friction force), so only rows 0-2 are computed.
"""

import math

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.physical_layout import (
    _A, _DP, _F0, _FC, _FS, _FV, _K, _PMIN, _TAU, _TS, _VSTICK, _XMAX)
from stiction_ros.kernels.physical_substep import load_state, store_state


@njit(cache=True, inline='always')
def _event(x: float, v: float, p: float, f: float, d: float, signwait: bool, xmax: float,
           A: float, k: float, Fv: float, vstick: float) -> bool:
    """Whether a stem sliding in direction ``d`` is past an event (stop, sign change, band)."""
    if x > xmax or x < 0.0:
        return True
    dv = d * v
    if dv < 0.0:
        return True
    if signwait or dv >= vstick:
        return False
    # The sign of the acceleration; M > 0 need not divide it.
    return d * (A * p - k * x - Fv * v + f) < 0.0


@njit(cache=True)
def run_exact(u: Floats, y: Floats, state: Floats, c: Floats, phis: Floats, hs: Floats, q: int,
              jmax: int) -> None:
    """Advance ``state`` over ``u``, writing positions into ``y`` (see the reference)."""
    A = c[_A]
    k = c[_K]
    Fv = c[_FV]
    F0 = c[_F0]
    xmax = c[_XMAX]
    tau = c[_TAU]
    Fc = c[_FC]
    Fs = c[_FS]
    ts = c[_TS]
    vstick = c[_VSTICK]
    pmin = c[_PMIN]
    dp = c[_DP]
    hmin = hs[jmax]
    ep_full = math.exp(-ts / tau) if tau > 0.0 else 0.0
    x, v, p, stuck, d, signwait = load_state(state, xmax)
    for i in range(u.shape[0]):
        ui = u[i]
        ui = 0.0 if ui < 0.0 else 100.0 if ui > 100.0 else ui
        pc = pmin + ui * 0.01 * dp
        if tau <= 0.0:
            p = pc
        t = 0.0
        while ts - t >= hmin:
            if stuck:
                rem = ts - t
                base = k * x + F0
                n0 = A * p - base
                tb = -1.0
                pb = p
                if n0 > Fs and x < xmax:
                    tb = 0.0
                    d = 1.0
                elif n0 < -Fs and x > 0.0:
                    tb = 0.0
                    d = -1.0
                elif tau > 0.0:
                    ninf = A * pc - base
                    if ninf > Fs and x < xmax:
                        pb = (base + Fs) / A
                        tb = tau * math.log((p - pc) / (pb - pc))
                        d = 1.0
                    elif ninf < -Fs and x > 0.0:
                        pb = (base - Fs) / A
                        tb = tau * math.log((p - pc) / (pb - pc))
                        d = -1.0
                if tb < 0.0 or tb >= rem:
                    if tau > 0.0:
                        # A whole sample at rest: the tabulated decay, no exp() call.
                        ep = ep_full if t == 0.0 else math.exp(-rem / tau)
                        p = pc + (p - pc) * ep
                    break
                t += tb
                p = pb
                v = 0.0
                stuck = False
                signwait = False
            f = -F0 - d * Fc
            while True:
                rem = ts - t
                j = q
                while hs[j] > rem and j < jmax:
                    j += 1
                if hs[j] > rem:
                    break
                P = phis[j]
                x1 = P[0, 0] * x + P[0, 1] * v + P[0, 2] * p + P[0, 3] * pc + P[0, 4] * f
                v1 = P[1, 0] * x + P[1, 1] * v + P[1, 2] * p + P[1, 3] * pc + P[1, 4] * f
                p1 = P[2, 0] * x + P[2, 1] * v + P[2, 2] * p + P[2, 3] * pc + P[2, 4] * f
                if not _event(x1, v1, p1, f, d, signwait, xmax, A, k, Fv, vstick):
                    x, v, p = x1, v1, p1
                    t += hs[j]
                    continue
                # Bisection: no event at (x, v, p) at time t, an event at (x1, v1, p1).
                for jj in range(j + 1, jmax + 1):
                    P = phis[jj]
                    xm = P[0, 0] * x + P[0, 1] * v + P[0, 2] * p + P[0, 3] * pc + P[0, 4] * f
                    vm = P[1, 0] * x + P[1, 1] * v + P[1, 2] * p + P[1, 3] * pc + P[1, 4] * f
                    pm = P[2, 0] * x + P[2, 1] * v + P[2, 2] * p + P[2, 3] * pc + P[2, 4] * f
                    if _event(xm, vm, pm, f, d, signwait, xmax, A, k, Fv, vstick):
                        x1, v1, p1 = xm, vm, pm
                    else:
                        x, v, p = xm, vm, pm
                        t += hs[jj]
                t += hmin
                x, v, p = x1, v1, p1
                if x > xmax or x < 0.0:
                    x = xmax if x > xmax else 0.0
                    v = 0.0
                    stuck = True
                elif abs(A * p - k * x - F0) <= Fs:
                    v = 0.0
                    stuck = True
                elif d * v < 0.0:
                    d = -d
                    signwait = False
                    f = -F0 - d * Fc
                else:
                    signwait = True
                if stuck:
                    break
            if not stuck:
                break
        y[i] = x / xmax * 100.0
    store_state(state, x, v, p, stuck, d, signwait, xmax)

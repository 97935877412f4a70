"""
Fixed-substep integrator of the physical valve, with the frictions the exact one cannot carry.

Semi-implicit steps of length ``dt`` (viscous friction implicit).  Besides
the reference role for the exact integrator, it carries the non-linear or
history-dependent friction laws of docs/EFFECTS.md:

- Stribeck: sliding friction ``Fc + (Fs - Fc) exp(-(v/vs)^2)``, so a stem
  driven slowly decelerates into the stick band again (stick-slip);
- dwell time: static friction ``Fs + dFs * t/(t + gamma)`` after ``t``
  seconds at rest (Armstrong-Helouvry), kinetic friction unchanged;
- asymmetry: every friction force is ``1 + asym`` times larger opening and
  ``1 - asym`` times closing (plug unbalance, gravity, packing).

numba compiles it when available: 10 000 substeps per sample are usual.
"""

import math

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.physical_layout import (
    _A, _ASYM, _DFS, _DP, _DT, _EP, _F0, _FC, _FOH, _FS, _FV, _GAMMA, _K, _M, _NSUB, _PMIN,
    _STRIB, _TAU, _VS, _VSTICK, _XMAX, S_DIR, S_P, S_REST, S_SIGNWAIT, S_STUCK, S_UPREV, S_V,
    S_X, S_Y)


@njit(cache=True)
def load_state(state: Floats, xmax: float) -> tuple[float, float, float, bool, float, bool]:
    """Return (x, v, p, stuck, direction, waiting-for-sign-change), put back inside the travel."""
    x = state[S_X]
    v = state[S_V]
    p = state[S_P]
    stuck = state[S_STUCK] > 0.5
    d = state[S_DIR]
    signwait = state[S_SIGNWAIT] > 0.5
    if x > xmax or x < 0.0:
        x = min(max(x, 0.0), xmax)
        v = 0.0
        stuck = True
    return x, v, p, stuck, d, signwait


@njit(cache=True)
def store_state(state: Floats, x: float, v: float, p: float, stuck: bool, d: float,
                signwait: bool, xmax: float) -> None:
    """Write the integrators' common state back (the output first, as base.py requires)."""
    state[S_Y] = x / xmax * 100.0
    state[S_X] = x
    state[S_V] = v
    state[S_P] = p
    state[S_STUCK] = 1.0 if stuck else 0.0
    state[S_DIR] = d
    state[S_SIGNWAIT] = 1.0 if signwait else 0.0


@njit(cache=True)
def run_substep(u: Floats, y: Floats, state: Floats, c: Floats) -> None:
    """Advance ``state`` over inputs ``u`` with fixed semi-implicit substeps; fill ``y``."""
    M = c[_M]
    A = c[_A]
    k = c[_K]
    F0 = c[_F0]
    xmax = c[_XMAX]
    tau = c[_TAU]
    Fc = c[_FC]
    Fs = c[_FS]
    Fv = c[_FV]
    vs = c[_VS]
    vstick = c[_VSTICK]
    dt = c[_DT]
    ep = c[_EP]
    nsub = int(c[_NSUB])
    stribeck = c[_STRIB] > 0.5
    dfs = c[_DFS]
    gamma = c[_GAMMA]
    asym = c[_ASYM]
    foh = c[_FOH] > 0.5
    uprev = state[S_UPREV]
    dtm = dt / M
    damp = 1.0 + dt * Fv / M
    x, v, p, stuck, d, signwait = load_state(state, xmax)
    rest = state[S_REST]
    for i in range(u.shape[0]):
        ui = u[i]
        ui = 0.0 if ui < 0.0 else 100.0 if ui > 100.0 else ui
        pc = c[_PMIN] + ui * 0.01 * c[_DP]
        p0 = c[_PMIN] + uprev * 0.01 * c[_DP]
        uprev = ui
        if tau <= 0.0:
            p = pc
        for j in range(nsub):
            if foh:
                # The command ramps from the previous input to this one over the sample.
                pj = p0 + (pc - p0) * (j + 1) / nsub
                if tau > 0.0:
                    p = pj + (p - pj) * ep
                else:
                    p = pj
            elif tau > 0.0:
                p = pc + (p - pc) * ep
            n = A * p - k * x - F0
            if stuck:
                fs_now = Fs + dfs * rest / (rest + gamma) if dfs > 0.0 else Fs
                if n > fs_now * (1.0 + asym) and x < xmax:
                    d = 1.0
                elif n < -fs_now * (1.0 - asym) and x > 0.0:
                    d = -1.0
                else:
                    rest += dt
                    continue
                stuck = False
                signwait = False
                v = 0.0
                rest = 0.0
            ff = Fc
            if stribeck:
                r = v / vs
                ff = Fc + (Fs - Fc) * math.exp(-r * r)
            ff *= 1.0 + asym * d
            vn = (v + dtm * (n - d * ff)) / damp
            xn = x + dt * vn
            if xn > xmax or xn < 0.0:
                x = xmax if xn > xmax else 0.0
                v = 0.0
                stuck = True
                continue
            dv = d * vn
            event = dv < 0.0 or (not signwait and dv < vstick and dv < d * v)
            x = xn
            v = vn
            if event:
                nn = A * p - k * x - F0
                if -Fs * (1.0 - asym) <= nn <= Fs * (1.0 + asym):
                    v = 0.0
                    stuck = True
                elif dv < 0.0:
                    d = -d
                    signwait = False
                else:
                    signwait = True
        y[i] = x / xmax * 100.0
    store_state(state, x, v, p, stuck, d, signwait, xmax)
    state[S_REST] = rest
    state[S_UPREV] = uprev

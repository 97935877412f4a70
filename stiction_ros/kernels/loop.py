"""
Compiled offline closed loop: controller, valve and plant in one numba loop.

``closed_loop.simulate_loop`` runs its first sample with the Python objects
(which set up the valve's state from the first OP), then hands the rest to
:func:`run_loop` with every state unpacked into arrays, and packs them back
at the end.  The arithmetic is the objects' own, in the same order, and the
valve is the model's own compiled kernel, so the two paths agree sample for
sample (``test_closed_loop.py``); the per-sample Python loop stays as the
reference (``simulate_loop(..., compiled=False)``).

Valve kernels are dispatched by a kind code (``ValveModel.loop_args``);
numba compiles each branch once.
"""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.kano_effects import kano_effects_run
from stiction_ros.kernels.loop_kinds import (
    CHOUDHURY, HE, KANO, LINEAR, PHYSICAL_EXACT, PHYSICAL_SUBSTEP, STENMAN)
from stiction_ros.kernels.physical_exact import run_exact
from stiction_ros.kernels.physical_substep import run_substep
from stiction_ros.kernels.plant import plant_advance_into, plant_output
from stiction_ros.kernels.valves import choudhury_run, he_run, kano_run, stenman_run


# PID constants and state, as indices into the arrays handed to run_loop.
P_KC, P_TI, P_TD, P_N, P_TS, P_MIN, P_MAX, P_BIAS, P_SIGN = range(9)
C_I, C_D, C_PVPREV, C_HAVEPREV, C_OP = range(5)
# Plant scalars: time (s) and the previous sample's input deviation.
T_TIME, T_LAST = range(2)


@njit(cache=True)
def valve_step(kind: int, u1: Floats, y1: Floats, st: Floats, fp: Floats, arr: Floats,
               phis: Floats, hs: Floats, q: int, jmax: int) -> None:
    """Advance the valve one sample: ``y1[0]`` from ``u1[0]``; ``st`` updated in place."""
    if kind == KANO:
        kano_run(u1, y1, st, fp[0], fp[1], fp[2])
    elif kind == CHOUDHURY:
        choudhury_run(u1, y1, st, fp[0], fp[1], fp[2], fp[3] > 0.5, int(fp[4]), fp[5],
                      fp[6] > 0.5)
    elif kind == HE:
        he_run(u1, y1, st, fp[0], fp[1])
    elif kind == STENMAN:
        stenman_run(u1, y1, st, fp[0])
    elif kind == LINEAR:
        uk = u1[0]
        st[0] = 0.0 if uk < 0.0 else 100.0 if uk > 100.0 else uk
        y1[0] = st[0]
    elif kind == PHYSICAL_EXACT:
        run_exact(u1, y1, st, arr, phis, hs, q, jmax)
    elif kind == PHYSICAL_SUBSTEP:
        run_substep(u1, y1, st, arr)
    else:
        kano_effects_run(u1, y1, st, fp[0], fp[1], arr)


@njit(cache=True)
def hold_input(u: float, phi: Floats, x: Floats, xn: Floats, g0: Floats, g1: Floats,
               hist: Floats, hpos: int, m: int, fractional: bool) -> int:
    """
    Advance the sampled plant one sample with input deviation ``u`` held over it.

    ``hist`` is the ring of the last ``m + 1`` inputs (dead time), the newest
    at ``hpos``; ``x`` is updated in place (``xn`` is scratch).  Returns the
    new ring position.
    """
    size = m + 1
    now = u if m == 0 else hist[(hpos + m - 1) % size]
    older = hist[(hpos + m) % size]
    plant_advance_into(phi, x, g0, now, g1, older, fractional, xn)
    x[:] = xn
    hpos = (hpos - 1) % size
    hist[hpos] = u
    return hpos


@njit(cache=True)
def run_loop(k0: int, k1: int, sp: Floats, op_open: Floats, pp: Floats, pc: Floats, kind: int,
             fp: Floats, st: Floats, arr: Floats, phis: Floats, hs: Floats, q: int, jmax: int,
             phi: Floats, g0: Floats, g1: Floats, cvec: Floats, dfeed: float, m: int,
             fractional: bool, x: Floats, hist: Floats, hpos: int, ps: Floats, pv0: float,
             mv0: float, dist_t: Floats, dist_v: Floats, noise: Floats, out_op: Floats,
             out_mv: Floats, out_pv: Floats) -> int:
    """
    Run samples ``k0 <= k < k1``; return the new ring position of ``hist``.

    ``hist`` holds the last ``m + 1`` input deviations, the newest at
    ``hpos``; ``op_open`` is used instead of the controller when it is not
    empty.  ``pc``, ``st``, ``x`` and ``ps`` are updated in place.
    """
    u1 = np.empty(1)
    y1 = np.empty(1)
    xn = np.empty(x.shape[0])
    size = m + 1
    ts = pp[P_TS]
    sign = pp[P_SIGN]
    for k in range(k0, k1):
        # Plant output (PV at this instant).
        if fractional:
            held = hist[(hpos + m) % size]
        elif m > 0:
            held = hist[(hpos + m - 1) % size]
        else:
            held = ps[T_LAST]
        pv = plant_output(cvec, x, dfeed, held, pv0)
        for i in range(dist_t.shape[0]):
            if ps[T_TIME] >= dist_t[i] - 1e-9 * ts:
                pv += dist_v[i]
        pv += noise[k]
        # Controller (the PID class's update, same order of operations).
        if op_open.shape[0] > 0:
            op = op_open[k]
        else:
            e = sign * (sp[k] - pv)
            if pp[P_TD] > 0.0 and pc[C_HAVEPREV] > 0.5:
                a = pp[P_TD] / (pp[P_TD] + pp[P_N] * ts)
                pc[C_D] = a * pc[C_D] - sign * pp[P_KC] * pp[P_N] * a * (pv - pc[C_PVPREV])
            pc[C_PVPREV] = pv
            pc[C_HAVEPREV] = 1.0
            raw = pp[P_BIAS] + pp[P_KC] * e + pc[C_I] + pc[C_D]
            op = min(max(raw, pp[P_MIN]), pp[P_MAX])
            if pp[P_TI] > 0.0:
                di = pp[P_KC] * ts / pp[P_TI] * e
                if (op == raw or (raw > pp[P_MAX] and di < 0.0)
                        or (raw < pp[P_MIN] and di > 0.0)):
                    pc[C_I] += di
            pc[C_OP] = op
        # Valve.
        u1[0] = op
        valve_step(kind, u1, y1, st, fp, arr, phis, hs, q, jmax)
        mv = y1[0]
        # Plant update: hold MV over the next sample.
        u = mv - mv0
        hpos = hold_input(u, phi, x, xn, g0, g1, hist, hpos, m, fractional)
        ps[T_LAST] = u
        ps[T_TIME] += ts
        out_op[k] = op
        out_mv[k] = mv
        out_pv[k] = pv
    return hpos

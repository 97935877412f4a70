"""
Compiled closed loop of the training corpus: sensor, PI, valve and plant in one loop.

One sample runs in the order a sampled loop does: the transmitter reads PV
(plant output plus load, then noise, faults, resolution), the PI computes OP,
the valve moves, and MV is held over the sample while the plant advances
(zero-order hold; an integer dead time as a ring of past MV and a fractional
remainder as a second held segment, as in ``stiction_ros.sim.plant``).  Valves are
the project's compiled one-sample kernels (``loop_kernel.valve_step``) plus a
positioner with a finite resolution, which the project has no model for.  The
plant sees the flow of the valve's installed characteristic, and the PI may act
on its error through a level controller's nonlinear law (gap or error squared).

:func:`loop_matrix` is the same loop linearised (no clamps, ideal valve), so
that scenario drawing can place the closed-loop poles before simulating.
"""

import math

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats
from stiction_ros.kernels.loop import hold_input, valve_step
from stiction_ros.kernels.plant import plant_output

# Outside the range of ``loop_kinds`` so that it can never reach valve_step.
QUANTISED = -1
# PI constants and sensor settings, as indices into the arrays of run_corpus_loop.
P_KC, P_KI, P_SIGN, P_BIAS, P_LAW, P_GAP, P_INNER = range(7)
S_PV0, S_MV0, S_RES, S_FREEZE0, S_FREEZE1, S_RANGE = range(6)
# Controller laws (``pid[P_LAW]``): plain PI, a gap with less gain inside, error squared.
LAW_PI, LAW_GAP, LAW_SQUARED = range(3)


@njit(cache=True)
def _quantise(value: float, step: float) -> float:
    # Rounds half away from zero, like a transmitter's or historian's display.
    if step <= 0.0:
        return value
    return step * np.floor(value / step + 0.5)


@njit(cache=True)
def installed_flow(mv: float, mv0: float, rangeability: float) -> float:
    """
    Return the flow change of an equal-percentage valve moved from ``mv0`` to ``mv`` (%).

    Scaled to unit slope at ``mv0``, so that a loop tuned at its operating
    point keeps that tuning there; its gain grows ``rangeability`` times over
    the whole travel as the valve opens.  A rangeability of 1 or less is a
    linear valve.
    """
    if rangeability <= 1.0:
        return mv - mv0
    ln_r = math.log(rangeability)
    return 100.0 / ln_r * (math.exp(ln_r * (mv - mv0) / 100.0) - 1.0)


@njit(cache=True)
def controller_law(e: float, law: int, gap: float, inner: float) -> float:
    """
    Return the error the PI acts on under a level controller's ``law``.

    A gap controller has ``inner`` times its gain while ``|e| < gap`` and
    its full gain outside, continuous at the gap; error squared scales the
    gain by ``|e| / gap`` up to the full gain at the gap (as a DCS scales it
    by the error's share of span, which never exceeds 1), so that neither law
    is ever hotter than the PI tuned at the set point.  Both let a level
    swing in its tank (averaging control), which a plain PI would hold tight.
    """
    if law == LAW_GAP:
        if abs(e) < gap:
            return inner * e
        return e - math.copysign((1.0 - inner) * gap, e)
    if law == LAW_SQUARED:
        return e * min(abs(e) / gap, 1.0)
    return e


@njit(cache=True)
def run_corpus_loop(sp: Floats, op_open: Floats, pv_load: Floats, pv_meas: Floats, pid: Floats,
                    sens: Floats, kind: int, fp: Floats, st: Floats, arr: Floats, phis: Floats,
                    hs: Floats, q: int, jmax: int, quantum: float, phi: Floats, g0: Floats,
                    g1: Floats, c: Floats, m: int, fractional: bool, out_op: Floats,
                    out_mv: Floats, out_pv: Floats) -> None:
    """
    Run the loop over ``sp.shape[0]`` samples, writing OP, MV and measured PV.

    ``sp`` is the set point and ``pv_load`` the load on the plant output (PV
    units, before the sensor); ``pv_meas`` the additive measurement error
    (noise, spikes, drift); ``op_open`` OP to apply instead of the PI (open
    loop) or empty.  ``pid`` holds ``Kc``, ``Kc ts / Ti``, the action sign (+1
    reverse, -1 direct), the bias, the law (:func:`controller_law`), its gap
    and inner gain; ``sens`` holds ``pv0``, ``mv0``, the PV resolution (0 =
    none), the frozen stretch (from, to sample) and the valve's rangeability
    (:func:`installed_flow`).  ``kind``
    to ``jmax`` are the valve (``ValveModel.loop_args`` and ``state``, which is
    updated in place); ``kind == QUANTISED`` rounds OP to ``quantum``.
    ``phi`` to ``fractional`` are the sampled plant (``TransferFunctionPlant``),
    started at rest at ``mv0`` (zero state, all past MV equal to ``mv0``).
    """
    n = sp.shape[0]
    u1 = np.empty(1)
    y1 = np.empty(1)
    x = np.zeros(phi.shape[0])
    xn = np.empty(phi.shape[0])
    hist = np.zeros(m + 1)
    hpos = 0
    integral = 0.0
    frozen = 0.0
    pv0 = sens[S_PV0]
    mv0 = sens[S_MV0]
    sign = pid[P_SIGN]
    law = int(pid[P_LAW])
    for k in range(n):
        # Strictly proper plants only: no feedthrough of the held input.
        pv = plant_output(c, x, 0.0, 0.0, pv0) + pv_load[k] + pv_meas[k]
        pv = _quantise(pv, sens[S_RES])
        if sens[S_FREEZE0] <= k < sens[S_FREEZE1]:
            pv = frozen
        else:
            frozen = pv
        if op_open.shape[0] > 0:
            op = op_open[k]
        else:
            e = sign * controller_law(sp[k] - pv, law, pid[P_GAP], pid[P_INNER])
            raw = pid[P_BIAS] + pid[P_KC] * e + integral
            op = min(max(raw, 0.0), 100.0)
            di = pid[P_KI] * e
            # Conditional integration: a saturated output stops winding up but
            # may still unwind.
            if op == raw or (raw > 100.0 and di < 0.0) or (raw < 0.0 and di > 0.0):
                integral += di
        if kind == QUANTISED:
            mv = _quantise(min(max(op, 0.0), 100.0), quantum)
            # Stay on the grid when 100 % is not a multiple of the quantum.
            if mv > 100.0:
                mv -= quantum
        else:
            u1[0] = op
            valve_step(kind, u1, y1, st, fp, arr, phis, hs, q, jmax)
            mv = y1[0]
        flow = installed_flow(mv, mv0, sens[S_RANGE])
        hpos = hold_input(flow, phi, x, xn, g0, g1, hist, hpos, m, fractional)
        out_op[k] = op
        out_mv[k] = mv
        out_pv[k] = pv


def loop_matrix(phi: Floats, g0: Floats, g1: Floats, c: Floats, m: int, fractional: bool,
                kc: float, ki: float, sign: float) -> Floats:
    """
    Return the state matrix of the linearised closed loop (ideal valve, no clamps).

    The state is the plant state, the last ``m + 1`` MV deviations (newest
    first) and the integral term, in the order :func:`run_corpus_loop` updates
    them, so its eigenvalues are the loop's discrete poles.
    """
    n = phi.shape[0]
    h = n
    i = n + m + 1
    a = np.zeros((i + 1, i + 1))
    # MV deviation computed from the state: u = -sign Kc c x + I.
    urow = np.zeros(i + 1)
    urow[:n] = -sign * kc * c
    urow[i] = 1.0
    a[:n, :n] = phi
    if m == 0:
        a[:n] += np.outer(g0, urow)
    else:
        a[:n, h + m - 1] += g0
    if fractional:
        a[:n, h + m] += g1
    a[h] = urow
    for j in range(1, m + 1):
        a[h + j, h + j - 1] = 1.0
    a[i, :n] = -sign * ki * c
    a[i, i] = 1.0
    return a


def min_damping(matrix: Floats) -> tuple[float, float]:
    """
    Return the smallest damping ratios of the slow and of the fast poles of ``matrix``.

    A pole ``z`` maps to ``s = ln z`` per sample.  Slow poles turn by at
    most a quarter turn per sample (period of 4 samples or more), the
    ringing a tuning causes; fast ones alternate nearly sample by sample,
    which a real controller running faster than the historian would not
    show.  Poles inside radius 0.5 die out within a few samples whatever
    their angle (dead-time poles of a detuned loop sit there), so they count
    as fully damped; a pole on or outside the unit circle gives zero or less.
    """
    z = np.linalg.eigvals(matrix)
    z = z[np.abs(z) >= 0.5]
    s = np.log(z.astype(complex))
    zeta = -s.real / np.maximum(np.abs(s), 1e-300)
    slow = np.abs(s.imag) <= 0.5 * np.pi
    low = float(zeta[slow].min()) if slow.any() else 1.0
    high = float(zeta[~slow].min()) if (~slow).any() else 1.0
    return low, high

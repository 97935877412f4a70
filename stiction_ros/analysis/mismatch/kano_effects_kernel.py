"""
Kano's model with the physics of docs EFFECTS.md switched on by parameters.

One compiled step serves the simulator (``kano_effects_output``) and the fits
(``kano_effects_sse``), so the model that explains a recording is the model
that generated the concealed test cases.  Every extra parameter at zero gives
Kano's plain model sample for sample (tested), which makes the candidates
nested.  The parameter vector ``p`` is indexed by the constants below:

- ``A_IN``: pole of a first-order lag on OP before the friction (actuator_lag);
- ``B_OUT``: pole of a first-order lag on the position after it (measurement_lag);
- ``ASYM``: friction forces scale by (1 + ASYM) opening and (1 - ASYM) closing, so
  the kinetic band (S - J)/2 and static band (S + J)/2 of each direction do, and a
  reversal from direction d needs (S - J)/2 (1 + ASYM d) + (S + J)/2 (1 - ASYM d);
- ``DWELL``, ``DWELL_TAU``: the static band grows by DWELL * S * r / (r + DWELL_TAU)
  after r samples at rest (Armstrong-Helouvry's dwell law; kinetic band unchanged);
- ``POS``, ``POS_REF``: S and J scale by 1 + POS * (y - POS_REF) / 50;
- ``DRIFT``, ``DRIFT_MID``, ``DRIFT_SPAN``: S and J scale by
  1 + DRIFT * (k - DRIFT_MID) / DRIFT_SPAN at sample k;
- ``STRIBECK``: a moving valve sticks again when the input moves less than
  this (% per sample), the velocity-weakening friction of a Stribeck curve;
- ``CREEP``: at rest the position follows CREEP * (u - u_s): pre-sliding
  deflection, bounded by the stick band and undone on reversal.
"""

import numpy as np

from stiction_ros.analysis.sse_kernels import _clip, njit

(A_IN, B_OUT, ASYM, DWELL, DWELL_TAU, POS, POS_REF, DRIFT, DRIFT_MID, DRIFT_SPAN,
 STRIBECK, CREEP) = range(12)
N_PARAMS = 12


def plain_params():
    """Return the parameter vector of the plain model (every effect off)."""
    p = np.zeros(N_PARAMS)
    p[DWELL_TAU] = 1.0
    p[POS_REF] = 50.0
    p[DRIFT_SPAN] = 1.0
    return p


@njit(cache=True)
def _scale(p, d, y, k):
    m = 1.0 + p[ASYM] * d + p[POS] * (y - p[POS_REF]) / 50.0
    m += p[DRIFT] * (k - p[DRIFT_MID]) / p[DRIFT_SPAN]
    return m if m > 0.0 else 0.0


@njit(cache=True)
def _breakaway_fx(d, rel, S, J, p, y, k, rest):
    # Kano's breakaway with the band of the direction the valve would move in.
    grow = 0.0
    if p[DWELL] != 0.0:
        grow = p[DWELL] * S * rest / (rest + p[DWELL_TAU])
    if d == 0.0:
        nd = 1.0 if rel > 0.0 else -1.0
        m = _scale(p, nd, y, k)
        if abs(rel) > 0.5 * (S + J) * m + grow:
            return nd
        return 0.0
    m_old = _scale(p, d, y, k)
    m_new = _scale(p, -d, y, k)
    # Reversing, the input first undoes the kinetic friction of the old direction,
    # then overcomes the static friction of the new one: (S-J)/2 + (S+J)/2 = S when
    # both directions are alike.
    if -d * rel > 0.5 * (S - J) * m_old + 0.5 * (S + J) * m_new + grow:
        return -d
    if d * rel > J * m_old + grow:
        return d
    return 0.0


@njit(cache=True)
def _step(uraw, k, S, J, p, uf, u1, u2, us, resting, d, yk, ym, since, yrest):
    uf = p[A_IN] * uf + (1.0 - p[A_IN]) * uraw
    uk = _clip(uf)
    if not resting and ((uk - u1) * (u1 - u2) <= 0.0 or abs(uk - u1) < p[STRIBECK]):
        us = u1
        resting = True
        since = k
        yrest = yk
    if resting:
        nd = _breakaway_fx(d, uk - us, S, J, p, yk, k, float(k - since))
        if nd != 0.0:
            d = nd
            resting = False
    if resting:
        yk = _clip(yrest + p[CREEP] * (uk - us))
    else:
        m = _scale(p, d, yk, k)
        yk = _clip(uk - d * 0.5 * (S - J) * m)
    ym = p[B_OUT] * ym + (1.0 - p[B_OUT]) * yk
    return uf, uk, u1, us, resting, d, yk, ym, since, yrest


@njit(cache=True)
def _at_rest(u0, k, y0):
    # The state of a valve resting at y0 with no friction force stored, before sample k.
    u1 = _clip(u0)
    return u0, u1, u1, u1, True, 0.0, y0, y0, k, y0


@njit(cache=True)
def kano_effects_sse(u, y, starts, stops, y0s, S, J, p, limit):
    """
    Return the SSE against ``y`` over the segments, or a number > ``limit`` once past it.

    Segment ``s`` starts at rest at position ``y0s[s]``.
    """
    sse = 0.0
    for s in range(starts.shape[0]):
        i0 = starts[s]
        uf, u1, u2, us, resting, d, yk, ym, since, yrest = _at_rest(u[i0], i0, y0s[s])
        for k in range(i0, stops[s]):
            uf, u1, u2, us, resting, d, yk, ym, since, yrest = _step(
                u[k], k, S, J, p, uf, u1, u2, us, resting, d, yk, ym, since, yrest)
            e = ym - y[k]
            sse += e * e
            if sse > limit:
                return sse
    return sse


@njit(cache=True)
def kano_effects_grid(u, y, starts, stops, y0s, s_values, j_values, p, limit):
    """Return the SSE of every (S, J) on a grid with the effect parameters ``p``."""
    out = np.empty((s_values.shape[0], j_values.shape[0]))
    for i in range(s_values.shape[0]):
        for j in range(j_values.shape[0]):
            out[i, j] = kano_effects_sse(u, y, starts, stops, y0s, s_values[i], j_values[j],
                                         p, limit)
    return out


@njit(cache=True)
def kano_effects_output(u, starts, stops, y0s, S, J, p, out, resting_out):
    """Write the model's position into ``out`` (and 1.0 where at rest into ``resting_out``)."""
    for s in range(starts.shape[0]):
        i0 = starts[s]
        uf, u1, u2, us, resting, d, yk, ym, since, yrest = _at_rest(u[i0], i0, y0s[s])
        for k in range(i0, stops[s]):
            uf, u1, u2, us, resting, d, yk, ym, since, yrest = _step(
                u[k], k, S, J, p, uf, u1, u2, us, resting, d, yk, ym, since, yrest)
            out[k] = ym
            resting_out[k] = 1.0 if resting else 0.0


@njit(cache=True)
def kano_effects_run(u, out, st, S, J, p):
    """
    Advance the model over ``u`` from the state array ``st`` (updated in place).

    ``st`` = [position seen (after any measurement lag), u(k-1), u(k-2), u_s,
    resting, direction, position, lagged input, rest start, rest position,
    sample counter]; ``stiction_ros.models.kano_effects`` builds it.
    """
    ym, u1, u2, us, resting, d, yk, uf, since, yrest, k = (
        st[0], st[1], st[2], st[3], st[4] > 0.5, st[5], st[6], st[7], st[8], st[9], st[10])
    for i in range(u.shape[0]):
        uf, u1, u2, us, resting, d, yk, ym, since, yrest = _step(
            u[i], k, S, J, p, uf, u1, u2, us, resting, d, yk, ym, since, yrest)
        out[i] = ym
        k += 1.0
    st[0], st[1], st[2], st[3], st[4], st[5] = ym, u1, u2, us, 1.0 if resting else 0.0, d
    st[6], st[7], st[8], st[9], st[10] = yk, uf, since, yrest, k

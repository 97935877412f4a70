"""
Kano's model with the physics of docs/EFFECTS.md switched on by parameters.

One compiled loop serves the simulator (``kano_effects_run``, ``kano_effects_output``)
and the fits (``kano_effects_sse``), so the model that explains a recording is the model
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

The ASYM, POS and DRIFT terms add into one multiplier of the bands,
``1 + ASYM d + POS (y - POS_REF) / 50 + DRIFT (k - DRIFT_MID) / DRIFT_SPAN``,
floored at zero; they do not multiply one another.  A restart in the
direction the valve last moved needs ``J`` times that multiplier (Kano's
rule), a first move from rest ``(S + J) / 2`` times it; the dwell growth
adds to each.
"""

import numpy as np

from stiction_ros._jit import njit
from stiction_ros.kernels.arrays import Floats, Ints
from stiction_ros.kernels.sse import insert_best
from stiction_ros.kernels.valve_starts import prune, RESTARTS
from stiction_ros.kernels.valve_steps import input_known

(A_IN, B_OUT, ASYM, DWELL, DWELL_TAU, POS, POS_REF, DRIFT, DRIFT_MID, DRIFT_SPAN,
 STRIBECK, CREEP) = range(12)
N_PARAMS = 12


@njit(cache=True, inline='always')
def _clip(x: float) -> float:
    return 0.0 if x < 0.0 else 100.0 if x > 100.0 else x


def plain_params() -> Floats:
    """Return the parameter vector of the plain model (every effect off)."""
    p = np.zeros(N_PARAMS)
    p[DWELL_TAU] = 1.0
    p[POS_REF] = 50.0
    p[DRIFT_SPAN] = 1.0
    return p


@njit(cache=True, inline='always')
def _scale(p: Floats, d: float, y: float, k: float, plain: bool) -> float:
    # ``plain``: ASYM, POS and DRIFT are all zero, so m is exactly 1 while y and k
    # are finite, which the callers' inputs are (NaN and infinity never reach a
    # fit or a run; the old sum would have carried a NaN on, this does not).
    # Skipping it takes two divisions off the chain from one sample's position to
    # the next: the fits of the other effects run faster.
    if plain:
        return 1.0
    m = 1.0 + p[ASYM] * d + p[POS] * (y - p[POS_REF]) / 50.0
    m += p[DRIFT] * (k - p[DRIFT_MID]) / p[DRIFT_SPAN]
    return m if m > 0.0 else 0.0


@njit(cache=True, inline='always')
def _breakaway_fx(d: float, rel: float, S: float, J: float, p: Floats, y: float, k: float,
                  rest: float, plain: bool) -> float:
    # Kano's breakaway with the band of the direction the valve would move in.
    grow = 0.0
    if p[DWELL] != 0.0:
        grow = p[DWELL] * S * rest / (rest + p[DWELL_TAU])
    if d == 0.0:
        nd = 1.0 if rel > 0.0 else -1.0
        m = _scale(p, nd, y, k, plain)
        if abs(rel) > 0.5 * (S + J) * m + grow:
            return nd
        return 0.0
    m_old = _scale(p, d, y, k, plain)
    m_new = _scale(p, -d, y, k, plain)
    # Reversing, the input first undoes the kinetic friction of the old direction,
    # then overcomes the static friction of the new one: (S-J)/2 + (S+J)/2 = S when
    # both directions are alike.
    if -d * rel > 0.5 * (S - J) * m_old + 0.5 * (S + J) * m_new + grow:
        return -d
    if d * rel > J * m_old + grow:
        return d
    return 0.0


# The state of one run, as kano_effects_run's callers hold it between calls.
(ST_YM, ST_U1, ST_U2, ST_US, ST_RESTING, ST_D, ST_YK, ST_UF, ST_SINCE, ST_YREST,
 ST_K) = range(11)
STATE_SIZE = 11


@njit(cache=True)
def _segment(u: Floats, y: Floats, i0: int, i1: int, S: float, J: float, p: Floats, st: Floats,
             sse: float, limit: float, out: Floats, resting_out: Floats) -> float:
    # The one loop behind the fits, the outputs and the simulator.  Written out
    # with the state in locals rather than as a step function returning a tuple:
    # numba kept that 10-tuple in memory, three times slower per sample.
    # With ``y`` non-empty it returns ``sse`` plus this stretch's squared errors
    # (stopping once past ``limit``); with ``out`` non-empty it writes the position
    # there, and the resting flag into ``resting_out`` when that is non-empty.
    score, write, flags = y.shape[0] > 0, out.shape[0] > 0, resting_out.shape[0] > 0
    ym, u1, u2, us, d, yk = st[ST_YM], st[ST_U1], st[ST_U2], st[ST_US], st[ST_D], st[ST_YK]
    uf, since, yrest, k = st[ST_UF], st[ST_SINCE], st[ST_YREST], st[ST_K]
    resting = st[ST_RESTING] > 0.5
    half_kinetic = 0.5 * (S - J)
    plain = p[ASYM] == 0.0 and p[POS] == 0.0 and p[DRIFT] == 0.0
    # Without a lag the filter passes its input through exactly (0 * x + 1 * u = u):
    # taken out of the loop, so are the multiply-adds that chain one sample to the next.
    a_in, b_out = p[A_IN], p[B_OUT]
    lag_in, lag_out = a_in != 0.0, b_out != 0.0
    stribeck, creep = p[STRIBECK], p[CREEP]
    for i in range(i0, i1):
        uf = a_in * uf + (1.0 - a_in) * u[i] if lag_in else u[i]
        uk = _clip(uf)
        if not resting and ((uk - u1) * (u1 - u2) <= 0.0 or abs(uk - u1) < stribeck):
            us = u1
            resting = True
            since = k
            yrest = yk
        if resting:
            nd = _breakaway_fx(d, uk - us, S, J, p, yk, k, k - since, plain)
            if nd != 0.0:
                d = nd
                resting = False
        if resting:
            yk = _clip(yrest + creep * (uk - us))
        else:
            yk = _clip(uk - d * half_kinetic * _scale(p, d, yk, k, plain))
        ym = b_out * ym + (1.0 - b_out) * yk if lag_out else yk
        u2 = u1
        u1 = uk
        k += 1.0
        if write:
            out[i] = ym
            if flags:
                resting_out[i] = 1.0 if resting else 0.0
        if score:
            e = ym - y[i]
            sse += e * e
            if sse > limit:
                break
    st[ST_YM], st[ST_U1], st[ST_U2], st[ST_US], st[ST_D], st[ST_YK] = ym, u1, u2, us, d, yk
    st[ST_UF], st[ST_SINCE], st[ST_YREST], st[ST_K] = uf, since, yrest, k
    st[ST_RESTING] = 1.0 if resting else 0.0
    return sse


@njit(cache=True)
def _at_rest(u0: float, k: float, y0: float) -> Floats:
    # A valve resting at y0 with no friction force stored, before sample k.
    st = np.empty(STATE_SIZE)
    u1 = _clip(u0)
    st[ST_YM], st[ST_U1], st[ST_U2], st[ST_US], st[ST_D], st[ST_YK] = y0, u1, u1, u1, 0.0, y0
    st[ST_UF], st[ST_SINCE], st[ST_YREST], st[ST_K] = u0, k, y0, k
    st[ST_RESTING] = 1.0
    return st


@njit(cache=True)
def _restart_state(c: int, u0: float, k: float, y0: float) -> Floats:
    # Restart c after a gap in OP, before sample k (valve_starts.restart_state): 0 and 1 stuck
    # at y0 with its stick point there, 2 and 3 moving up and down; the input lag at u0.
    st = _at_rest(u0, k, y0)
    if c < 2:
        st[ST_US] = _clip(y0)
    else:
        d = 1.0 if c == 2 else -1.0
        st[ST_U1] = _clip(u0) - d
        st[ST_U2] = st[ST_U1] - d
        st[ST_US] = st[ST_U1]
        st[ST_D] = d
        st[ST_RESTING] = 0.0
    return st


# The stick point, rest start and rest position count only while at rest.
_REST_ONLY = np.zeros(STATE_SIZE, dtype=np.bool_)
_REST_ONLY[[ST_US, ST_SINCE, ST_YREST]] = True


@njit(cache=True)
def _restart(u: Floats, y: Floats, i0: int, i1: int, y0: float, S: float, J: float, p: Floats,
             bound: float) -> tuple[float, int, int, Floats]:
    # valve_starts.restart with this model: (SSE of the best restart, first sample not yet
    # scored, its number, its state), the restarts side by side until they merge.
    none = np.empty(0)
    cand = np.empty((RESTARTS, STATE_SIZE))
    sse = np.zeros(RESTARTS)
    alive = np.ones(RESTARTS, dtype=np.bool_)
    for c in range(RESTARTS):
        cand[c] = _restart_state(c, u[i0], float(i0), y0 if c == 0 else y[i0])
    best, k = 0, i0
    while k < i1 and alive.sum() > 1:
        for c in range(RESTARTS):
            if alive[c]:
                sse[c] = _segment(u, y, k, k + 1, S, J, p, cand[c], sse[c], np.inf, none, none)
        best = prune(cand, sse, alive, ST_RESTING, _REST_ONLY)
        k += 1
        if sse[best] > bound:
            break
    return sse[best], k, best, cand[best].copy()


@njit(cache=True, nogil=True)
def kano_effects_sse(u: Floats, y: Floats, starts: Ints, stops: Ints, y0s: Floats, S: float,
                     J: float, p: Floats, limit: float) -> float:
    """
    Return the SSE against ``y`` over the segments, or a number > ``limit`` once past it.

    The first segment starts at rest at position ``y0s[0]``.  Where OP is known
    since the last segment the valve runs on through the gap, whose samples are
    not scored; after a gap in OP the best of the restarts of
    ``valve_starts.restart_state`` at ``y0s[s]`` is scored (``fit_core`` says why).
    """
    sse = 0.0
    none = np.empty(0)
    st = none
    for s in range(starts.shape[0]):
        i0 = starts[s]
        k0 = i0
        if s == 0:
            st = _at_rest(u[i0], float(i0), y0s[s])
        elif input_known(u, stops[s - 1], i0):
            _segment(u, none, stops[s - 1], i0, S, J, p, st, 0.0, np.inf, none, none)
        else:
            e, k0, _, st = _restart(u, y, i0, stops[s], y0s[s], S, J, p, limit - sse)
            sse += e
            if sse > limit:
                return sse
        sse = _segment(u, y, k0, stops[s], S, J, p, st, sse, limit, none, none)
        if sse > limit:
            return sse
    return sse


@njit(cache=True, nogil=True)
def kano_effects_grid(u: Floats, y: Floats, starts: Ints, stops: Ints, y0s: Floats,
                      s_values: Floats, j_values: Floats, p: Floats, limit: float,
                      keep: int) -> Floats:
    """
    Return the SSE of every (S, J) on a grid with the effect parameters ``p``.

    Only the ``keep`` best points matter to the caller, so each point stops summing
    once it is worse than the ``keep``-th best so far (or ``limit``): those best
    points are exact, every other entry is merely known to be worse.
    """
    out = np.empty((s_values.shape[0], j_values.shape[0]))
    best = np.full(keep, np.inf)
    for i in range(s_values.shape[0]):
        for j in range(j_values.shape[0]):
            e = kano_effects_sse(u, y, starts, stops, y0s, s_values[i], j_values[j],
                                 p, min(limit, best[keep - 1]))
            out[i, j] = e
            if e < best[keep - 1]:
                insert_best(best, e)
    return out


@njit(cache=True, nogil=True)
def kano_effects_fit_output(u: Floats, y: Floats, starts: Ints, stops: Ints, y0s: Floats,
                            S: float, J: float, p: Floats, out: Floats,
                            resting_out: Floats) -> None:
    """
    Write the position :func:`kano_effects_sse` scores into ``out`` (rests: ``resting_out``).

    The gaps the valve runs on through are written too.  With ``y`` empty, a
    restart after a gap in OP is the valve stuck at ``y0s[s]``.
    """
    none = np.empty(0)
    st = none
    for s in range(starts.shape[0]):
        i0 = starts[s]
        if s == 0:
            st = _at_rest(u[i0], float(i0), y0s[s])
        elif input_known(u, stops[s - 1], i0):
            _segment(u, none, stops[s - 1], i0, S, J, p, st, 0.0, np.inf, out, resting_out)
        else:
            c = 0
            if y.shape[0] > 0:
                c = _restart(u, y, i0, stops[s], y0s[s], S, J, p, np.inf)[2]
            st = _restart_state(c, u[i0], float(i0), y0s[s] if c == 0 else y[i0])
        _segment(u, none, i0, stops[s], S, J, p, st, 0.0, np.inf, out, resting_out)


@njit(cache=True, nogil=True)
def kano_effects_output(u: Floats, starts: Ints, stops: Ints, y0s: Floats, S: float, J: float,
                        p: Floats, out: Floats, resting_out: Floats) -> None:
    """Write the model's position into ``out`` (and 1.0 where at rest into ``resting_out``)."""
    kano_effects_fit_output(u, np.empty(0), starts, stops, y0s, S, J, p, out, resting_out)


@njit(cache=True)
def kano_effects_run(u: Floats, out: Floats, st: Floats, S: float, J: float, p: Floats) -> None:
    """
    Advance the model over ``u`` from the state array ``st`` (updated in place).

    ``st`` holds the ``ST_*`` entries (position seen after any measurement lag,
    u(k-1), u(k-2), u_s, resting, direction, position, lagged input, rest start,
    rest position, sample counter); ``stiction_ros.models.kano_effects`` builds it.
    """
    _segment(u, np.empty(0), 0, u.shape[0], S, J, p, st, 0.0, np.inf, out, np.empty(0))

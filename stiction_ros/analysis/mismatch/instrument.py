"""
The valve seen through its instruments: dead time, lags, calibration, backlash, stiction.

A recorded valve position differs from a simulated one first through timing
and instruments, before any friction: the position may follow OP a second
late, through an actuator or transmitter lag, read 2 % high.  So every
explanation starts from a *chain* whose every stage reduces to nothing at its
null value::

    OP -> dead time d -> friction (none | backlash | stiction) -> lag tau
       -> second lag tau2 -> offset + gain * position -> MV reading

``d``, ``tau`` and ``tau2`` are in samples (``d`` fractional: a sample
misalignment is a dead time under one sample).  Backlash is Kano's model with
J = 0 (play that moves smoothly once taken up); stiction is Kano's (S, J).
The frictionless chain is linear in offset and gain, which are solved in
closed form for every (d, tau, tau2) tried.
"""

from dataclasses import dataclass, field
import math

import numpy as np
from scipy.optimize import minimize_scalar

from stiction_ros.analysis.fit_core import carried_runs
from stiction_ros.analysis.identify import identify, plausible_box, wider_s
from stiction_ros.analysis.mismatch.fit import EffectsProblem, local_sj, RESOLUTION, \
    start_positions
from stiction_ros.analysis.mismatch.stats import curvature_errors
# The limits, grid and dead-time shift the verdict's own frictionless valve uses too.
from stiction_ros.analysis.without_friction import indices, lagged, limits, shift
from stiction_ros.kernels import kano_effects as kk
from stiction_ros.kernels.chain import limited

COMPONENTS = ('delay', 'tau', 'tau2', 'offset', 'gain', 'rate', 'travel')
# 'rate': the largest change per sample (0: none); 'travel': 1 when the reading is held
# within [travel_lo, travel_hi] (the stops), else 0.
NULL = {'delay': 0.0, 'tau': 0.0, 'tau2': 0.0, 'offset': 0.0, 'gain': 1.0, 'rate': 0.0,
        'travel': 0.0, 'travel_lo': -math.inf, 'travel_hi': math.inf}
FRICTION_PARAMS = {'none': 0, 'backlash': 1, 'stiction': 2}
# The stages a friction chain fits (its kernel holds the valve within 0-100 % already).
FRICTION_STAGES = ('delay', 'tau', 'offset', 'gain')
# Smallest sizes worth a sentence: below them a stage is noise-fitting, however
# significant (a 0.05-sample dead time is a clock detail, not an actuator).
PLAUSIBLE = {'delay': 0.1, 'tau': 0.2, 'tau2': 0.2, 'offset': 0.1, 'gain': 0.005}
# A rate limit or a travel stop must act on this many samples to be named (a few OP
# steps turned into ramps; a limiter no step reaches is no stage).
ACTIVE_SAMPLES = 8
SEARCH_RESOLUTION = 0.01
LAG_TRIES = (0.5, 1.0, 2.0, 3.0, 5.0, 8.0)


@dataclass
class ChainFit:
    """One chain fitted on the fitted part: its friction, stages, S, J and SSE."""

    friction: str
    params: dict
    S: float
    J: float
    sse: float
    n: int
    free: tuple
    se: dict = field(default_factory=dict)

    @property
    def k(self) -> int:
        """Return the number of fitted parameters."""
        return len(self.free) + FRICTION_PARAMS[self.friction]

    @property
    def mse(self) -> float:
        """Mean squared error on the fitted part."""
        return self.sse / self.n


def lag(x: np.ndarray, tau: float, segments) -> np.ndarray:
    """Return ``x`` through a first-order lag of ``tau`` samples, at rest at each run start."""
    return lagged(x, tau, carried_runs(segments, x))


def affine(y: np.ndarray, mv: np.ndarray, idx: np.ndarray, offset: bool,
           gain: bool) -> tuple[float, float, float]:
    """Return (offset, gain, SSE) of the least-squares ``mv = offset + gain * y`` on ``idx``."""
    yy, mm = y[idx], mv[idx]
    if offset and gain:
        a = np.column_stack([np.ones(len(yy)), yy])
        (c0, c1), *_ = np.linalg.lstsq(a, mm, rcond=None)
    elif offset:
        c0, c1 = float(np.mean(mm - yy)), 1.0
    elif gain:
        den = float(yy @ yy)
        c0, c1 = 0.0, (float(yy @ mm) / den if den > 0 else 1.0)
    else:
        c0, c1 = 0.0, 1.0
    r = mm - c0 - c1 * yy
    return float(c0), float(c1), float(r @ r)


def friction_output(u: np.ndarray, segments, S: float, J: float, y: np.ndarray) -> np.ndarray:
    """
    Return Kano's position for input ``u`` over ``segments``, started at rest at ``y``.

    After a gap in ``u``, the restart that fits ``y`` best (``fit_core``).  The
    gaps it runs on through (``u`` known) hold positions too, so that a lag
    after the friction runs on through them as well.
    """
    out = np.full(len(u), np.nan)
    starts = np.array([a for a, _ in segments], dtype=np.int64)
    stops = np.array([b for _, b in segments], dtype=np.int64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    y0s = start_positions(y, starts, stops)
    kk.kano_effects_fit_output(np.ascontiguousarray(u, dtype=np.float64), y, starts, stops,
                               y0s, float(S), float(J), kk.plain_params(), out,
                               np.zeros(len(u)))
    return out


def split_delay(d: float) -> tuple[float, float]:
    """
    Return (nearest whole samples, the rest, within half a sample either way).

    A friction chain delays OP by the whole samples and its position by the
    rest: a reading taken a fraction of a sample off the OP's clock blends the
    samples around a slip, which a delay of OP by a fraction cannot do.
    """
    whole = float(round(d))
    return whole, d - whole


def chain_output(op: np.ndarray, mv: np.ndarray, segments, fit: ChainFit) -> np.ndarray:
    """Return the MV reading ``fit`` predicts over ``segments`` (NaN elsewhere)."""
    p = fit.params
    before = fit.friction != 'none' and p.get('lag_before', 0.0) > 0.0
    if fit.friction != 'none':
        whole, frac = split_delay(p['delay'])
        u = shift(op, whole, segments)
        # The friction model starts where the valve is: the reading, calibration undone.
        y0 = (np.asarray(mv, dtype=np.float64) - p['offset']) / (p['gain'] or 1.0)
        u = friction_output(lag(u, p['tau'], segments) if before else u, segments, fit.S,
                            fit.J, y0)
        u = shift(u, frac, segments)
    else:
        u = shift(op, p['delay'], segments)
        if p.get('rate', 0.0) > 0.0:
            u = limited(u, carried_runs(segments, u), p['rate'])
    y = lag(lag(u, 0.0 if before else p['tau'], segments), p['tau2'], segments)
    out = np.full(len(op), np.nan)
    idx = indices(segments)
    out[idx] = p['offset'] + p['gain'] * y[idx]
    if p.get('travel', 0.0) > 0.0:
        out[idx] = np.clip(out[idx], p['travel_lo'], p['travel_hi'])
    return out


def _friction_at(op, mv, segments, idx, d, friction, free, box, start, tau=0.0, near=None,
                 polish=True, before=False):
    """
    Return (sse, S, J, offset, gain) of a friction chain at dead time ``d`` and lag ``tau``.

    Without a lag, stiction's (S, J) come from ``identify``; with one, from a
    coarse-to-fine search of the effects kernel with its lag after the
    friction, around ``near`` (the lag-free fit's S and J).  Offset and gain
    alternate with (S, J) twice when ``polish``, else once at a coarser grid
    (the searches over dead time and lag compare many such points).
    """
    whole, frac = split_delay(d)
    u = shift(op, whole, segments)
    p_lag = _lagged_params(tau, before)
    c0, c1 = start
    best = None
    calibrated = 'offset' in free or 'gain' in free
    for _ in range(2 if calibrated and polish else 1):
        y = (mv - c0) / (c1 or 1.0)
        if friction == 'stiction' and tau <= 0.0:
            f = identify(u, y, 'kano', segments=segments,
                         resolution=RESOLUTION if polish else SEARCH_RESOLUTION,
                         interval=False)
            S, J = f.S, f.J
        elif friction == 'stiction':
            S, J = _stiction_lagged(u, y, segments, p_lag, near, box, polish)
        else:
            S, J = _backlash_s(u, y, segments, box[0], p_lag), 0.0
        if before:
            pos = friction_output(lag(u, tau, segments), segments, S, J, y)
        else:
            pos = lag(friction_output(u, segments, S, J, y), tau, segments)
        pos = shift(pos, frac, segments)
        c0, c1, sse = affine(pos, mv, idx, 'offset' in free, 'gain' in free)
        if best is None or sse < best[0]:
            best = (sse, S, J, c0, c1)
    return best


def _lagged_params(tau, before=False):
    # The effects kernel's lags: A_IN on OP before the friction, B_OUT on the position.
    p = kk.plain_params()
    p[kk.A_IN if before else kk.B_OUT] = math.exp(-1.0 / tau) if tau > 0.0 else 0.0
    return p


def _stiction_lagged(u, y, segments, p_lag, near, box, polish=True):
    problem = EffectsProblem(u, y, [a for a, _ in segments], [b for _, b in segments])
    s0, j0 = near if near is not None else (0.5 * box[0], 0.25 * box[0])
    half = max(s0, 1.0)
    _, S, J = local_sj(problem, p_lag, s0, j0, half, half, points=13,
                       j_max=s0 + half, levels=math.inf if polish else 2)
    return float(S), float(J)


def _backlash_s(u, y, segments, s_max, p):
    problem = EffectsProblem(u, y, [a for a, _ in segments], [b for _, b in segments])
    j = np.zeros(1)
    s_axis = np.linspace(0.0, max(s_max, 0.1), 41)
    scores = problem.grid(s_axis, j, p)[:, 0]
    s_wide = wider_s(float(s_axis[int(np.argmin(scores))]), float(s_axis[-1]))
    if s_wide is not None:
        # The play may be wider than OP's travel from rest allows past (identify.AT_CAP).
        s_axis = np.linspace(0.0, s_wide, 81)
        scores = problem.grid(s_axis, j, p)[:, 0]
    s0 = float(s_axis[int(np.argmin(scores))])
    step = s_axis[1] - s_axis[0]
    while step > RESOLUTION:
        axis = np.clip(s0 + step * np.linspace(-1.0, 1.0, 9), 0.0, None)
        scores = problem.grid(axis, j, p)[:, 0]
        s0 = float(axis[int(np.argmin(scores))])
        step /= 4.0
    return s0


def fit_friction(op: np.ndarray, mv: np.ndarray, segments, sample_time: float,
                 friction: str = 'stiction', free=('delay', 'tau', 'offset', 'gain'),
                 hint: ChainFit | None = None, delay: float | None = None) -> ChainFit:
    """
    Return the best chain with ``friction`` ('stiction' or 'backlash') and stages ``free``.

    Dead time: whole samples around the frictionless fit's (``hint``), then
    onwards from the best until two in a row do worse, then half and quarter
    samples and a bounded search around the best (``delay`` fixes it
    instead).  Lag: a few values before the friction (an actuator) and after
    it (a transmitter), with no dead time and with the best, then refined.
    ``hint``, the frictionless fit, gives a second start for offset and gain
    beside the ideal 0 and 1.  The search compares points on a coarse grid;
    the best is fitted again finely.
    """
    op = np.asarray(op, dtype=np.float64)
    mv = np.asarray(mv, dtype=np.float64)
    idx = indices(segments)
    box = plausible_box(op[idx], mv[idx])
    d_max, tau_max = limits(sample_time)
    d0 = 0.0 if delay is None else float(delay)
    starts = [(0.0, 1.0)]
    if hint is not None and ('offset' in free or 'gain' in free):
        starts.append((hint.params['offset'] if 'offset' in free else 0.0,
                       hint.params['gain'] if 'gain' in free else 1.0))
    firsts = [_friction_at(op, mv, segments, idx, d0, friction, free, box, st, polish=False)
              for st in starts]
    start = starts[min(range(len(firsts)), key=lambda i: firsts[i][0])]
    # Keys: (dead time, lag, lag before the friction).
    tried = {(d0, 0.0, False): min(firsts, key=lambda r: r[0])}

    def at(d, tau=0.0, before=False, near=None):
        key = (float(d), float(tau), bool(before and tau > 0.0))
        if key not in tried and 0.0 <= d <= d_max and tau <= tau_max:
            tried[key] = _friction_at(op, mv, segments, idx, d, friction, free, box, start,
                                      tau, near, polish=False, before=key[2])
        return tried.get(key, (math.inf,))

    def best_key(tau=None, before=None):
        keys = [k for k in tried if (tau is None or k[1] == tau)
                and (before is None or k[2] == before)]
        return min(keys, key=lambda k: tried[k][0])

    timed = delay is None and 'delay' in free
    if timed:
        # Whole samples around the frictionless fit's dead time (and its dead time plus
        # lag: a frictionless fit reads a sticking valve's late breakaways as lag), then
        # onwards from the best while it improves.
        hd = hint.params['delay'] if hint is not None else 0.0
        ht = hd + (hint.params['tau'] + hint.params['tau2'] if hint is not None else 0.0)
        for d in sorted({float(round(x)) for x in (hd - 1, hd, hd + 1, ht - 1, ht, ht + 1)}):
            at(max(d, 0.0))
        for direction in (1.0, -1.0):
            d, worse = best_key()[0], 0
            while worse < 2 and 0.0 <= d + direction <= d_max:
                d += direction
                worse = worse + 1 if at(d)[0] > tried[best_key()][0] else 0
        _refine_delay(at, best_key, 0.0, False)
    if 'tau' in free:
        # A lag hides the slip jump (a stiction valve read through 3 s of lag fits as
        # J = 0 without it) and a lag-free fit mimics it with a dead time; so lags are
        # tried with no dead time and with the lag-free best, then refined.
        d_free = best_key(0.0)[0]
        for d in sorted({d0, d_free}):
            near = tried[(d, 0.0, False)][1:3]
            for tau in LAG_TRIES:
                for before in (False, True):
                    at(d, tau, before, near)
        d, tau, before = best_key()
        if tau > 0.0:
            near = tried[(d, tau, before)][1:3]
            for t2 in (0.7 * tau, 1.4 * tau):
                at(d, t2, before, near)
            d, tau, before = best_key()
            if timed:
                _refine_delay(at, best_key, tau, before, near)
            _refine_lag(at, tried, *best_key(), tau_max)
    d, tau, before = best_key()
    near = tried[(d, tau, before)][1:3]
    if timed:
        # Between quarter samples: a dead time a tenth of a sample off leaves a residual
        # that a quiet record reads as a lag.
        res = minimize_scalar(lambda x: _friction_at(op, mv, segments, idx, x, friction, free,
                                                     box, start, tau, near, polish=False,
                                                     before=before)[0],
                              bounds=(max(d - 0.25, 0.0), min(d + 0.25, d_max)),
                              method='bounded', options={'xatol': 0.02, 'maxiter': 12})
        if res.fun < tried[(d, tau, before)][0]:
            d = float(res.x)
    sse, S, J, c0, c1 = _friction_at(op, mv, segments, idx, d, friction, free, box, start,
                                     tau, near, polish=True, before=before)
    params = {**NULL, 'delay': d, 'tau': tau, 'offset': c0, 'gain': c1,
              'lag_before': float(before)}
    return ChainFit(friction, params, float(S), float(J), float(sse), len(idx),
                    tuple(c for c in COMPONENTS if c in free and c in FRICTION_STAGES))


def _refine_lag(at, tried, d, tau, before, tau_max):
    """
    Try lags between 0.7 and 1.4 times ``tau`` at dead time ``d`` (into ``tried``, by ``at``).

    The tries step the lag by 40 %, and a sticking valve read through a lag
    4 samples long fits as one of 3.5 or 5 only with its breakaways moved
    (ten times the SSE of the true lag): the lag's SSE is smooth between the
    tries, so a bounded scalar search finds it.
    """
    if tau <= 0.0:
        return
    near = tried[(d, tau, before)][1:3]
    minimize_scalar(lambda x: at(d, float(x), before, near)[0],
                    bounds=(0.7 * tau, min(1.4 * tau, tau_max)), method='bounded',
                    options={'xatol': max(0.02 * tau, 0.02), 'maxiter': 10})


def _refine_delay(at, best_key, tau, before, near=None):
    """Try half and quarter samples around the best dead time at lag ``tau``."""
    for step in (0.5, 0.25):
        d = best_key(tau, before)[0]
        for d2 in (d - step, d + step):
            at(d2, tau, before, near)


def standard_errors(op: np.ndarray, mv: np.ndarray, segments, fit: ChainFit,
                    rho: float) -> dict:
    """
    Return the standard error of each free stage from the SSE's curvature.

    The stages are varied together, and with a stiction chain its S and J
    too (``stats.curvature_errors``), so a stage that trades off against
    another, or against the friction, gets its marginal error.  The noise
    variance is inflated by (1 + rho) / (1 - rho) for a residual of lag-1
    autocorrelation ``rho``, which a least-squares error ignores.
    """
    idx = indices(segments)
    sigma2 = fit.mse * (1.0 + rho) / max(1.0 - rho, 0.05)
    names = [name for name in fit.free if name != 'travel']
    if not names:
        return {}
    positive = ('delay', 'tau', 'tau2', 'rate')
    sj = fit.friction == 'stiction'

    def sse(theta):
        params = dict(fit.params)
        for name, x in zip(names, theta):
            params[name] = max(x, 0.0) if name in positive else x
        S, J = (max(theta[-2], 0.0), max(theta[-1], 0.0)) if sj else (fit.S, fit.J)
        trial = ChainFit(fit.friction, params, S, J, 0.0, fit.n, fit.free)
        r = chain_output(op, mv, segments, trial)[idx] - mv[idx]
        return float(r @ r)

    theta = [fit.params[name] for name in names]
    steps = [max(1e-3, 0.05 * abs(v)) if name in positive else (
        0.01 if name == 'offset' else 1e-3) for name, v in zip(names, theta)]
    if sj:
        theta += [fit.S, fit.J]
        steps += [max(0.01, 0.05 * fit.S), max(0.01, 0.05 * fit.J)]
    return dict(zip(names, curvature_errors(sse, theta, steps, sigma2)))


def quantum(mv: np.ndarray, idx: np.ndarray) -> float:
    """
    Return the reading's resolution when MV lies on a grid of one step, else 0.

    A transmitter of coarse resolution gives few distinct values, all an
    integer number of steps apart; a continuous reading gives as many values
    as samples.
    """
    y = np.asarray(mv, dtype=np.float64)[idx]
    y = y[np.isfinite(y)]
    values = np.unique(np.round(y, 9))
    if len(values) < 3 or len(values) > 0.2 * len(y):
        return 0.0
    steps = np.diff(values)
    q = float(np.min(steps[steps > 1e-9]))
    if q <= 0.0:
        return 0.0
    k = (values - values[0]) / q
    return q if np.all(np.abs(k - np.round(k)) < 0.05) else 0.0

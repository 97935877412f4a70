"""
The best valve without friction: dead time, lags, calibration, a rate limit and travel stops.

Linear stages first: a grid over dead time (quarter samples) and lag, then a
bounded Powell search, with offset and gain solved in closed form for every
point.  Then the two nonlinear actuator stages, each by a one-dimensional
search with the rest held: a rate limit (the most the position can change
in a sample) and travel stops (the reading held within the extremes it
reaches while OP goes on).  :func:`stage_ok` says whether a stage is big
enough to name.
"""

import math

import numpy as np
from scipy.optimize import minimize, minimize_scalar

from stiction_ros.analysis.fit_core import carried_runs
from stiction_ros.analysis.mismatch import instrument as ins
from stiction_ros.analysis.without_friction import TAU_GRID
from stiction_ros.kernels.chain import limited


def _sse(op, mv, segments, idx, v, free):
    """Return (offset, gain, SSE) of the linear and rate stages in ``v``."""
    u = ins.shift(op, v['delay'], segments)
    if v.get('rate', 0.0) > 0.0:
        u = limited(u, carried_runs(segments, u), v['rate'])
    y = ins.lag(ins.lag(u, v['tau'], segments), v['tau2'], segments)
    return ins.affine(y, mv, idx, 'offset' in free, 'gain' in free)


def fit_frictionless(op: np.ndarray, mv: np.ndarray, segments, sample_time: float,
                     free=ins.COMPONENTS) -> ins.ChainFit:
    """Return the best frictionless chain with the stages in ``free`` (the others at null)."""
    op = np.asarray(op, dtype=np.float64)
    mv = np.asarray(mv, dtype=np.float64)
    idx = ins.indices(segments)
    d_max, tau_max = ins.limits(sample_time)
    v = dict(ins.NULL)
    # Quarter samples where a sample misalignment lives, whole samples beyond.
    d_axis = (np.unique(np.r_[np.arange(0.0, min(d_max, 4.0) + 1e-9, 0.25),
                              np.arange(4.0, d_max + 1e-9, 1.0)])
              if 'delay' in free else np.zeros(1))
    t_axis = [t for t in TAU_GRID if t <= tau_max] if 'tau' in free else [0.0]
    best = math.inf
    for d in d_axis:
        for tau in t_axis:
            sse = _sse(op, mv, segments, idx, {**v, 'delay': d, 'tau': tau}, free)[2]
            if sse < best:
                best, v['delay'], v['tau'] = sse, float(d), float(tau)
    names = [c for c in ('delay', 'tau', 'tau2') if c in free]
    v = _powell(op, mv, segments, idx, v, free, names, d_max, tau_max)
    if 'rate' in free:
        # A limiter turns steps into ramps, which a dead time and a lag imitate: it is
        # tried from the linear optimum and from none of either, fitted with them, and
        # kept only where it does better than the linear chain.
        sse_lin = _sse(op, mv, segments, idx, v, free)[2]
        for start in (dict(v), {**v, 'delay': 0.0, 'tau': 0.0, 'tau2': 0.0}):
            start['rate'] = _rate(op, mv, segments, idx, start, free,
                                  _sse(op, mv, segments, idx, start, free)[2])
            if start['rate'] <= 0.0:
                continue
            trial = _powell(op, mv, segments, idx, start, free, names + ['rate'], d_max,
                            tau_max)
            sse = _sse(op, mv, segments, idx, trial, free)[2]
            if sse < sse_lin:
                v, sse_lin = trial, sse
    if v['tau2'] > v['tau']:
        # Two lags in series commute: the longer is called the lag.
        v['tau'], v['tau2'] = v['tau2'], v['tau']
    c0, c1, sse = _sse(op, mv, segments, idx, v, free)
    v.update(offset=c0, gain=c1)
    stages = tuple(c for c in ins.COMPONENTS if c in free)
    fit = ins.ChainFit('none', v, 0.0, 0.0, sse, len(idx), stages)
    if 'travel' in free:
        fit = _travel(op, mv, segments, idx, fit)
    return fit


def _powell(op, mv, segments, idx, v, free, names, d_max, tau_max):
    """Return ``v`` with ``names`` refined together by a bounded Powell search."""
    if not names:
        return v
    top = float(np.max(np.abs(np.diff(op[idx])))) or 1.0
    bounds = {'delay': (0.0, d_max), 'tau': (0.0, tau_max), 'tau2': (0.0, tau_max),
              'rate': (1e-4 * top, top)}
    res = minimize(lambda th: _sse(op, mv, segments, idx, {**v, **dict(zip(names, th))},
                                   free)[2],
                   [min(max(v[c], bounds[c][0]), bounds[c][1]) for c in names],
                   method='Powell', bounds=[bounds[c] for c in names],
                   options={'xtol': 1e-3, 'ftol': 1e-9, 'maxfev': 600})
    if res.fun < _sse(op, mv, segments, idx, v, free)[2]:
        return {**v, **dict(zip(names, (float(x) for x in res.x)))}
    return v


def _rate(op, mv, segments, idx, v, free, sse0):
    """Return the rate limit (per sample) that fits best, or 0 where none helps."""
    steps = np.abs(np.diff(ins.shift(op, v['delay'], segments)[idx]))
    top = float(np.max(steps)) if len(steps) else 0.0
    if top <= 0.0:
        return 0.0
    axis = top * np.geomspace(0.02, 1.0, 12)
    scores = [_sse(op, mv, segments, idx, {**v, 'rate': r}, free)[2] for r in axis]
    k = int(np.argmin(scores))
    if scores[k] >= sse0:
        return 0.0
    lo, hi = axis[max(k - 1, 0)], axis[min(k + 1, len(axis) - 1)]
    res = minimize_scalar(lambda lr: _sse(op, mv, segments, idx, {**v, 'rate': math.exp(lr)},
                                          free)[2],
                          bounds=(math.log(lo), math.log(hi)), method='bounded',
                          options={'xatol': 0.01})
    return float(math.exp(res.x)) if res.fun < scores[k] else float(axis[k])


def _travel(op, mv, segments, idx, fit):
    """Return ``fit`` held at travel stops where that lowers the SSE (each side alone)."""
    y = ins.chain_output(op, mv, segments, fit)[idx]
    m = mv[idx]
    bounds = {'travel_lo': -math.inf, 'travel_hi': math.inf}
    for key, clip, lo_q, hi_q in (('travel_hi', np.minimum, 0.9, 1.0),
                                  ('travel_lo', np.maximum, 0.0, 0.1)):
        a, b = (float(np.quantile(m, q)) for q in (lo_q, hi_q))
        if b <= a:
            continue
        # The stop sits where the reading piles up, not at its noisy extreme.
        res = minimize_scalar(lambda x: float(np.sum((clip(y, x) - m) ** 2)), bounds=(a, b),
                              method='bounded', options={'xatol': 1e-3})
        held = int(np.sum(y > res.x) if key == 'travel_hi' else np.sum(y < res.x))
        if res.fun < float(np.sum((y - m) ** 2)) and held >= ins.ACTIVE_SAMPLES:
            bounds[key] = float(res.x)
            y = clip(y, float(res.x))
    if bounds == {'travel_lo': -math.inf, 'travel_hi': math.inf}:
        return ins.ChainFit('none', {**fit.params, 'travel': 0.0}, 0.0, 0.0, fit.sse, fit.n,
                            fit.free)
    r = y - m
    return ins.ChainFit('none', {**fit.params, 'travel': 1.0, **bounds}, 0.0, 0.0,
                        float(r @ r), fit.n, fit.free)


def stage_ok(fit, name: str, op: np.ndarray, segments) -> bool:
    """Return whether stage ``name`` of a fitted chain is big enough to name."""
    p = fit.params
    if name == 'rate':
        if p['rate'] <= 0.0:
            return False
        steps = np.abs(np.diff(ins.shift(op, p['delay'], segments)[ins.indices(segments)]))
        return int(np.sum(steps > p['rate'])) >= ins.ACTIVE_SAMPLES
    if name == 'travel':
        if p['travel'] <= 0.0:
            return False
        free = ins.ChainFit('none', {**p, 'travel': 0.0}, 0.0, 0.0, 0.0, fit.n, fit.free)
        y = ins.chain_output(op, op, segments, free)[ins.indices(segments)]
        held = (y < p['travel_lo']) | (y > p['travel_hi'])
        return int(np.sum(held)) >= ins.ACTIVE_SAMPLES
    return abs(p[name] - ins.NULL[name]) >= ins.PLAUSIBLE[name]

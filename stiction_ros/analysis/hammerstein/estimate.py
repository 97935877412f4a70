"""
The Hammerstein quantification of one record: search, evidence and verdict.

Evidence
--------
``fit_improvement`` is the residual variance of the best Hammerstein model
over that of the best linear model (S = J = 0, same ARX orders and dead-time
search): below 1 the sticky valve explains PV better.  The search picks the
best of thousands of (S, J) pairs, and a small S filters the noise that the
controller feeds back into OP, so a linear valve still gets a ratio a little
below 1 (0.91 to 1 in our simulations, 0.90 to 1 on the plant records
labelled without stiction); ``MAX_IMPROVEMENT_RATIO`` sets the bar at 0.9.
The ratio is of one-step-ahead prediction errors, which PV noise dominates:
with PV noise of about a tenth of the oscillation amplitude, a real stiction
may no longer clear the bar although S is still estimated well.  The
intervals are described in ``stats``.

``jump_likelihood_ratio`` asks the question that tells stiction from
backlash: does the slip jump J earn its place?  The fit is redone with J
held at zero (a deadband valve, ``Search.deadband``) and the ratio is
``n_eff log(SSE(J = 0) / SSE)``, about chi-square with one degree of
freedom when there is no jump.  It is a figure, not a verdict: over the
simulated loops of the detector's training seeds its median is 1.5 with a
backlash valve (90th percentile 15), 3 with a linear one and 18 with a
sticky one (25th percentile 3.6), so it is read beside the others.

Identifiability
---------------
* S (deadband plus stickband, % of OP) is set by when the valve breaks away,
  i.e. how far OP travels while PV does not respond; it is well determined
  when the valve sticks and slips several times.
* J (slip jump) is in % of OP as well, but only under the assumption of unity
  valve gain: the gain of B absorbs any scaling of MV_hat.  In a limit cycle
  the valve jumps by J at each reversal and then follows OP until the next
  reversal; J is identified only through the ratio of the jump to that
  follow-through.  When OP reverses soon after each slip (large J, J near S,
  or a fast loop sampled slowly) MV_hat is nearly a square wave whose height
  the plant gain absorbs, and J is weakly determined: read its interval, not
  its value, and an interval of None means the data do not bound it.
* J also depends on the valve's unrecorded state at each segment start; the
  search fits it (step 4 in ``search``), but on short segments after a gap
  J can still be off by a quarter while S is right.
* Only the dead time of the Kano model is resolved to a sample; breakaways
  between samples, an air-chamber lag or a different friction law shift S.
* A regular oscillation is needed; a record without one, too short, where
  stiction does not explain PV better than a linear valve, whose optimum or
  S interval reaches the upper edge of the search box, or whose dead time is
  the longest searched is marked ``reliable = False`` with the reason.
"""

from dataclasses import dataclass, field
import math
import time

import numpy as np

from stiction_ros.analysis.hammerstein.problem import HammersteinProblem, MIN_ROWS, \
    valid_segments
from stiction_ros.analysis.hammerstein.search import _best, CHI2_95_2DOF, FINAL_KEEP, \
    PER_DELAY, Search
from stiction_ros.analysis.hammerstein.stats import _interval, effective_samples, jackknife, \
    linear_model_json
from stiction_ros.analysis.oscillation import detect_oscillation

# A linear valve scores 0.9 to 1 (see the module docstring); stiction with
# moderate noise 0.05 to 0.85.
MAX_IMPROVEMENT_RATIO = 0.9
MIN_CYCLES = 3
DEFAULT_MAX_DELAY = 30
REFERENCE = ('Jelali (2008) J. Process Control 18, 632-642; Srinivasan et al. (2005) '
             'Ind. Eng. Chem. Res. 44, 6719-6728')


@dataclass
class HammersteinResult:
    """
    The Hammerstein quantification of one record.

    ``S`` and ``J`` are in % of OP (J assuming unity valve gain); None when
    the data could not be fitted at all.  An interval is None where the data
    do not bound it (the 95 % region reaches the edge of the search box).
    ``fit_improvement`` is residual variance with stiction over that with a
    linear valve.  ``linear_model`` describes G; ``details`` holds the search
    box, sample counts, the fitted valve start states, the jackknife
    standard errors and timings; ``curves`` holds MV_hat for figures and is
    never written to JSON.
    """

    S: float | None
    J: float | None
    S_interval: tuple | None
    J_interval: tuple | None
    fit_improvement: float | None
    reliable: bool
    reason: str
    linear_model: dict = field(default_factory=dict)
    details: dict = field(default_factory=dict)
    curves: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        """Return the JSON-able part (everything but ``curves``)."""
        def interval(iv):
            return None if iv is None else [float(iv[0]), float(iv[1])]
        return {'S': self.S, 'J': self.J, 'S_interval': interval(self.S_interval),
                'J_interval': interval(self.J_interval),
                'fit_improvement': self.fit_improvement, 'reliable': self.reliable,
                'reason': self.reason, 'linear_model': self.linear_model,
                'details': self.details, 'reference': REFERENCE}


def _failure(reason, details) -> HammersteinResult:
    return HammersteinResult(None, None, None, None, None, False, reason, details=details)


def _unusable(problem, op, pv) -> str:
    """Return why the data cannot be fitted at all, or ''."""
    if problem.n < MIN_ROWS:
        return (f'too short: {problem.n} usable samples after the lags, at least {MIN_ROWS} '
                'needed')
    if max(np.ptp(op[a:b]) for a, b in problem.segments) <= 0.0:
        return 'OP never moves, so the valve cannot be seen sticking'
    span = max(np.ptp(pv[a:b]) for a, b in problem.segments)
    if span <= 1e-9 * max(1.0, float(np.median(np.abs(pv[problem.rows])))) or problem.tt <= 0:
        return 'PV does not vary (or only as its own past predicts): nothing to fit'
    return ''


def _likelihood_ratio(n_eff: float, nested_sse: float, sse: float) -> float:
    """
    Return ``n_eff log(nested_sse / sse)``: what the fuller model earns over the nested one.

    A residual sum of squares read off the normal equations can come out 0
    or a hair below it when a fit is exact.  A nested model that fits
    exactly leaves the fuller one nothing to earn (0); a fuller one that
    alone fits exactly earns without bound (1e300).
    """
    if nested_sse <= 0:
        return 0.0
    if sse <= 0:
        return 1e300
    return n_eff * math.log(nested_sse / sse)


def quantify(op, pv, sample_time: float, segments=None, integrating: bool = False,
             s_max: float | None = None, progress=None, orders: tuple = (2, 2),
             min_delay: int = 1, max_delay: int | None = None,
             resolution: float | None = None) -> HammersteinResult:
    """
    Return the :class:`HammersteinResult` of OP and PV sampled every ``sample_time`` s.

    ``segments``: (start, stop) index ranges of valid samples (default: the
    whole record, split at NaN); regressors never reach across a gap.
    ``integrating``: put an integrator in front of G (level loops).
    ``s_max``: upper edge of the S and J search (default: the OP travel).
    ``orders``: ARX orders (PV lags, valve-input lags); dead times from
    ``min_delay`` to ``max_delay`` samples (default 30) are searched.
    ``resolution``: finest grid step in % (default s_max / 500).
    ``progress(done, total)`` is called after each search stage.
    """
    t0 = time.perf_counter()
    op = np.asarray(op, dtype=np.float64)
    pv = np.asarray(pv, dtype=np.float64)
    if op.shape != pv.shape or op.ndim != 1:
        raise ValueError('op and pv must be 1-D arrays of the same length')
    segs = valid_segments(op, pv, segments)
    longest = max((b - a for a, b in segs), default=0)
    max_delay = int(max_delay if max_delay is not None
                    else min(DEFAULT_MAX_DELAY, max(min_delay, longest // 10)))
    details = {'samples': int(sum(b - a for a, b in segs)), 'sample_time': float(sample_time),
               'min_delay': int(min_delay), 'max_delay': max_delay}
    problem = HammersteinProblem(op, pv, segs, integrating, orders, min_delay, max_delay)
    details['rows'] = problem.n
    why = _unusable(problem, op, pv)
    if why:
        return _failure(why, details)
    s_max = float(min(s_max if s_max is not None
                      else max(np.ptp(op[a:b]) for a, b in problem.segments), 100.0))
    res = float(resolution if resolution is not None else s_max / 500)
    search = Search(problem, s_max, s_max, res)
    if progress is not None:
        progress(1, search.levels + 3)
    finalists = search.polish(search.refine(search.coarse(), progress))
    sse, S, J, delay, start = finalists[0]
    # Settled from the polished start and from rest: the grid is taken one
    # segment at a time and can stop in a local optimum.
    settled = [search.settle_start((sse, S, J, delay, s)) for s in (start, problem.at_rest())]
    finalists = search.refine(_best(settled + finalists, FINAL_KEEP, PER_DELAY))
    sse, S, J, delay, start = best = finalists[0]
    coefs, resid = problem.fit(S, J, delay, start)
    n_eff = effective_samples(resid)
    inside, steps = search.region(best, n_eff)
    se = jackknife(problem, s_max, res, finalists)
    if progress is not None:
        progress(search.levels + 3, search.levels + 3)
    lin_sse, _, _, lin_delay, _ = search.score([0.0], [0.0], problem.at_rest())[0]
    ratio = sse / lin_sse if lin_sse > 0 else 1.0
    lr = _likelihood_ratio(n_eff, lin_sse, sse)
    db_sse = search.deadband(best)[0]
    # J > 0 nests J = 0, so a negative ratio is the search missing a valley: none.
    jump_lr = max(0.0, _likelihood_ratio(n_eff, db_sse, sse))
    details.update({
        'search_box': {'S_max': s_max, 'J_max': s_max, 'resolution': res},
        'residual_variance': sse / problem.n, 'linear_residual_variance': lin_sse / problem.n,
        'linear_delay_samples': int(lin_delay), 'effective_samples': n_eff,
        'likelihood_ratio': lr,
        'deadband_residual_variance': db_sse / problem.n, 'jump_likelihood_ratio': jump_lr,
        'jackknife_se': None if se is None else {'S': se[0], 'J': se[1]},
        'valve_start': [{'direction': int(d), 'fraction': float(f)} for d, f in start],
        'evaluations': problem.evaluations, 'seconds': round(time.perf_counter() - t0, 4)})
    result = HammersteinResult(
        round(S, 6), round(J, 6),
        _interval(inside, steps, 1, S, se and se[0], s_max),
        _interval(inside, steps, 2, J, se and se[1], s_max), float(ratio), True, '',
        linear_model_json(coefs, delay, problem, sample_time), details,
        {'mv_hat': problem.mv_hat(S, J, start)})
    _judge(result, problem, sample_time, lr, s_max, steps)
    return result


def _oscillation_reason(problem, sample_time) -> str:
    """Return '' if OP or PV oscillates regularly over the longest segment, else why not."""
    a, b = max(problem.segments, key=lambda s: s[1] - s[0])
    found = [detect_oscillation(x[a:b], sample_time) for x in (problem.op, problem.pv)]
    if any(o.oscillating and o.n_cycles >= MIN_CYCLES for o in found):
        return ''
    return (f'no regular oscillation of at least {MIN_CYCLES} cycles in OP or PV (OP: '
            f'{found[0].reason}; PV: {found[1].reason}): the valve did not stick and slip '
            'often enough to quantify')


def _judge(result, problem, sample_time, lr, s_max, steps):
    """Set ``reliable`` and ``reason`` from the checks the data must pass."""
    why = [_oscillation_reason(problem, sample_time)]
    ratio = result.fit_improvement
    if ratio > MAX_IMPROVEMENT_RATIO or lr < CHI2_95_2DOF:
        why.append(f'no improvement over a linear valve: residual variance ratio {ratio:.3g} '
                   f'(needs <= {MAX_IMPROVEMENT_RATIO}), likelihood ratio {lr:.3g}')
    if result.S >= s_max - steps[0] or result.J >= s_max - steps[1]:
        why.append(f'optimum on the edge of the search box (S, J <= {s_max:.4g} %, the OP '
                   'travel): the data do not bound it')
    elif result.S_interval is None:
        why.append('the 95 % interval of S reaches the edge of the search box')
    if result.linear_model['delay_samples'] >= problem.dhi:
        why.append(f'dead time at the end of the searched range ({problem.dhi} samples): the '
                   'plant model is not bounded either')
    why = [w for w in why if w]
    result.reliable = not why
    if why:
        result.reason = '; '.join(why)
        return
    j_iv = result.J_interval
    j_note = ('; J is not bounded by the data (weakly identifiable)' if j_iv is None
              else '; J is weakly determined, read its interval' if j_iv[1] - j_iv[0] > 0.5 *
              max(result.S, 1e-9) else '')
    result.reason = (f'a sticky valve explains PV better than a linear one (residual variance '
                     f'ratio {ratio:.3g}, likelihood ratio {lr:.3g}); S = {result.S:.3g} % '
                     f'(95 % range {result.S_interval[0]:.3g}-{result.S_interval[1]:.3g}){j_note}')

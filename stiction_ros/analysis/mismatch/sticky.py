"""
With friction present: which physics does Kano's plain model leave out, one or two effects.

The friction effects of EFFECTS.md and the chain's dead time and calibration
compete on one scale: the likelihood ratio against the plain model over the
largest any candidate reached on effect-free bootstrap replicates
(:mod:`explain`).  The best passing candidate is taken first; when it is a
chain stage, the friction effects are searched again on the record with that
stage undone, with the same thresholds, for a second effect.  A dead time
and an actuator lag, an offset and direction-dependent friction, look alike
in part; whichever fits better wins, as a greedy forward selection would.
"""

from stiction_ros.analysis.mismatch import explain as fx
from stiction_ros.analysis.mismatch import instrument as ins
from stiction_ros.analysis.mismatch import sentences
from stiction_ros.analysis.mismatch.stats import acf1, chi2_999

STAGE_NAMES = {'delay': 'dead_time', 'offset': 'positioner_calibration'}
SUBSAMPLE_LAGS = ('actuator_lag', 'measurement_lag')
STAGE_SETS = (('delay',), ('offset', 'gain'), ('delay', 'offset', 'gain'))
PLAUSIBLE = ins.PLAUSIBLE


def _plausible(fit, stages):
    timing = 'delay' not in stages or fit.params['delay'] >= PLAUSIBLE['delay']
    calib = 'offset' not in stages or (abs(fit.params['offset']) >= PLAUSIBLE['offset']
                                       or abs(fit.params['gain'] - 1.0) >= PLAUSIBLE['gain'])
    return timing and calib


# The friction effects whose bootstrap LRs stand in for a stage's: a dead time is a
# timing stage like a lag, an offset or gain shifts positions like direction- or
# position-dependent friction.
ANALOGUES = {'delay': ('actuator_lag', 'measurement_lag'),
             'offset': ('asymmetric_friction', 'position_dependent_friction'),
             'gain': ('asymmetric_friction', 'position_dependent_friction')}


def chain_candidates(op, mv, fit_segs, sample_time, plain_sse, worst, hint) -> list:
    """Return the dead-time and calibration candidates, scored like the friction effects."""
    out, delay = [], None
    for stages in STAGE_SETS:
        # The dead time is searched once; with calibration it is held at that value.
        c = ins.fit_friction(op, mv, fit_segs, sample_time, 'stiction', stages, hint=hint,
                             delay=delay if len(stages) == 3 else None)
        if stages == ('delay',):
            delay = c.params['delay']
        stat = fx.lr(c.n, plain_sse, c.sse)
        top = max((worst.get(e, 0.0) for s in stages for e in ANALOGUES[s]), default=0.0)
        thr = max(chi2_999(len(stages)), fx.MARGIN * top)
        out.append({'stages': stages, 'fit': c, 'lr': round(stat, 3), 'threshold': round(thr, 3),
                    'score': round(stat / thr, 4) if _plausible(c, stages) else 0.0,
                    'k': len(stages)})
    return out


def explain_sticky(t, op, mv, segments, sample_time, holdout, reps, seed, say, jobs, hint):
    """Return (report, arrays, effects named) of a valve with friction, Kano's model first."""
    say('friction present: which physics does the plain model leave out?')
    report, arrays = fx.explain(t, op, mv, segments, sample_time, holdout=holdout, reps=reps,
                                seed=seed, progress=say, jobs=jobs)
    m = report['mismatch']
    n_fit = report['holdout']['first_sample']
    fit_segs = fx.split_segments(segments, n_fit)
    plain_sse = report['baseline']['mse_fit'] * report['holdout']['fit_samples']
    worst = m['bootstrap']['largest_lr']
    say('fitting dead time and calibration against the friction effects')
    cands = chain_candidates(op, mv, fit_segs, sample_time, plain_sse, worst, hint)
    # Greedy forward selection on one scale: the likelihood ratio less the chi-square
    # penalty of the parameters it adds, among candidates that pass their threshold.
    passing = [c for c in cands if c['score'] > 1.0]
    best = max(passing, key=lambda c: c['lr'] - chi2_999(c['k']), default=None)
    effects = [c for c in report['candidates'] if c['score'] > 1.0]
    top_effect = max((c['lr'] - chi2_999(len(c['params'])) for c in effects), default=-1.0)
    report['chain_candidates'] = _summaries(cands, sample_time)
    if best is None or best['lr'] - chi2_999(best['k']) <= top_effect:
        return report, arrays, _effect_list(report)
    chain = best['fit']
    say(f'kept {", ".join(chain.free)}; searching the friction effects once more')
    p = chain.params
    # OP is delayed by the whole samples only: the rest acts on the reading, which the
    # friction effects then see as a lag under a sample (named with the dead time).
    op_c = ins.shift(op, ins.split_delay(p['delay'])[0], segments)
    mv_c = (mv - p['offset']) / (p['gain'] or 1.0)
    plain, plain_arrays = report['baseline'], arrays
    # Fresh replicates: with the stage undone the plain fit's residual is smaller, and
    # replicates as noisy as the first search's misfit set thresholds too low for it.
    report, arrays = fx.explain(t, op_c, mv_c, segments, sample_time, holdout=holdout,
                                reps=reps, seed=seed, progress=say, jobs=jobs)
    report['chain_candidates'] = _summaries(cands, sample_time)
    report['chain_kept'] = {'stages': list(best['stages']), 'score': best['score']}
    _back_to_reading(report, arrays, op, mv, p, plain, plain_arrays)
    model = report['mismatch']['model']
    model['name'] = '+'.join(['kano'] + [STAGE_NAMES[s] for s in chain.free
                                         if s in STAGE_NAMES] + model['name'].split('+')[1:])
    model['params'].update({'dead_time_s': p['delay'] * sample_time, 'offset': p['offset'],
                            'gain': p['gain']})
    idx = ins.indices(fit_segs)
    rho = acf1((ins.chain_output(op, mv, fit_segs, chain) - mv)[idx])
    stages = sentences.chain_effects(chain, ins.standard_errors(op, mv, fit_segs, chain, rho),
                                     sample_time)
    second = _effect_list(report)
    lag = report['mismatch']['model']['params'].get('time_constant_s')
    if ('delay' in chain.free and report['mismatch']['effect'] in SUBSAMPLE_LAGS
            and lag is not None and lag <= sample_time):
        # A lag under one sample beside a dead time is the dead time's fraction of a
        # sample seen through the slips; it is not a second effect.
        second = []
    return report, arrays, stages + second


def _summaries(cands, sample_time):
    return [{'stages': list(c['stages']), 'lr': c['lr'], 'threshold': c['threshold'],
             'score': c['score'], 'S': c['fit'].S, 'J': c['fit'].J,
             'dead_time_s': round(c['fit'].params['delay'] * sample_time, 4),
             'offset': round(c['fit'].params['offset'], 4),
             'gain': round(c['fit'].params['gain'], 5)} for c in cands]


def _effect_list(report):
    """Return the friction effect of a report as a named effect with size and error."""
    m = report['mismatch']
    if m['effect'] in ('none', 'unexplained'):
        return []
    cand = next((c for c in report['candidates'] if c['effect'] == m['effect']), {})
    params, errors = cand.get('params', {}), cand.get('standard_errors', {})
    first = next(iter(params), None)
    return [{'id': m['effect'], 'size': None if first is None else params[first],
             'unit': first or '', 'uncertainty': errors.get(first),
             'sentence': m['explanation'], 'params': m['model']['params'],
             'standard_errors': errors}]


def _back_to_reading(report, arrays, op, mv, p, plain, plain_arrays):
    """Put the second run's model back on the reading's own scale and clock."""
    fit_mask, hold_mask = arrays['fit_mask'], arrays['hold_mask']
    arrays['mv_explained'] = p['offset'] + p['gain'] * arrays['mv_explained']
    arrays['mv'], arrays['op'] = mv, op
    # The plain model stays the one fitted on the reading as it came.
    for key in ('mv_baseline', 'resting', 'breakaways'):
        arrays[key] = plain_arrays[key]
    report['baseline'] = plain
    m = report['mismatch']
    m['mse_fit'] = fx.masked_mse(arrays['mv_explained'], mv, fit_mask)
    m['mse_holdout'] = fx.masked_mse(arrays['mv_explained'], mv, hold_mask)
    s = report['series']
    s['op'], s['mv'] = fx._json(op), fx._json(mv)
    s['mv_baseline'] = fx._json(arrays['mv_baseline'])
    s['mv_explained'] = fx._json(arrays['mv_explained'])

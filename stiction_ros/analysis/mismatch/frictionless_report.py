"""The report of a valve explained without stiction (no friction or backlash), Kano beside."""

import numpy as np

from stiction_ros.analysis.identify import identify
from stiction_ros.analysis.mismatch import explain as friction_explain
from stiction_ros.analysis.mismatch import locate
from stiction_ros.analysis.mismatch.explain import masked_mse
from stiction_ros.analysis.mismatch.fit import RESOLUTION
from stiction_ros.analysis.mismatch.stats import acf1


def without_friction(t, op, mv, segments, sample_time, chain, mv_chain, n_fit, holdout,
                     effects):
    """Return (report, arrays) of a valve explained by ``chain`` (no stiction), Kano beside."""
    baseline, mv_base, rest = plain_baseline(op, mv, segments, sample_time, n_fit)
    fit_mask, hold_mask = friction_explain.scored_masks(segments, len(op), n_fit)
    located = friction_explain.without_start(fit_mask, segments)
    residual = mv - mv_base
    labels = locate.regime_labels(op, np.where(np.isfinite(mv_base), mv_base, mv), rest)
    labels.update(locate.time_thirds(len(op), fit_mask))
    effect = effects[0]['id'] if effects else 'none'
    explanation = (' '.join(e['sentence'] for e in effects) if effects else
                   'Nothing is missing: the valve follows OP up to noise, with no friction, '
                   'dead time, lag or calibration error that the data can show.')
    name = 'frictionless' if chain.friction == 'none' else 'backlash'
    report = {
        'baseline': baseline,
        'mismatch': {
            'effect': effect, 'effects': effects,
            'confidence': 1.0, 'explanation': explanation,
            'regions': locate.regions(t, residual, labels, located),
            'regimes': locate.regime_shares(residual, labels, located),
            'model': {'name': name, 'params': {'S': chain.S, 'J': chain.J, **chain.params}},
            'mse_fit': masked_mse(mv_chain, mv, fit_mask),
            'mse_holdout': masked_mse(mv_chain, mv, hold_mask),
            'residual_acf1': round(acf1((mv - mv_chain)[fit_mask]), 4)},
        'candidates': [],
        'holdout': {'share': holdout, 'first_sample': n_fit,
                    't_start': float(t[n_fit]) if n_fit < len(op) else None,
                    'fit_samples': int(np.sum(fit_mask)),
                    'holdout_samples': int(np.sum(hold_mask))},
        'series': {'t': t.tolist(), 'op': friction_explain._json(op),
                   'mv': friction_explain._json(mv),
                   'mv_baseline': friction_explain._json(mv_base),
                   'mv_explained': friction_explain._json(mv_chain)},
    }
    arrays = {'t': t, 'op': op, 'mv': mv, 'mv_baseline': mv_base, 'resting': rest,
              'mv_explained': mv_chain, 'fit_mask': fit_mask, 'hold_mask': hold_mask,
              'breakaways': locate.breakaways(t, op, mv, mv_base, rest, sample_time)}
    return report, arrays


def plain_baseline(op, mv, segments, sample_time, n_fit):
    """Return (section, output, resting) of the plain Kano model fitted before ``n_fit``."""
    fit_segs = friction_explain.split_segments(segments, n_fit)
    base = identify(op, mv, 'kano', segments=fit_segs, sample_time=sample_time,
                    resolution=RESOLUTION, interval=False)
    mv_base, rest = friction_explain.model_output(op, mv, segments, base.S, base.J,
                                                  friction_explain.kk.plain_params())
    fit_mask, hold_mask = friction_explain.scored_masks(segments, len(op), n_fit)
    return ({'model': 'kano', 'S': base.S, 'J': base.J,
             'mse_fit': masked_mse(mv_base, mv, fit_mask),
             'mse_holdout': masked_mse(mv_base, mv, hold_mask)}, mv_base, rest)

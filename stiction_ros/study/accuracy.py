"""
How well the verdict and each signature separate sticky from healthy valves on labelled loops.

Honesty rules: a signature alone uses its paper's threshold, tuned on
nothing here.  The combined verdict has choices (which signatures vote, the
score threshold); those are chosen on the training loops of each fold and
scored on the held-out ones.  Folds leave one *loop* (historian tag) out,
not one file, because several files of the same valve would otherwise sit on
both sides of a fold.  An undetermined answer counts as "no stiction": a
verdict that declines to decide earns nothing.
"""

from itertools import product

import numpy as np

from stiction_ros.analysis.signature_vote import from_signatures, THRESHOLD, WEIGHTS

SIGNATURES = tuple(WEIGHTS)
THRESHOLDS = (0.25, 0.34, 0.5, 0.67, 0.75, 1.0)


def confusion(truth, predicted):
    """Return {tp, fn, fp, tn} with stiction as the positive class."""
    truth = np.asarray(truth, dtype=bool)
    pred = np.asarray(predicted, dtype=bool)
    return {'tp': int(np.sum(truth & pred)), 'fn': int(np.sum(truth & ~pred)),
            'fp': int(np.sum(~truth & pred)), 'tn': int(np.sum(~truth & ~pred))}


def balanced_accuracy(c):
    """Return the mean of sensitivity and specificity of a confusion dict."""
    sens = c['tp'] / (c['tp'] + c['fn']) if c['tp'] + c['fn'] else float('nan')
    spec = c['tn'] / (c['tn'] + c['fp']) if c['tn'] + c['fp'] else float('nan')
    return 0.5 * (sens + spec)


def decide(case, weights, threshold):
    """Return True when the combined verdict calls ``case`` sticky under these choices."""
    detected, _, _ = from_signatures(case['oscillation'], case['signatures'], weights,
                                     threshold)
    return bool(detected)


def candidate_rules():
    """Return every (weights, threshold) the folds may choose from."""
    rules = []
    for mask in product((0.0, 1.0), repeat=len(SIGNATURES)):
        if sum(mask):
            weights = dict(zip(SIGNATURES, mask))
            rules += [(weights, th) for th in THRESHOLDS]
    return rules


def best_rule(cases, rules):
    """Return the rule with the highest balanced accuracy on ``cases`` (ties: published rule)."""
    def score(rule):
        c = confusion([x['label'] for x in cases], [decide(x, *rule) for x in cases])
        return balanced_accuracy(c)
    published = (dict(WEIGHTS), THRESHOLD)
    best, best_score = published, score(published)
    for rule in rules:
        s = score(rule)
        if s > best_score + 1e-12:
            best, best_score = rule, s
    return best, best_score


def cross_validate(cases):
    """
    Return (predictions, chosen rules) of leave-one-loop-out cross-validation.

    ``cases``: dicts with ``group`` (loop tag), ``label`` (True = sticky),
    ``oscillation`` and ``signatures`` as the pipeline computes them.
    """
    rules = candidate_rules()
    predictions = [None] * len(cases)
    chosen = []
    for group in sorted({c['group'] for c in cases}):
        train = [c for c in cases if c['group'] != group]
        rule, _ = best_rule(train, rules)
        chosen.append((group, rule))
        for i, c in enumerate(cases):
            if c['group'] == group:
                predictions[i] = decide(c, *rule)
    return predictions, chosen


def signature_alone(cases, name):
    """Return the predictions of one signature at its published threshold."""
    return [bool(c['signatures'][name].stiction) if name in c['signatures'] else False
            for c in cases]

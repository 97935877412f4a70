"""
The old rule: the OP/PV stiction signatures vote.

With neither a measured position nor the learned detector, the OP/PV
signatures vote: each decided signature counts 1 for stiction and 0 against,
weighted by ``WEIGHTS``; an undetermined one does not vote.  ``score`` is the
weighted mean of the votes and stiction is reported when it reaches
``THRESHOLD``.  In a loop without a regular oscillation only the signatures
of ``WITHOUT_OSCILLATION`` vote: they look for single stick-slip events,
where the others need a limit cycle (Yamashita's index needs none either, but
it also fires on noisy healthy loops, see docs/ACCURACY.md).  The weights and
the threshold are the ones whose cross-validated accuracy on the real plant
loops is in ``docs/ACCURACY.md``.
"""

WEIGHTS = {'horch': 1.0, 'he_curve_fit': 1.0, 'hos_pv_op': 1.0, 'yamashita': 1.0,
           'slip_events': 1.0}
THRESHOLD = 0.5
WITHOUT_OSCILLATION = ('slip_events',)


def from_signatures(osc, sigs, weights=None, threshold=None):
    """Return (detected, score, reason) from the OP/PV signatures."""
    weights = WEIGHTS if weights is None else weights
    threshold = THRESHOLD if threshold is None else threshold
    votes = {n: s.stiction for n, s in sigs.items() if s.stiction is not None}
    said = ', '.join(f'{n} {"yes" if v else "no"}' for n, v in votes.items())
    steady = osc is not None and not osc.oscillating
    if steady:
        votes = {n: v for n, v in votes.items() if n in WITHOUT_OSCILLATION}
    total = sum(weights.get(n, 0.0) for n in votes)
    if total == 0.0:
        if steady:
            return False, 0.0, f'no regular oscillation and no slip event; signatures: {said}'
        return None, 0.0, 'no signature could decide'
    score = sum(weights.get(n, 0.0) for n, v in votes.items() if v) / total
    if steady:
        return (score >= threshold, score,
                f'no regular oscillation; voting without one: '
                f'{", ".join(votes)} (score {score:.2f}); all signatures: {said}')
    return score >= threshold, score, f'signatures: {said} (score {score:.2f})'

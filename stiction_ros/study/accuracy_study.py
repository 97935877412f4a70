"""
The accuracy study behind docs/ACCURACY.md: every method on the same held-out records.

Two held-out sets, reported first:

* the labelled plant loops, grouped by valve (historian tag).  The learned
  detector is trained and calibrated on simulated loops only, so every tag
  is scored by a model that never saw it; the old rule's cross-validated
  row chooses its voters and threshold on the other tags, fold by fold;
* simulated records whose seeds were never used for training, calibration
  or any choice of threshold (``dataset.TEST``).

Each method is a function of one case giving True (stiction), False (no
stiction) or None (cannot tell).  Balanced accuracy counts ``cannot tell``
as "no stiction" (a refusal earns nothing), and is also given on the
decided records alone with the share decided.
"""

import numpy as np

from stiction_ros.analysis.detection.detect import answer_of, BALANCED, BAND, THRESHOLD
from stiction_ros.analysis.detection.features import FEATURE_NAMES
from stiction_ros.analysis.signatures import he_curve_fit, horch, slip_events, yamashita
from stiction_ros.analysis.verdict import ANSWER
from stiction_ros.study.accuracy import balanced_accuracy, confusion

# Published thresholds of the single signatures, read from the feature vector.
FEATURE_RULES = {
    'horch alone (published 120 deg)': ('horch_deg', horch.STICTION_DEG),
    'he_curve_fit alone (published SI 0.6)': ('he_si', he_curve_fit.STICTION_SI),
    'yamashita alone (published 0.25)': ('yamashita', yamashita.THRESHOLD),
    'slip_events alone (1 event)': ('slip_events', slip_events.THRESHOLD),
}

# The detector's two ways of answering, as the tables name them.
FORCED = f'probability >= {THRESHOLD}'
BANDED = f'cannot tell at {BALANCED[0]}-{BALANCED[1]}'
# Which of the two the analyzer prints.
SHIPPED = BANDED if BAND == BALANCED else FORCED
ANSWER_FLAG = {word: flag for flag, word in ANSWER.items()}


def band_answer(p: float) -> bool | None:
    """Return the band's answer at ``p`` as True, False or None (balanced: cannot tell)."""
    return ANSWER_FLAG[answer_of(float(p), BALANCED)]


def score(truth, answers) -> dict:
    """Return confusion counts, cannot-tell counts and both balanced accuracies."""
    truth = np.asarray(truth, dtype=bool)
    told = np.array([a is not None for a in answers], dtype=bool)
    pred = np.array([bool(a) for a in answers], dtype=bool)
    c = confusion(truth, pred)
    out = {**c, 'cannot_tell_sticky': int(np.sum(truth & ~told)),
           'cannot_tell_healthy': int(np.sum(~truth & ~told)),
           'balanced_accuracy': balanced_accuracy(c), 'decided_share': float(np.mean(told))}
    if told.any() and truth[told].any() and (~truth[told]).any():
        out['balanced_accuracy_decided'] = balanced_accuracy(confusion(truth[told],
                                                                       pred[told]))
    else:
        out['balanced_accuracy_decided'] = float('nan')
    return out


def feature_rule(x: np.ndarray, name: str, threshold: float) -> list:
    """Return the answers of ``feature >= threshold`` (NaN: the signature does not apply)."""
    v = x[:, FEATURE_NAMES.index(name)]
    return [bool(val >= threshold) if np.isfinite(val) else False for val in v]


def best_threshold(values: np.ndarray, truth: np.ndarray) -> float:
    """Return the threshold of ``values >= t`` with the best balanced accuracy on these cases."""
    cand = np.unique(np.round(values[np.isfinite(values)], 3))
    best, best_ba = float('inf'), -1.0
    for t in cand:
        ba = balanced_accuracy(confusion(truth, np.nan_to_num(values, nan=-np.inf) >= t))
        if ba > best_ba + 1e-12:
            best, best_ba = float(t), ba
    return best


def sim_rows(test: dict, model, stuck_threshold: float) -> dict:
    """
    Return {method: score} on a simulated set built by ``dataset.build``.

    ``test['large_logit']``: the large network's logit of each record, for a
    detector that weighs it in (``stack.seed_logits``).
    """
    x, y = test['x'], test['y']
    p = model.probability(x, test.get('large_logit')) if len(y) else np.zeros(0)
    rows = {f'learned detector ({FORCED})': score(y, list(p >= THRESHOLD)) if len(y) else None,
            f'learned detector, {BANDED}': score(y, [band_answer(v) for v in p])
            if len(y) else None,
            'old rule (signature vote, published weights)': score(y, list(test['old_rule'])),
            f'stuck-period test alone (OP share >= {stuck_threshold:.3g}, set on simulation)':
            score(y, feature_rule(x, 'stuck_op_share', stuck_threshold))}
    for label, (name, th) in FEATURE_RULES.items():
        rows[label] = score(y, feature_rule(x, name, th))
    return rows


def by_kind(test: dict, model) -> list:
    """
    Return rows of the simulated set by kind: kind, label, records, shares.

    The shares: called stiction at ``THRESHOLD``, and with the band called
    stiction and left at cannot tell.
    """
    p = model.probability(test['x'], test.get('large_logit'))
    band = np.array([band_answer(v) for v in p], dtype=object)
    rows = []
    for kind in sorted(set(test['kind'])):
        for lab in (True, False):
            m = (test['kind'] == kind) & (test['y'] == lab)
            if m.any():
                rows.append((str(kind), lab, int(m.sum()), float(np.mean(p[m] >= THRESHOLD)),
                             float(np.mean([b is True for b in band[m]])),
                             float(np.mean([b is None for b in band[m]]))))
    return rows


# Stated probability bins of the reliability table: the tails apart, since the
# calibration map's end steps are where a probability can claim too much.
RELIABILITY_BINS = (0.0, 0.01, 0.05, 0.2, 0.5, 0.8, 0.95, 0.99, 1.0)


def reliability(y: np.ndarray, p: np.ndarray) -> dict:
    """
    Return how the stated probability compares with what happened, at even odds.

    Each class weighs half, as in the calibration, so a bin's observed rate
    is the share of sticky records it would hold were sticky and healthy
    loops equally common.  ``rows``: (low, high, records, sticky, mean
    stated, observed); ``log_loss`` and ``brier``: the class-balanced means
    (a stated 0 or 1 that is wrong makes the log loss infinite).
    """
    y, p = np.asarray(y, dtype=bool), np.asarray(p, dtype=float)
    w = np.where(y, 0.5 / max(y.sum(), 1), 0.5 / max((~y).sum(), 1))
    rows = []
    for lo, hi in zip(RELIABILITY_BINS[:-1], RELIABILITY_BINS[1:]):
        m = (p >= lo) & ((p < hi) if hi < 1.0 else (p <= hi))
        if m.any():
            rows.append((lo, hi, int(m.sum()), int(y[m].sum()), float(p[m].mean()),
                         float((w[m] * y[m]).sum() / w[m].sum())))
    with np.errstate(divide='ignore'):
        loss = -np.where(y, np.log(p), np.log1p(-p))
    return {'rows': rows, 'log_loss': float((w * loss).sum()),
            'brier': float((w * (p - y) ** 2).sum())}


def per_tag(cases: list, answers: list) -> list:
    """Return rows (tag, label, records, called stiction, cannot tell) of the plant loops."""
    rows = []
    for tag in sorted({c['group'] for c in cases}):
        idx = [i for i, c in enumerate(cases) if c['group'] == tag]
        lab = cases[idx[0]]['label']
        rows.append((tag, lab, len(idx), sum(answers[i] is True for i in idx),
                     sum(answers[i] is None for i in idx)))
    return rows


def threshold_by_tag(groups: list, truth: list, probability: list) -> tuple:
    """
    Return (answers, {tag: threshold}) of a probability threshold chosen leave-one-tag-out.

    For each tag the threshold is the one with the best balanced accuracy on
    the other tags' records (their own probabilities are the candidates;
    ties go to the candidate nearest 0.5, the threshold set on simulation),
    and only the held-out tag is answered with it.  A record without a
    probability (``cannot tell``) stays unanswered in its fold and counts as
    "no stiction" where it trains; other tags of one label alone choose
    nothing, and the fold keeps 0.5.  This fits one number on plant loops, so
    it measures how far the simulated probability is off on the plant, not
    what the shipped verdict answers.
    """
    groups = np.asarray(groups)
    y = np.asarray(truth, dtype=bool)
    told = np.array([p is not None for p in probability])
    p = np.array([-np.inf if v is None else float(v) for v in probability])
    answers: list = [None] * len(p)
    chosen = {}
    for tag in sorted(set(groups.tolist())):
        held = groups == tag
        train = ~held
        best, best_ba = 0.5, -1.0
        for t in sorted(set(p[train & told].tolist()), key=lambda v: abs(v - 0.5)):
            ba = balanced_accuracy(confusion(y[train], p[train] >= t))
            if ba > best_ba + 1e-12:
                best, best_ba = t, ba
        chosen[tag] = best
        for i in np.flatnonzero(held & told):
            answers[i] = bool(p[i] >= best)
    return answers, chosen

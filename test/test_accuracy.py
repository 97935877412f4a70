"""Scoring and the leave-one-loop-out protocol of docs/ACCURACY.md, on known cases."""

from types import SimpleNamespace

import pytest

from stiction_ros.analysis.signatures.result import Signature
from stiction_ros.study.accuracy import balanced_accuracy, confusion, cross_validate


def case(group, label, **votes):
    sigs = {n: Signature(n, None, None, v, '', '') for n, v in votes.items()}
    return {'group': group, 'label': label, 'signatures': sigs,
            'oscillation': SimpleNamespace(oscillating=True)}


def test_confusion_and_balanced_accuracy():
    c = confusion([True, True, False, False, False], [True, False, False, False, True])
    assert c == {'tp': 1, 'fn': 1, 'fp': 1, 'tn': 2}
    assert balanced_accuracy(c) == pytest.approx(0.5 * (1 / 2 + 2 / 3))


def test_cv_finds_the_one_informative_signature_in_every_fold():
    # yamashita always right, horch always wrong: every fold must learn to ignore horch
    cases = [case(f'L{i}', i % 2 == 0, yamashita=i % 2 == 0, horch=i % 2 == 1)
             for i in range(8)]
    pred, chosen = cross_validate(cases)
    assert pred == [c['label'] for c in cases]
    assert all(rule[0]['horch'] == 0.0 for _, rule in chosen)


def test_a_held_out_loop_cannot_teach_its_own_rule():
    # horch is right only on loop X; held out, the other loops never saw it work
    cases = [case('X', True, horch=True), case('X', False, horch=False)]
    cases += [case(f'L{i}', i % 2 == 0, horch=i % 2 == 1, yamashita=i % 2 == 0)
              for i in range(6)]
    pred, _ = cross_validate(cases)
    assert pred[0] is False  # loop X judged by a rule learnt without X


def test_the_probability_threshold_chosen_on_other_tags_never_reads_the_held_out_one():
    from stiction_ros.study.accuracy_study import threshold_by_tag
    groups = ['A', 'A', 'B', 'B', 'C', 'C', 'D']
    truth = [True, True, True, False, False, False, False]
    prob = [0.30, 0.35, 0.32, 0.10, 0.12, 0.05, None]
    answers, chosen = threshold_by_tag(groups, truth, prob)
    # Sticky records at 0.30-0.35 and healthy ones at most 0.12: every fold
    # learns a threshold in that gap, far under the simulation's 0.5.
    assert all(0.12 < t <= 0.35 for t in chosen.values())
    assert answers[:6] == [p >= chosen[g] for g, p in zip(groups[:6], prob[:6])]
    assert answers[3:6] == [False] * 3
    assert answers[6] is None   # cannot tell stays cannot tell
    # Moving A's own probabilities moves nothing in A's fold.
    moved, again = threshold_by_tag(groups, truth, [0.9, 0.01] + prob[2:])
    assert again['A'] == chosen['A'] and moved[:2] == [True, False]
    # Other tags of one label alone choose nothing: the fold keeps the simulation's 0.5.
    lone, flat = threshold_by_tag(['A', 'B', 'C'], [True, True, False], [0.2, 0.6, 0.45])
    assert flat['C'] == 0.5 and lone[2] is False


def test_the_band_decides_only_at_three_to_one_and_counts_what_it_declines():
    import numpy as np
    from stiction_ros.analysis.detection.features import FEATURE_NAMES
    from stiction_ros.study.accuracy_study import BANDED, by_kind, FORCED, sim_rows
    p = np.array([0.9, 0.6, 0.4, 0.1, 0.8, 0.3, 0.2, 0.76])
    y = np.array([True] * 4 + [False] * 4)
    model = SimpleNamespace(probability=lambda x, logit=None: p)
    test = {'x': np.full((8, len(FEATURE_NAMES)), np.nan), 'y': y,
            'old_rule': [False] * 8, 'kind': np.array(['kano'] * 4 + ['linear'] * 4)}
    rows = sim_rows(test, model, 0.5)
    forced, band = rows[f'learned detector ({FORCED})'], rows[f'learned detector, {BANDED}']
    assert (forced['tp'], forced['fn'], forced['fp'], forced['tn']) == (2, 2, 2, 2)
    assert forced['decided_share'] == 1.0
    # 0.6, 0.4 (sticky) and 0.3 (healthy) are declined; a refusal counts as "no stiction".
    assert (band['cannot_tell_sticky'], band['cannot_tell_healthy']) == (2, 1)
    assert (band['tp'], band['fn'], band['fp'], band['tn']) == (1, 3, 2, 2)
    assert band['decided_share'] == pytest.approx(5 / 8)
    assert band['balanced_accuracy_decided'] == pytest.approx(0.5 * (1 / 2 + 1 / 3))
    assert by_kind(test, model) == [('kano', True, 4, 0.5, 0.25, 0.5),
                                    ('linear', False, 4, 0.5, 0.5, 0.25)]


def test_the_plant_rows_score_the_band_from_the_reports_probabilities():
    from stiction_ros.cli.accuracy import plant_rows
    from stiction_ros.study.accuracy_study import BANDED, FORCED
    # A record that cannot be judged has no probability and stays cannot tell both ways.
    prob = [0.9, 0.43, None, 0.1, 0.6, 0.2]
    cases = [case(f'T{i}', i < 3) for i in range(6)]
    for c, p in zip(cases, prob):
        c['report'] = {'stiction': {'probability': p, 'signature_vote': {'detected': False},
                                    'detector': {'features': {}}}}
    rows = plant_rows(cases, [False] * 6, 0.5)
    forced = next(v for k, v in rows.items() if FORCED in k)
    band = next(v for k, v in rows.items() if BANDED in k)
    assert (forced['tp'], forced['fp'], forced['cannot_tell_sticky']) == (1, 1, 1)
    assert (band['tp'], band['fp'], band['cannot_tell_sticky'], band['cannot_tell_healthy']) \
        == (1, 0, 2, 1)

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

"""A record cut into stretches: the pooled answer, and the study that scores it."""

import json
import math

import numpy as np
import pytest

from stiction_ros.analysis.detection.stretches import logit, pooled_probability
from stiction_ros.study.gaps import answers, gap_of, MARGIN, SHARES


def test_pooled_odds_lie_between_the_stretches_and_weigh_them_by_length():
    assert pooled_probability([0.8], [300]) == pytest.approx(0.8)
    # Stretches that agree give their own reading, not a stronger one.
    assert pooled_probability([0.9, 0.9], [200, 500]) == pytest.approx(0.9)
    p = pooled_probability([0.9, 0.2], [600, 200])
    assert 0.2 < p < 0.9
    # The longer stretch pulls harder; equal lengths meet at the mean log-odds.
    assert p > pooled_probability([0.9, 0.2], [200, 600])
    mean = (logit(0.9) + logit(0.2)) / 2
    assert pooled_probability([0.9, 0.2], [300, 300]) == pytest.approx(1 / (1 + math.exp(-mean)))
    # Symmetric: stiction and no stiction swap places exactly.
    assert pooled_probability([0.1, 0.8], [300, 400]) == pytest.approx(
        1 - pooled_probability([0.9, 0.2], [300, 400]))
    assert pooled_probability([0.0, 1.0], [100, 100]) == pytest.approx(0.5)
    with pytest.raises(ValueError):
        pooled_probability([], [])
    with pytest.raises(ValueError):
        pooled_probability([0.5], [0])


@pytest.mark.parametrize('share', SHARES)
def test_the_gap_keeps_clear_of_both_ends_and_takes_its_share(share):
    for seed in range(50):
        a, b = gap_of(1000, share, seed)
        assert b - a == round(share * 1000)
        assert a >= MARGIN * 1000 and b <= (1 - MARGIN) * 1000


def test_the_longest_stretch_answers_alone_and_the_pool_uses_every_judged_one():
    longest, pooled = answers([(400, 0.3), (500, None)])
    assert np.isnan(longest) and pooled == pytest.approx(0.3)
    longest, pooled = answers([(400, 0.3), (500, 0.8)])
    assert longest == 0.8 and pooled == pytest.approx(pooled_probability([0.3, 0.8], [400, 500]))
    assert all(np.isnan(v) for v in answers([(50, None), (60, None)]))


@pytest.mark.slow
def test_the_study_scores_the_records_make_accuracy_scores(tmp_path):
    from stiction_ros.analysis.detection import dataset, deadband_like
    from stiction_ros.cli.gaps import main
    seeds = range(3_600_000, 3_600_010)
    md, js = tmp_path / 'g.md', tmp_path / 'g.json'
    assert main(['--first-seed', str(seeds.start), '--seeds', '10', '--jobs', '1',
                 '--markdown', str(md), '--json', str(js)]) == 0
    study = json.loads(js.read_text())
    acc = deadband_like.leave_out(deadband_like.mark(dataset.build(seeds, progress=False)))
    assert study['records'] == len(acc['y']) and study['sticky'] == int(acc['y'].sum())
    assert len(study['rows']) == 3 * len(SHARES)
    for r in study['rows']:
        assert r['tp'] + r['fn'] == study['sticky']
        if r['rule'] == 'whole record':
            assert r['refused'] == 0 and r['differ_from_whole'] == 0
    assert '| 20% | every stretch pooled |' in md.read_text()

"""Position readings with effects the MV verdict was never set on, and the page scoring them."""

import numpy as np
import pytest

from stiction_ros.cli.mv_probes import markdown
from stiction_ros.sim.reading_probes import CASES, EFFECTS, probe_case
from stiction_ros.study.mv_verdict import MvVerdictStudy, runs

N = 1200


def _case(case, seed=3, ts=1.0, extra=0.0):
    return probe_case(case, seed, ts, N, 1.0, extra)


def test_a_seed_gives_both_valves_one_loop_and_one_effect():
    healthy, h_truth = _case('historian')
    sticky, s_truth = _case('sticky_historian')
    assert h_truth['sizes'] == s_truth['sizes'] and not h_truth['friction']
    assert s_truth['friction'] and s_truth['valve']['model'] == 'kano'
    np.testing.assert_array_equal(healthy['t'], sticky['t'])
    again, _ = _case('historian')
    np.testing.assert_array_equal(healthy['mv'], again['mv'])
    assert len(CASES) == 2 * len(EFFECTS)
    with pytest.raises(ValueError, match='unknown probe'):
        probe_case('nothing', 1)


def test_each_reading_effect_does_what_it_says():
    hist, truth = _case('historian', extra=1.0)
    moves = np.abs(np.diff(hist['mv']))
    # Exception reporting: a value is stored only past the deadband; else the last is held.
    assert np.all((moves == 0.0) | (moves > truth['sizes']['deadband']))
    held, truth = _case('sample_hold', extra=1.0)
    every = truth['sizes']['every']
    assert np.all(held['mv'][1:every] == held['mv'][0])
    # A characteristic is a rising curve of the stem position, off the diagonal inside.
    curve, truth = probe_case('characteristic', 3, 1.0, N, 0.0, 0.0)
    order = np.argsort(curve['mv_true'], kind='stable')
    assert np.all(np.diff(curve['mv'][order]) >= 0.0)
    assert np.max(np.abs(curve['mv'] - curve['mv_true'])) > 5.0
    frozen, truth = _case('frozen')
    assert np.sum(np.diff(frozen['mv']) == 0.0) >= truth['sizes']['share'] * N * 0.9
    jitter, truth = _case('jitter_drop')
    assert len(jitter['t']) == len(jitter['mv']) < N and truth['sizes']['dropped_share'] > 0
    spikes, truth = _case('spikes')
    assert np.max(np.abs(spikes['mv'] - spikes['mv_true'])) >= 3.0 - 0.5
    windup, truth = _case('windup')
    point = truth['sizes']['operating_point']
    assert 3.0 <= point <= 7.0 or 93.0 <= point <= 97.0


def test_the_probe_study_reads_its_own_cases_and_pages_them():
    plan = runs(2, 50, 'probe')
    assert {r.case for r in plan} == set(CASES) and all(r.family == 'probe' for r in plan)
    rows = [{'case': 'drift', 'truth': 'no stiction', 'answer': 'stiction', 'on_time':
             'stiction', 'jump': 'stiction', 'old': 'stiction', 'extra_mv_noise': 1.0,
             'cannot_tell': None, 'seed': 50, 'sample_time': 0.5, 'mv_noise': 1.0,
             'S': 0.4, 'J': 0.5},
            {'case': 'sticky_drift', 'truth': 'stiction', 'answer': 'cannot tell',
             'on_time': 'cannot tell', 'jump': 'no stiction', 'old': 'no stiction',
             'extra_mv_noise': 0.0, 'cannot_tell': 'noise_unknown', 'seed': 50,
             'sample_time': 0.5, 'mv_noise': 0.1, 'S': 3.0, 'J': 1.0}]
    study = MvVerdictStudy(50, 1, rows, 2.0)
    page = markdown({**study.to_json(), 'run': {'date': 'today', 'machine': 'here'}})
    assert '| **shipped** | 1 | 1/1 | 0/1 | 1 | 0 |' in page
    assert '| `sticky_drift` | stiction | 1 | 0 / 0 / 1 | 1 `noise_unknown` |' in page
    assert '- `drift` seed 50, 0.5 s, MV noise 1 %: stiction (fit S 0.40 %, J 0.50 %)' in page


def test_a_probe_record_is_read_as_the_analyzer_reads_a_csv():
    from stiction_ros.study.mv_verdict import read, Run
    row = read(Run('sticky_sample_hold', 9_000_001, 1.0, 1.0, 1.0, 'probe'))
    assert row['truth'] == 'stiction' and row['case'] == 'sticky_sample_hold'
    assert row['answer'] in ('stiction', 'no stiction', 'cannot tell')
    assert row['mv_noise'] == pytest.approx(1.005, abs=1e-3)

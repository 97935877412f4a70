"""The instrument-effect cases hide what they say, at the size they say, from their seed."""

from bench.instrument_bench import case_list, score, write_section
import numpy as np
import pytest

from stiction_ros.models.lags import first_order_pole
from stiction_ros.sim.instrument_cases import CASES, instrument_case

N = 1500
SEEDS = range(600000, 600006)


def xcorr_lag(op, mv, max_lag):
    a, b = np.diff(op), np.diff(mv)
    a, b = a - a.mean(), b - b.mean()
    return int(np.argmax([np.dot(a[:len(a) - k], b[k:]) for k in range(max_lag)]))


def test_every_case_is_reproducible_from_its_seed_and_seeds_differ():
    for case in CASES:
        r1, t1 = instrument_case(case, 600003, sample_time=2.0, n_samples=N, noise=0.5)
        r2, t2 = instrument_case(case, 600003, sample_time=2.0, n_samples=N, noise=0.5)
        r3, _ = instrument_case(case, 600004, sample_time=2.0, n_samples=N, noise=0.5)
        assert t1 == t2 and t1['case'] == case
        assert t1['effects'] == sorted(t1['effects']) and set(t1['sizes']) == set(t1['effects'])
        for k in ('t', 'sp', 'pv', 'op', 'mv'):
            assert len(r1[k]) == N and np.array_equal(r1[k], r2[k])
        assert not np.array_equal(r1['mv'], r3['mv'])
        assert r1['t'][-1] == pytest.approx((N - 1) * 2.0)
    # One seed: the same dead time wherever it hides, the same stiction in every sticky case.
    _, a = instrument_case('dead_time', 600003, n_samples=N)
    _, b = instrument_case('sticky_dead_time', 600003, n_samples=N)
    _, c = instrument_case('sticky_calibration', 600003, n_samples=N)
    assert a['sizes']['dead_time'] == b['sizes']['dead_time'] and b['valve'] == c['valve']


def test_the_loop_is_the_same_in_samples_at_every_sample_time():
    a, _ = instrument_case('clean_linear', 600001, sample_time=0.1, n_samples=N)
    b, _ = instrument_case('clean_linear', 600001, sample_time=5.0, n_samples=N)
    for k in ('sp', 'pv', 'op', 'mv'):
        assert np.allclose(a[k], b[k], atol=1e-9)
    assert np.ptp(a['op']) > 5.0


def test_dead_time_shows_as_the_lag_of_the_op_mv_cross_correlation():
    for seed in SEEDS:
        for ts in (0.1, 1.0, 5.0):
            rec, truth = instrument_case('dead_time', seed, sample_time=ts, n_samples=N)
            d = truth['sizes']['dead_time'] / ts
            assert d >= 0.5 - 1e-12
            assert abs(xcorr_lag(rec['op'], rec['mv'], 40) - d) <= 1.0, (seed, ts, d)


def test_clean_linear_mv_is_op_plus_the_mv_noise():
    for noise in (0.5, 2.0):
        rec, truth = instrument_case('clean_linear', 600002, n_samples=N, noise=noise)
        assert truth['effects'] == [] and truth['friction'] is False
        assert np.std(rec['mv'] - rec['op']) == pytest.approx(0.1 * noise, rel=0.1)


def test_quantised_mv_lies_on_the_grid_of_the_drawn_step():
    rec, truth = instrument_case('quantisation', 600004, sample_time=0.5, n_samples=N)
    q = truth['sizes']['quantisation']
    assert 0.25 <= q <= 1.0
    steps = rec['mv'] / q
    assert np.allclose(steps, np.round(steps), atol=1e-9)
    assert len(np.unique(rec['mv'])) > 5


def test_regression_of_mv_on_op_gives_the_positioner_gain_and_offset():
    for seed in SEEDS:
        rec, truth = instrument_case('positioner_calibration', seed, n_samples=8641)
        cal = truth['sizes']['positioner_calibration']
        assert 0.02 <= abs(cal['gain'] - 1.0) <= 0.06 and 0.5 <= abs(cal['offset']) <= 3.0
        (gain, offset), cov = np.polyfit(rec['op'], rec['mv'], 1, cov=True)
        se_gain, se_offset = np.sqrt(np.diag(cov))
        # Tight enough to tell the drawn gain from 1 and the offset from 0.
        assert se_gain < 0.005 and se_offset < 0.25
        assert abs(gain - cal['gain']) < 4 * se_gain
        assert abs(offset - cal['offset']) < 4 * se_offset


def test_response_lag_is_a_first_order_filter_of_op_without_noise():
    rec, truth = instrument_case('response_lag', 600005, sample_time=2.0, n_samples=N, noise=0)
    tau = truth['sizes']['response_lag']
    assert tau >= 0.7 * 2.0
    a = first_order_pole(tau, 2.0)
    op, mv = rec['op'], rec['mv']
    assert np.allclose(mv[1:], a * mv[:-1] + (1 - a) * op[1:], atol=1e-9)
    assert np.max(np.abs(mv - op)) > 0.1


def test_backlash_keeps_mv_within_half_the_play_of_op_and_reaches_it():
    rec, truth = instrument_case('backlash', 600000, n_samples=N, noise=0)
    half = truth['sizes']['backlash'] / 2
    gap = np.abs(rec['mv'] - rec['op'])
    assert truth['friction'] is False and gap.max() <= half + 1e-9
    assert np.mean(np.isclose(gap, half)) > 0.2


@pytest.mark.parametrize('kwargs', [
    {'case': 'stiction'}, {'seed': -1}, {'seed': 1.5}, {'sample_time': 0.0},
    {'sample_time': float('nan')}, {'n_samples': 10}, {'noise': -1.0}])
def test_bad_arguments_raise_value_error(kwargs):
    args = {'case': 'clean_linear', 'seed': 1, **kwargs}
    with pytest.raises(ValueError):
        instrument_case(args.pop('case'), args.pop('seed'), **args)


def test_bench_scores_missing_keys_as_wrong_and_exact_sets_as_right():
    run = case_list(1)[0]
    truth = {'friction': False, 'effects': [], 'sizes': {}}
    missing = score(run, truth, {'mismatch': {'effect': 'none'}})
    assert not missing['correct'] and missing['false_alarm'] and missing['ratio'] is None
    report = {'mismatch': {'friction': False, 'effects': [], 'mse_holdout': 0.01},
              'baseline': {'mse_holdout': 0.04}, 'frictionless': {'mse_holdout': 0.02}}
    row = score(run, truth, report)
    assert row['correct'] and not row['false_alarm'] and row['ratio'] == pytest.approx(0.5)
    truth = {'friction': True, 'effects': ['dead_time'], 'sizes': {'dead_time': 1.0}}
    report['mismatch'].update(friction=True, effects=[{'id': 'dead_time'}, {'id': 'backlash'}])
    assert not score(run, truth, report)['correct']


def test_bench_section_replaces_its_markers_and_keeps_the_rest(tmp_path):
    path = tmp_path / 'b.md'
    path.write_text('# Head\n\ntext\n')
    write_section(path, '<!-- instrument-bench:start -->\nA\n<!-- instrument-bench:end -->\n')
    write_section(path, '<!-- instrument-bench:start -->\nB\n<!-- instrument-bench:end -->\n')
    text = path.read_text()
    assert text.startswith('# Head\n\ntext\n') and 'B' in text and '\nA\n' not in text
    assert text.count('instrument-bench:start') == 1

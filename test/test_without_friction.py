"""The verdict's valve without friction: dead time, lag and calibration recovered from MV."""

import numpy as np
from scipy.signal import lfilter

from stiction_ros.analysis.fit_core import carried_runs
from stiction_ros.analysis.mismatch import instrument as ins
from stiction_ros.analysis.mismatch.frictionless import fit_frictionless
from stiction_ros.analysis.verdict import chain_words
from stiction_ros.analysis.without_friction import calibrated, fit_without_friction, \
    lagged, shift, significant
from stiction_ros.kernels.chain import limited


def _op(n=3000, seed=0):
    # Steps and a slow wander, as a PI controller's output under set-point and load steps.
    rng = np.random.default_rng(seed)
    op = 50 + np.repeat(rng.uniform(-8, 8, n // 150), 150) + np.cumsum(rng.normal(0, 0.05, n))
    return np.r_[op, np.full(n - len(op), op[-1])]


def test_a_known_chain_is_recovered_to_its_noise():
    op = _op()
    segs = [(0, 1400), (1410, 3000)]
    runs = carried_runs(segs, op)
    # 3.4 s dead time, 6 s lag at 0.5 s sampling, reading 1.5 % high and 3 % short.
    truth = 1.5 + 0.97 * lagged(shift(op, 6.8, segs), 12.0, runs)
    noise = np.random.default_rng(1).normal(0, 0.05, op.size)
    fit = fit_without_friction(op, truth + noise, segs, 0.5)
    assert abs(fit['dead_time_s'] - 3.4) < 0.1 and abs(fit['lag_s'] - 6.0) < 0.3
    assert abs(fit['offset'] - 1.5) < 0.2 and abs(fit['gain'] - 0.97) < 0.005
    # Nothing left but the noise it was read with, and no stage it was not read through.
    assert fit['mse'] < 1.05 * 0.05 ** 2
    assert fit['rate_pct_s'] is None and fit['stop_low'] is None and fit['stop_high'] is None


def test_the_lag_kernel_is_a_first_order_filter_at_rest_on_each_run():
    # The naive reference: scipy's filter, started at rest on each run's first sample.
    op = _op(seed=2)
    segs = [(0, 900), (905, 3000)]
    p = np.exp(-1.0 / 7.3)
    ref = op.copy()
    for a, b in carried_runs(segs, op):
        ref[a:b] = lfilter([1.0 - p], [1.0, -p], op[a:b], zi=[p * op[a]])[0]
    np.testing.assert_allclose(lagged(op, 7.3, carried_runs(segs, op)), ref, rtol=0,
                               atol=1e-10)
    # --explain's chain runs the same lag.
    assert np.array_equal(ins.lag(op, 7.3, segs), lagged(op, 7.3, carried_runs(segs, op)))


def test_the_grid_search_matches_explains_optimiser_on_the_same_stages():
    # A valve reading through a lag that no grid point holds: the refinement must find
    # what --explain's bounded Powell search finds on the same four stages.
    op = _op(seed=3)
    segs = [(0, 3000)]
    mv = -0.8 + 1.02 * lagged(shift(op, 2.6, segs), 7.7, carried_runs(segs, op))
    mv += np.random.default_rng(4).normal(0, 0.1, op.size)
    light = fit_without_friction(op, mv, segs, 1.0)
    full = fit_frictionless(op, mv, segs, 1.0, free=('delay', 'tau', 'offset', 'gain'))
    assert light['mse'] <= 1.001 * full.mse
    assert abs(light['dead_time_s'] - full.params['delay']) < 0.1
    assert abs(light['lag_s'] - full.params['tau']) < 0.2


def test_op_past_the_valve_stops_and_a_long_record():
    # OP winds up past 100 % and below 0: the valve sits at its stops, as an ideal one does.
    op = np.r_[_op(seed=5), np.linspace(50, 115, 400), np.full(300, 115.0),
               np.linspace(115, -10, 600), np.full(200, -10.0)]
    op = np.tile(op, 6)       # 27 000 samples: the search reads the first 20 000
    segs = [(0, op.size)]
    mv = np.clip(shift(op, 2.0, segs), 0, 100)
    mv += np.random.default_rng(6).normal(0, 0.1, op.size)
    fit = fit_without_friction(op, mv, segs, 1.0)
    assert abs(fit['dead_time_s'] - 2.0) < 0.05 and abs(fit['gain'] - 1.0) < 0.005
    assert fit['mse'] < 1.05 * 0.1 ** 2


def test_a_lagged_noisy_reading_of_a_noisy_op_is_no_still_valve(tmp_path):
    from stiction_ros.analysis.measures.still import still_valve
    from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
    from stiction_ros.sim.closed_loop import write_csv
    # OP's spread is mostly its own noise (a controller on a noisy PV every sample); MV
    # follows its slow part through a 30-sample lag, read with 1 % noise.
    rng = np.random.default_rng(7)
    n = 4000
    op = 50 + np.repeat(rng.uniform(-2, 2, n // 400), 400) + rng.normal(0, 3, n)
    segs = [(0, n)]
    mv = lagged(op, 30.0, segs) + rng.normal(0, 1, n)
    dead = 50 + rng.normal(0, 1, n)
    # Sample by sample MV stays within its noise and hardly correlates with OP.
    assert still_valve(op, mv, segs) is not None
    for name, reading in (('lagged', mv), ('dead', dead)):
        rows = {'t': np.arange(n, dtype=float), 'op': op, 'mv': reading}
        write_csv(tmp_path / f'{name}.csv', rows, columns=('t', 'op', 'mv'))
    lag = analyze_file(AnalyzeOptions(input=str(tmp_path / 'lagged.csv'), explain=True,
                                      jobs=1)).report
    assert lag['stiction'].get('cannot_tell') != 'mv_still'
    assert any('not read as still' in note for note in lag['notes'])
    # --explain reads the valve by the same test, and explains the lag.
    assert lag['mismatch']['friction'] is False
    assert [e['id'] for e in lag['mismatch']['effects']] == ['response_lag']
    # A dead reading needs a gain near zero to be fitted: still, as before.
    held = analyze_file(AnalyzeOptions(input=str(tmp_path / 'dead.csv'))).report
    assert held['stiction']['cannot_tell'] == 'mv_still'


def test_the_closed_form_calibration_is_the_least_squares_line():
    rng = np.random.default_rng(8)
    y = rng.normal(50, 5, 500)
    mv = 1.2 + 0.95 * y + rng.normal(0, 0.2, 500)
    idx = np.arange(20, 480)
    a = np.column_stack([np.ones(idx.size), y[idx]])
    (c0, c1), *_ = np.linalg.lstsq(a, mv[idx], rcond=None)
    offset, gain, sse = calibrated(y, mv, idx)
    assert abs(offset - c0) < 1e-9 and abs(gain - c1) < 1e-12
    assert abs(sse - float(np.sum((mv[idx] - c0 - c1 * y[idx]) ** 2))) < 1e-9


def test_a_travel_stop_is_found_and_leaves_the_calibration_alone():
    op = _op(seed=5)
    segs = [(0, 3000)]
    position = shift(op, 4.0, segs)
    stop = float(np.quantile(position, 0.95))
    noise = np.random.default_rng(6).normal(0, 0.1, op.size)
    held = 0.5 + 1.01 * np.minimum(position, stop) + noise
    fit = fit_without_friction(op, held, segs, 0.5)
    assert fit['stop_low'] is None and abs(fit['stop_high'] - (0.5 + 1.01 * stop)) < 0.2
    # Left out, the stop pulled the gain down; with it, the reading's own calibration.
    assert abs(fit['gain'] - 1.01) < 0.005 and abs(fit['offset'] - 0.5) < 0.3
    assert fit['mse'] < 1.05 * 0.1 ** 2
    # Without a stop none is claimed from the noise.
    free = fit_without_friction(op, 0.5 + 1.01 * position + noise, segs, 0.5)
    assert free['stop_low'] is None and free['stop_high'] is None


def test_an_actuator_rate_limit_is_found_where_a_lag_alone_leaves_the_ramps():
    op = _op(seed=7)
    segs = [(0, 3000)]
    runs = carried_runs(segs, op)
    # OP's steps (up to 16 %) ramp at 0.9 % a sample, 1.8 %/s at 0.5 s sampling.
    position = limited(shift(op, 3.0, segs), runs, 0.9)
    mv = 0.3 + 0.99 * lagged(position, 2.0, runs)
    mv += np.random.default_rng(8).normal(0, 0.1, op.size)
    fit = fit_without_friction(op, mv, segs, 0.5)
    assert abs(fit['rate_pct_s'] - 1.8) < 0.3 * 1.8
    assert fit['mse'] < 1.3 * 0.1 ** 2 and abs(fit['dead_time_s'] - 1.5) < 0.3
    assert 'rate limit' in chain_words(fit)


def test_a_stage_must_remove_a_third_and_pass_on_its_effective_samples():
    rng = np.random.default_rng(9)
    white = rng.normal(0, 1, 4000)
    # A slow misfit: the same 4 000 samples carry a few independent ones.
    slow = lfilter([1.0], [1, -0.999], rng.normal(0, 1, 4000))
    assert significant(1.0, 0.6, white)
    assert not significant(1.0, 0.6, slow)
    # A small share of the misfit is no stage, however many samples back it.
    assert not significant(1.0, 0.7, white)
    assert significant(1.0, 0.0, white) and not significant(0.0, 0.0, white)


def test_a_limit_cycle_is_no_pair_of_travel_stops():
    # A sticking valve's rests at its reversals, read by a valve without friction: the
    # extremes look held, but clipping them removes little of the misfit (on this seed a
    # one-parameter likelihood-ratio test alone kept a low stop at 48.5 %).
    from stiction_ros.sim.instrument_cases import instrument_case
    rec, _ = instrument_case('clean_sticky', 600001, sample_time=1.0, n_samples=4321)
    fit = fit_without_friction(rec['op'], rec['mv'], [(0, 4321)], 1.0)
    assert fit['stop_low'] is None and fit['stop_high'] is None
    assert fit['rate_pct_s'] is None

"""The valve through its instruments: chain stages, the frictionless fit and the friction claim."""

import math

import numpy as np
import pytest

from stiction_ros.analysis.mismatch import decide
from stiction_ros.analysis.mismatch import frictionless
from stiction_ros.analysis.mismatch import instrument as ins
from stiction_ros.analysis.mismatch import stats
from stiction_ros.sim.closed_loop import simulate_loop
from stiction_ros.sim.concealed_cases import concealed_case


@pytest.fixture(scope='module')
def loop():
    """Return a closed loop with a sticky valve (3 001 samples at 1 s) and its truth."""
    d, truth = concealed_case('none', 3, duration=3000.0)
    return d, truth


def _noise(n, std, seed=1):
    return std * np.random.default_rng(seed).standard_normal(n)


def test_shift_by_whole_samples_holds_the_first_value_and_halfway_interpolates():
    x = np.arange(10.0) ** 2
    y = ins.shift(x, 2.0, [(0, 10)])
    assert np.array_equal(y[:2], [x[0], x[0]]) and np.array_equal(y[2:], x[:-2])
    half = ins.shift(x, 0.5, [(0, 10)])
    assert np.allclose(half[1:], 0.5 * (x[1:] + x[:-1]))
    # Nothing crosses a gap where x is unknown; where it is known, a delay reads it.
    gap = np.where(np.arange(10) == 5, np.nan, x)
    two = ins.shift(gap, 1.0, [(0, 5), (6, 10)])
    assert two[6] == x[6] and two[7] == x[6]
    known = ins.shift(x, 1.0, [(0, 5), (6, 10)])
    assert known[6] == x[5] and known[7] == x[6]


def test_lag_step_response_is_the_exact_first_order_one():
    x = np.r_[np.zeros(10), np.ones(200)]
    tau = 4.0
    y = ins.lag(x, tau, [(0, len(x))])
    k = np.arange(len(x) - 10)
    assert np.allclose(y[10:], 1.0 - np.exp(-(k + 1) / tau))
    assert np.array_equal(ins.lag(x, 0.0, [(0, len(x))]), x)


def test_frictionless_fit_recovers_dead_time_lag_and_calibration(loop):
    d, _ = loop
    op = d['op']
    n = len(op)
    whole = [(0, n)]
    mv = 1.5 + 1.04 * ins.lag(ins.shift(op, 1.6, whole), 3.0, whole) + _noise(n, 0.1)
    stages = ('delay', 'tau', 'offset', 'gain')
    fit = frictionless.fit_frictionless(op, mv, [(0, 2000)], 1.0, free=stages)
    p = fit.params
    assert abs(p['delay'] - 1.6) < 0.2 and abs(p['tau'] - 3.0) < 0.3
    assert abs(p['offset'] - 1.5) < 0.3 and abs(p['gain'] - 1.04) < 0.01
    # The fitted chain explains the reading to its noise.
    assert fit.mse < 1.1 * 0.1 ** 2


def test_quantum_finds_a_transmitter_step_and_nothing_in_a_continuous_reading(loop):
    d, _ = loop
    n = len(d['op'])
    continuous = d['op'] + _noise(n, 0.1)
    idx = np.arange(n)
    assert ins.quantum(continuous, idx) == 0.0
    stepped = 0.5 * np.round(continuous / 0.5)
    assert math.isclose(ins.quantum(stepped, idx), 0.5, rel_tol=1e-6)


def test_heldout_test_sees_a_real_gain_and_none_between_equal_models():
    rng = np.random.default_rng(0)
    e = rng.standard_normal(2000)
    same = stats.heldout_test(e, e.copy())
    assert same['gain'] == 0.0 and same['p'] == 1.0
    better = stats.heldout_test(e + 0.5 * rng.standard_normal(2000), e)
    assert better['gain'] > 0.1 and better['p'] < 0.01


def _calibration_line(seed):
    """
    Return (sse, least-squares beta, sigma2, least-squares errors) of offset + gain * OP.

    OP lies far from 0, so offset and gain trade off.
    """
    rng = np.random.default_rng(seed)
    x = rng.uniform(40.0, 60.0, 400)
    y = 1.0 + 0.97 * x + 0.2 * rng.standard_normal(400)
    X = np.column_stack([np.ones_like(x), x])
    beta, *_ = np.linalg.lstsq(X, y, rcond=None)
    sigma2 = float(np.sum((y - X @ beta) ** 2)) / len(y)

    def sse(t):
        e = y - X @ np.asarray(t)
        return float(e @ e)
    return sse, beta, sigma2, np.sqrt(sigma2 * np.diag(np.linalg.inv(X.T @ X)))


def test_curvature_errors_are_the_least_squares_errors_of_a_correlated_line():
    # The offset's error is many times the one it would have with the gain known.
    sse, beta, sigma2, naive = _calibration_line(3)
    got = stats.curvature_errors(sse, beta, [0.01, 1e-3], sigma2)
    np.testing.assert_allclose(got, naive, rtol=1e-4)
    alone = math.sqrt(sigma2 / 400)          # the offset's error with the gain known
    assert got[0] > 5 * alone


def test_curvature_errors_cover_where_a_search_stopped_short_of_the_minimum():
    # The offset left 3 errors short of the least-squares value (a grid point, a
    # search's tolerance): the offset's error must reach the minimum, and the gain,
    # at its own best given the offset's miss, keeps its error.
    sse, beta, sigma2, naive = _calibration_line(4)
    short = beta - [3.0 * naive[0], 0.0]
    got = stats.curvature_errors(sse, short, [0.01, 1e-3], sigma2)
    np.testing.assert_allclose(got, [math.hypot(naive[0], 3.0 * naive[0]), naive[1]],
                               rtol=1e-3)
    assert abs(short[0] - beta[0]) <= 2.0 * got[0]
    # One parameter on its own curvature (the fallback): the same rule.
    one = stats.curvature_errors(lambda t: 4.0 * (t[0] - 1.0) ** 2, [1.5], [1e-3], 2.0)
    assert one[0] == pytest.approx(math.hypot(math.sqrt(2.0 * 2.0 / 8.0), 0.5))


def test_curvature_errors_fall_back_to_each_parameters_own_curvature_on_a_flat_direction():
    def sse(t):
        return 4.0 * (t[0] - 1.0) ** 2         # the second parameter changes nothing

    got = stats.curvature_errors(sse, [1.0, 0.0], [1e-3, 1e-3], 2.0)
    assert got[0] == pytest.approx(math.sqrt(2.0 * 2.0 / 8.0)) and math.isinf(got[1])


def _explain(d, mv):
    n = len(mv)
    return decide.explain_record(d['t'], d['op'], mv, [(0, n)], 1.0, reps=1)[0]


def _late_and_high(op, delay):
    """Return the reading of a frictionless valve ``delay`` samples late, lagged, 2 % high."""
    whole = [(0, len(op))]
    return 2.0 + ins.lag(ins.shift(op, delay, whole), 2.0, whole) + _noise(len(op), 0.1)


def _never_worse_than_frictionless(report):
    assert report['mismatch']['mse_holdout'] <= report['frictionless']['mse_holdout'] * 1.0001


def test_a_clean_frictionless_valve_gets_no_effect_and_no_friction(loop):
    d, _ = loop
    mv = d['op'] + _noise(len(d['op']), 0.1)
    r = _explain(d, mv)
    m = r['mismatch']
    assert m['friction'] is False and m['effects'] == [] and m['effect'] == 'none'
    _never_worse_than_frictionless(r)


def test_a_frictionless_valve_late_and_off_is_timing_and_calibration_not_stiction(loop):
    # The boiler-feed valve: follows OP late, through a lag, reading high.
    d, _ = loop
    r = _explain(d, _late_and_high(d['op'], 1.0))
    m = r['mismatch']
    assert m['friction'] is False
    assert {e['id'] for e in m['effects']} == {'dead_time', 'response_lag',
                                               'positioner_calibration'}
    size = {e['id']: e['size'] for e in m['effects']}
    assert abs(size['positioner_calibration'] - 2.0) < 0.3
    # Plain Kano with no timing does far worse on the held-out part.
    assert m['mse_holdout'] < 0.1 * r['baseline']['mse_holdout']
    _never_worse_than_frictionless(r)


def test_a_sticky_valve_read_late_is_stiction_and_dead_time(loop):
    d, truth = loop
    whole = [(0, len(d['op']))]
    mv = ins.shift(d['mv_true'], 2.0, whole) + _noise(len(d['op']), 0.1)
    r = _explain(d, mv)
    m = r['mismatch']
    assert m['friction'] is True and m['friction_kind'] == 'stiction'
    assert 'dead_time' in {e['id'] for e in m['effects']}
    chain = r['chains']['stiction']
    assert abs(chain['dead_time_s'] - 2.0) <= 0.5
    assert abs(chain['S'] - truth['valve']['S']) < 0.3
    _never_worse_than_frictionless(r)
    # The answer is the dead time wherever it is read (JSON, page, figure), not the
    # friction search's 'nothing is missing' beside a list that names it.
    assert m['effect'] == m['effects'][0]['id'] and 'Nothing is missing' not in m['explanation']
    assert m['explanation'].startswith(m['effects'][0]['sentence'])


def test_play_without_stick_is_backlash_not_stiction(loop):
    d, _ = loop
    op = d['op']
    whole = [(0, len(op))]
    mv = ins.friction_output(op, whole, 3.0, 0.0, op) + _noise(len(op), 0.1)
    r = _explain(d, mv)
    m = r['mismatch']
    assert m['friction'] is False and m['friction_kind'] == 'backlash'
    assert [e['id'] for e in m['effects']] == ['backlash']
    assert abs(m['effects'][0]['size'] - 3.0) < 0.3
    _never_worse_than_frictionless(r)


def test_the_chapters_pure_deadband_is_play_not_a_calibration():
    # Table 2.1's deadband column (S 5 %, J 0) with noise: in the first 70 % the valve
    # only ever leaves rest, and OP spans less than S. Friction sized within OP's travel
    # lost to a "valve" reading 51 % scaled by -0.011: a reading that does not follow OP,
    # named a positioner calibration with confidence 1.
    from stiction_ros.resources import config_file
    from stiction_ros.sim.loop_config import load_loop
    cfg = load_loop(config_file('concentration_loop.yaml'), 'deadband',
                    overrides={'noise': {'pv_std': 0.02, 'mv_std': 0.05, 'seed': 2}})
    d = simulate_loop(cfg)
    m = _explain(d, d['mv'])['mismatch']
    assert m['friction_kind'] == 'backlash' and m['friction'] is False
    assert [e['id'] for e in m['effects']] == ['backlash']
    assert abs(m['effects'][0]['size'] - 5.0) < 0.25


def test_shifting_op_by_one_sample_moves_the_dead_time_not_the_verdict(loop):
    # The real valve flipped from no stiction to stiction when OP moved a sample.
    d, _ = loop
    mv = _late_and_high(d['op'], 1.5)
    late = _explain(d, mv)
    early = _explain({**d, 'op': ins.shift(d['op'], 1.0, [(0, len(mv))])}, mv)
    for r in (late, early):
        assert r['mismatch']['friction'] is False
    shift = late['frictionless']['dead_time_s'] - early['frictionless']['dead_time_s']
    assert abs(shift - 1.0) < 0.2


def test_a_reading_in_steps_is_quantisation_not_friction(loop):
    d, _ = loop
    mv = 0.5 * np.round((d['op'] + _noise(len(d['op']), 0.05)) / 0.5)
    r = _explain(d, mv)
    m = r['mismatch']
    assert m['friction'] is False and m['friction_kind'] == 'none'
    assert [e['id'] for e in m['effects']] == ['quantisation']
    assert math.isclose(m['effects'][0]['size'], 0.5, rel_tol=1e-6)


def test_without_a_held_out_part_friction_rests_on_the_fitted_part(loop):
    d, _ = loop
    mv = d['mv_true'] + _noise(len(d['op']), 0.1)
    r = decide.explain_record(d['t'], d['op'], mv, [(0, len(mv))], 1.0, holdout=0.0, reps=1)[0]
    assert r['mismatch']['friction'] is True
    assert 'heldout_p' not in r['friction_tests']['stiction_vs_frictionless']


def test_a_rate_limited_actuator_is_a_rate_limit_not_friction(loop):
    from stiction_ros.kernels.chain import limited
    d, _ = loop
    rate = 0.3 * float(np.max(np.abs(np.diff(d['op']))))
    mv = limited(d['op'], [(0, len(d['op']))], rate) + _noise(len(d['op']), 0.1)
    m = _explain(d, mv)['mismatch']
    assert m['friction'] is False and [e['id'] for e in m['effects']] == ['rate_limit']
    assert abs(m['effects'][0]['size'] - rate) < 0.1 * rate


def test_a_valve_on_its_travel_stop_is_a_travel_limit(loop):
    d, _ = loop
    stop = float(np.quantile(d['op'], 0.97))
    mv = np.minimum(d['op'], stop) + _noise(len(d['op']), 0.1)
    m = _explain(d, mv)['mismatch']
    assert m['friction'] is False and [e['id'] for e in m['effects']] == ['travel_limits']
    assert abs(m['effects'][0]['size'] - stop) < 0.1


def test_a_reading_ahead_of_op_is_a_clock_skew_not_a_calibration(loop):
    # No valve moves before its command: a reading 2 samples early is the clocks' doing.
    d, _ = loop
    whole = [(0, len(d['op']))]
    r = _explain(d, ins.shift(d['op'], -2.0, whole) + _noise(len(d['op']), 0.1))
    m = r['mismatch']
    assert m['friction'] is False and [e['id'] for e in m['effects']] == ['clock_skew']
    assert m['effect'] == 'clock_skew' and abs(r['clock_skew']['samples'] - 2.0) < 0.1
    # The plain model on OP as recorded is far worse held out than the realigned one.
    assert m['mse_holdout'] < 0.1 * r['clock_skew']['plain_mse_holdout_as_recorded']
    assert r['clock_skew']['at_least'] is False


def test_a_sticky_valve_read_ahead_of_op_is_stiction_and_a_clock_skew(loop):
    d, truth = loop
    whole = [(0, len(d['op']))]
    r = _explain(d, ins.shift(d['mv_true'], -2.0, whole) + _noise(len(d['op']), 0.1))
    m = r['mismatch']
    assert m['friction'] is True and m['effects'][0]['id'] == 'clock_skew'
    assert abs(m['effects'][0]['size'] - 2.0) < 0.1
    assert 'positioner_calibration' not in {e['id'] for e in m['effects']}
    assert abs(r['chains']['stiction']['S'] - truth['valve']['S']) < 0.3


@pytest.mark.slow
def test_a_reading_through_a_lag_and_ahead_of_op_is_still_a_clock_skew(loop):
    # A lag fitted to an early reading is a shorter one (it takes in the lead), so the
    # same chain a sample ahead fits worse: the lead shows only when the chain is refitted.
    d, _ = loop
    whole = [(0, len(d['op']))]
    lagged = ins.lag(d['mv_true'], 3.0, whole)
    r = _explain(d, ins.shift(lagged, -2.0, whole) + _noise(len(d['op']), 0.05))
    m = r['mismatch']
    assert m['friction'] is True and m['effects'][0]['id'] == 'clock_skew', m['effects']
    assert abs(r['clock_skew']['samples'] - 2.0) <= 0.5
    assert {'measurement_lag', 'response_lag', 'actuator_lag'} & {e['id'] for e in m['effects']}

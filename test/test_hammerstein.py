"""
Hammerstein quantification of S and J from OP and PV alone, on known loops.

The records are closed-loop simulations of the concentration loop (self-
regulating, 3 e^{-10 s} / (10 s + 1)) and of a level-like integrating loop
(0.05 e^{-10 s} / (s (20 s + 1)), PI 1.0, Ti = 100 s), each with a Kano valve
of known S and J and seeded white noise on PV, which the controller feeds
into OP.  The tolerances: S within 10 % (on these records the estimates are
within 1 % for the self-regulating loop and 3 % for the integrating one, so
10 % leaves room for other platforms' round-off to move a breakaway by a
sample); J within 25 % of J or 0.25 %, because J is weakly identifiable (the
plant gain absorbs the height of a slip, see the module docstring).
"""

import json

import numpy as np
import pytest

from stiction_ros.analysis.hammerstein import (
    HammersteinProblem, MAX_IMPROVEMENT_RATIO, quantify, segment_path)
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import build_controller, build_plant, build_valve, simulate_loop
from stiction_ros.sim.loop_config import load_loop

INTEGRATING = {'plant.num': [0.05], 'plant.den': [20.0, 1.0, 0.0], 'controller.Kc': 1.0,
               'controller.Ti': 100.0}


def loop_config(S, J, pv_std, seed, duration, extra=None):
    overrides = {'valve.model': 'kano', 'valve.S': S, 'valve.J': J, 'noise.pv_std': pv_std,
                 'noise.seed': seed, 'duration': float(duration)}
    overrides.update(extra or {})
    return load_loop(config_file('concentration_loop.yaml'), overrides=overrides)


def record(S, J, pv_std=0.1, seed=1, duration=1500, extra=None):
    d = simulate_loop(loop_config(S, J, pv_std, seed, duration, extra))
    return d['op'], d['pv']


def record_with_load_sine(amplitude, period, pv_std=0.1, seed=1, duration=3000):
    """Run the loop with a linear valve and a sinusoidal load added to PV."""
    cfg = loop_config(0.0, 0.0, pv_std, seed, duration)
    valve, plant = build_valve(cfg), build_plant(cfg)
    pid, sp, _ = build_controller(cfg)
    valve.reset(y0=plant.mv0)
    n = duration + 1
    op, pv = np.empty(n), np.empty(n)
    for k in range(n):
        pv[k] = plant.output() + amplitude * np.sin(2 * np.pi * k / period)
        op[k] = pid.update(sp(float(k)), pv[k])
        plant.update(valve.step(op[k]))
    return op, pv


def assert_close(r, S, J):
    assert abs(r.S - S) <= 0.1 * S, (r.S, r.J)
    assert abs(r.J - J) <= max(0.25 * J, 0.25), (r.S, r.J)


@pytest.mark.parametrize('S, J', [(4.0, 1.0), (2.0, 2.0), (5.0, 7.0)])
def test_self_regulating_loop_gives_back_S_and_J(S, J):
    op, pv = record(S, J)
    r = quantify(op, pv, 1.0)
    assert_close(r, S, J)
    assert r.reliable, r.reason
    assert r.fit_improvement < 0.7
    assert r.S_interval[0] <= S <= r.S_interval[1]
    assert r.J_interval is None or r.J_interval[0] <= r.J <= r.J_interval[1]
    # 10 s of dead time after the sample PV is read: 10 or 11 samples
    assert r.linear_model['delay_samples'] in (10, 11)
    assert r.linear_model['gain'] == pytest.approx(3.0, rel=0.2)


@pytest.mark.parametrize('S, J', [(4.0, 1.0), (3.0, 0.0)])
def test_integrating_loop_gives_back_S_and_J(S, J):
    op, pv = record(S, J, pv_std=0.02, duration=2000, extra=INTEGRATING)
    r = quantify(op, pv, 1.0, integrating=True)
    assert_close(r, S, J)
    assert r.reliable, r.reason
    assert r.linear_model['integrating']
    assert r.linear_model['integrator_gain_per_s'] == pytest.approx(0.05, rel=0.3)


# chi-square, one degree of freedom, 95 %: J = 0 nested in J free
CHI2_95_1DOF = 3.841


@pytest.mark.parametrize('seed', [1, 2])
def test_the_slip_jump_is_tested_against_a_deadband(seed):
    # Backlash (J = 0) leaves nothing for a jump to explain; a slip of a
    # sixth of the band is plain in the same loop.  The J = 0 fit is nested
    # in the free one, so its ratio is never negative.
    ratios = []
    for J in (0.0, 0.5):
        op, pv = record(3.0, J, seed=seed)
        d = quantify(op, pv, 1.0).details
        assert d['deadband_residual_variance'] >= d['residual_variance']
        ratios.append(d['jump_likelihood_ratio'])
    assert 0.0 <= ratios[0] < CHI2_95_1DOF < 10 * CHI2_95_1DOF < ratios[1], ratios


def test_linear_valve_with_an_oscillating_load_is_not_called_stiction():
    op, pv = record_with_load_sine(1.0, 150.0)
    r = quantify(op, pv, 1.0)
    assert not r.reliable
    assert 'no improvement over a linear valve' in r.reason
    assert r.fit_improvement > MAX_IMPROVEMENT_RATIO
    # against an OP swinging by several %, the S found is noise filtering
    assert r.S < 0.1 * np.ptp(op), r.S


def test_linear_valve_with_aggressive_tuning_is_not_called_stiction():
    op, pv = record(0.0, 0.0, pv_std=0.02, duration=3000, extra={'controller.Kc': 0.45})
    r = quantify(op, pv, 1.0)
    assert not r.reliable
    assert r.fit_improvement > MAX_IMPROVEMENT_RATIO
    assert r.S < 0.1


def test_a_record_without_oscillation_is_unreliable():
    # linear valve, one set-point step, then the loop settles
    op, pv = record(0.0, 0.0, pv_std=0.02)
    r = quantify(op, pv, 1.0)
    assert not r.reliable
    assert 'no regular oscillation' in r.reason


def test_a_short_record_is_refused_with_a_reason():
    op, pv = record(4.0, 1.0, duration=150)
    r = quantify(op, pv, 1.0)
    assert (r.S, r.J, r.reliable) == (None, None, False)
    assert r.reason.startswith('too short')
    assert json.loads(json.dumps(r.to_json()))['S'] is None


def test_flat_op_or_pv_is_refused():
    op, pv = record(4.0, 1.0)
    assert 'OP never moves' in quantify(np.full_like(op, 50.0), pv, 1.0).reason
    assert 'PV does not vary' in quantify(op, np.zeros_like(pv), 1.0).reason


def test_gaps_split_the_fit_and_no_regressor_crosses_them():
    op, pv = record(4.0, 1.0, duration=2000, seed=3)
    op[900:960] = np.nan
    segments = [(0, 700), (760, 2001)]    # 700..760 is valid but excluded by the caller
    r = quantify(op, pv, 1.0, segments=segments)
    # the valve's state at each restart is unknown and fitted, which leaves J
    # less certain than on one unbroken record (see the module docstring)
    assert_close(r, 4.0, 1.0)
    assert r.reliable, r.reason
    assert len(r.details['valve_start']) == 3
    p = HammersteinProblem(op, pv, [(0, 700), (760, 900), (960, 2001)], False, (2, 2), 1, 30)
    for s, (a, b) in enumerate(p.segments):
        rows = p.rows[p.row_seg == s]
        # the oldest regressor of every row (PV or valve input) lies in its segment
        assert rows.min() - 30 - 1 >= a and rows.max() < b


def test_kernel_sse_equals_a_plain_least_squares_fit():
    op, pv = record(4.0, 1.0, duration=800)
    for integrating in (False, True):
        p = HammersteinProblem(op, pv, [(0, 400), (420, 801)], integrating, (2, 2), 1, 20)
        starts = [p.at_rest(), ((1, 0.3), (-1, 1.0))]
        for (S, J, d), start in zip([(0.0, 0.0, 3), (3.0, 1.5, 11), (4.0, 1.0, 20)],
                                    starts * 2):
            sse, _ = p.grid([S], [J], start, d, d)
            _, resid = p.fit(S, J, d, start)
            assert sse[0, 0] == pytest.approx(float(resid @ resid), rel=1e-6)


def naive_lag_sums(v, rows, row_seg, qy, tres, dlo, nl, nb, nseg):
    qv, tv = np.zeros((nl, qy.shape[1])), np.zeros(nl)
    vv, sv = np.zeros((nl, nb)), np.zeros((nseg, nl))
    for r, row in enumerate(rows):
        for i in range(nl):
            x = float(v[row - dlo - i])
            sv[row_seg[r], i] += x
            tv[i] += x * tres[r]
            for c in range(qy.shape[1]):
                qv[i, c] += x * qy[r, c]
            for m in range(min(nb, nl - i)):
                vv[i, m] += x * v[row - dlo - i - m]
    return qv, tv, vv, sv


@pytest.mark.parametrize('p, nb', [(0, 2), (2, 2), (3, 1), (4, 2), (5, 2), (2, 3), (7, 4), (2, 0)])
def test_the_lag_sums_are_the_row_by_row_sums_to_the_bit(p, nb):
    # The fits sum lag by lag in registers; every sum must still add its terms in
    # the order of the rows, from zero, whatever the shapes and however the rows'
    # segments follow one another (interleaved here, as no fit makes them).
    from stiction_ros.kernels.hammerstein import lag_sums, lag_sums_reference
    rng = np.random.default_rng(10 * p + nb)
    for n, nseg, interleaved in ((0, 1, False), (1, 1, False), (300, 3, False), (300, 3, True)):
        v = rng.normal(size=400) * 10.0 ** rng.integers(-3, 4, size=400)
        dlo, dhi = 1, 4
        nl = dhi - dlo + nb
        rows = np.sort(rng.choice(np.arange(dhi + nb + 1, 400), size=n, replace=False))
        row_seg = (rng.integers(0, nseg, size=n) if interleaved
                   else np.repeat(np.arange(nseg), -(-n // nseg))[:n]).astype(np.int64)
        qy, tres = rng.normal(size=(n, p)), rng.normal(size=n)
        args = (v, rows.astype(np.int64), row_seg, qy, tres, dlo, nl, nb, nseg)
        want = naive_lag_sums(*args)
        for got in (lag_sums(*args), lag_sums_reference(*args)):
            # Bytes, not values: a -0.0 for a 0.0 would be another bit.
            assert all(a.shape == b.shape and a.tobytes() == b.tobytes()
                       for a, b in zip(got, want)), (n, interleaved)
    assert np.any(want[0]) or p == 0


def test_start_states_put_the_valve_where_they_say():
    u = np.array([50.0, 50.5, 51.5, 52.5])
    S, J = 2.0, 1.0
    fd = (S - J) / 2      # a moving valve lags OP by this much
    # at rest at the first OP: breakaway needs more than (S + J) / 2 = 1.5
    assert segment_path(u, S, J, 0, 0.5).tolist() == [50.0, 50.0, 50.0, 52.5 - fd]
    # last moved up and stuck at OP 50: more than J onwards moves it
    up = segment_path(u, S, J, 1, (50.0 - (u[0] - J)) / (S + J))
    assert up.tolist() == [50.0 - fd, 50.0 - fd, 51.5 - fd, 52.5 - fd]
    # last moved down and stuck at OP 50: going up is a reversal, needs S
    down = segment_path(u, S, J, -1, (50.0 - (u[0] - S)) / (S + J))
    assert down.tolist() == [50.0 + fd, 50.0 + fd, 50.0 + fd, 52.5 - fd]


def test_result_is_json_and_progress_is_reported():
    op, pv = record(4.0, 1.0, duration=1000)
    calls = []
    r = quantify(op, pv, 1.0, progress=lambda done, total: calls.append((done, total)))
    out = json.loads(json.dumps(r.to_json(), allow_nan=False))
    assert set(out) >= {'S', 'J', 'S_interval', 'J_interval', 'fit_improvement', 'reliable',
                        'reason', 'linear_model'}
    assert len(r.curves['mv_hat']) == len(op) and 'curves' not in out
    assert calls and calls[-1][0] == calls[-1][1]
    assert [c[0] for c in calls] == sorted(c[0] for c in calls)


def test_a_plant_loops_length_of_751_samples_is_enough_to_size_the_band():
    # The plant loops' length; the fit's time is in make bench-detector.
    op, pv = record(4.0, 1.0, duration=750)
    r = quantify(op, pv, 1.0)
    assert r.S is not None and r.S_interval[0] <= 4.0 <= r.S_interval[1], (r.S, r.S_interval)


def test_an_exact_fit_reads_as_no_evidence_not_as_a_math_error():
    from stiction_ros.analysis.hammerstein.estimate import _likelihood_ratio
    # A residual sum of squares off the normal equations is 0, or a rounding
    # error below it, when a fit is exact.
    assert _likelihood_ratio(100.0, 0.0, 1.0) == 0.0
    assert _likelihood_ratio(100.0, -1e-18, 1.0) == 0.0
    assert _likelihood_ratio(100.0, 1.0, 0.0) == 1e300
    assert _likelihood_ratio(100.0, 2.0, 1.0) == pytest.approx(100.0 * np.log(2.0))
    # The simulated record that met it: a level on a Kano valve whose transmitter
    # froze for 74 of its 800 samples; the deadband fit (J = 0), at the top of the
    # S range where the valve moves once, is nearly singular: its sum of squares
    # off the normal equations came out at 0 (least squares on the same regressors:
    # 58.5 of 3 014); such cells are now scored again by least squares (next test).
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(3_101_918)
    rec = simulate(sc)
    span = float(np.ptp(rec['op']))
    d = quantify(rec['op'], rec['pv'], sc.sample_time, integrating=sc.integrating,
                 max_delay=10, resolution=span / 40).details
    # Whether its sum of squares lands on 0 or a hair either side is rounding, so
    # only what must hold either way: a finite figure, never negative or NaN.
    assert 0.0 <= d['jump_likelihood_ratio'] < 1e300


def test_every_cell_of_a_nearly_singular_fit_is_the_least_squares_sse(monkeypatch):
    # The record above: its deadband cells came out of the normal equations at 0-196
    # where least squares gives 58.5 (the stuck valve's ramp nearly repeats the
    # integrating plant's ramp regressors, and the projection cancels its digits).
    # The kernel bounds each cell's rounding; a cell over the bound is scored again
    # by least squares.  Every cell the search scores must now be least squares' SSE.
    from stiction_ros.analysis.hammerstein.problem import DOUBT, HammersteinProblem
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(3_101_918)
    rec = simulate(sc)
    grid, checked, problems = HammersteinProblem.grid, [], []

    def checking_grid(self, s_values, j_values, start, dlo=None, dhi=None):
        sse, delay = grid(self, s_values, j_values, start, dlo, dhi)
        problems.append(self)
        for a, b in np.ndindex(sse.shape):
            _, resid = self.fit(s_values[a], j_values[b], int(delay[a, b]), start)
            checked.append(abs(sse[a, b] - float(resid @ resid)) / self.tt)
        return sse, delay

    monkeypatch.setattr(HammersteinProblem, 'grid', checking_grid)
    span = float(np.ptp(rec['op']))
    quantify(rec['op'], rec['pv'], sc.sample_time, integrating=sc.integrating, max_delay=10,
             resolution=span / 40)
    assert sum(p.rescored for p in problems) > 0      # the record still needs the fallback
    assert len(checked) > 1000 and max(checked) <= 10 * DOUBT, max(checked)

"""The prediction-error Hammerstein figures: a sticky valve predicts a closed loop's PV better."""

import numpy as np
from scipy.signal import lfilter

from stiction_ros.analysis.detection.output_error import output_error_figures
from stiction_ros.analysis.detection.prediction_error import prediction_error_figures, SKIP
from stiction_ros.models.kano import Kano


def _closed_loop(sticky: bool, seed: int, n: int = 1500):
    """Return OP and PV of a PI loop on a first-order plant, a random-walk load and PV noise."""
    rng = np.random.default_rng(seed)
    valve = Kano(S=3.0, J=1.5)
    valve.reset(y0=50.0)
    a = np.exp(-1 / 5.0)
    x = load = 0.0
    integral = 50.0
    op, pv = np.empty(n), np.empty(n)
    for k in range(n):
        load += rng.normal(0, 0.02)
        pv[k] = x + load + rng.normal(0, 0.2)
        integral -= 0.15 * pv[k]
        op[k] = integral - 0.8 * pv[k]
        mv = valve.step(op[k]) if sticky else op[k]
        # The plant sees this sample's valve position from the next sample on.
        x = a * x + (1 - a) * (mv - 50.0)
    return op, pv


def _open_loop_level(sticky: bool, seed: int, n: int = 1200):
    """OP wanders; a level integrates the valve position; white measurement noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    op = 50 + 8 * np.sin(2 * np.pi * t / 300) + np.cumsum(rng.normal(0, 0.15, n))
    mv = Kano(S=4.0, J=2.0).simulate(op) if sticky else op.copy()
    # The level sees this sample's valve position from the next sample on.
    level = 0.02 * np.concatenate(([0.0], np.cumsum(mv - mv.mean())[:-1]))
    return op, level + rng.normal(0, 0.01, n)


def _open_loop_flow(seed: int, n: int = 1200):
    """Return OP and PV of a sticky valve before a first-order lag, white noise, no feedback."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    op = 50 + 8 * np.sin(2 * np.pi * t / 300) + np.cumsum(rng.normal(0, 0.15, n))
    mv = Kano(S=4.0, J=2.0).simulate(op)
    a = np.exp(-1 / 6.0)
    pv = lfilter([0.0, 1 - a], [1, -a], mv - mv.mean())
    return op, pv + rng.normal(0, 0.3, n)


def test_a_sticky_valve_predicts_a_closed_loop_pv_better_where_output_error_cannot_tell():
    for seed in range(3):
        op, pv = _closed_loop(sticky=True, seed=seed)
        ratio, _ = prediction_error_figures(op, pv, integrating=False)
        assert ratio < 0.93
        # The output-error fit, judged on the whole PV path, prefers OP here.
        assert output_error_figures(op, pv, integrating=False)[0] > ratio + 0.1


def test_a_linear_valve_is_not_beaten_by_a_sticky_one():
    for seed in range(3):
        op, pv = _closed_loop(sticky=False, seed=seed)
        assert prediction_error_figures(op, pv, integrating=False)[0] > 0.99
        op, pv = _open_loop_level(sticky=False, seed=seed)
        assert prediction_error_figures(op, pv, integrating=True)[0] > 0.99


def test_an_integrating_level_is_fitted_on_its_increments():
    op, pv = _open_loop_level(sticky=True, seed=2)
    ratio, _ = prediction_error_figures(op, pv, integrating=True)
    assert ratio < 0.97
    # Read as a self-regulating loop, the same record shows the slips less.
    assert prediction_error_figures(op, pv, integrating=False)[0] > ratio


def test_without_feedback_and_with_white_noise_the_output_error_fit_is_the_sharper():
    for seed in range(2):
        op, pv = _open_loop_flow(seed)
        ratio, _ = prediction_error_figures(op, pv, integrating=False)
        assert ratio < 1.0
        assert output_error_figures(op, pv, integrating=False)[0] < ratio


def test_op_computed_from_the_same_pv_sample_explains_nothing():
    # A proportional controller on a PV that no valve moves: OP[k] is PV[k]
    # scaled, so a fit allowed no dead time would predict PV exactly and the
    # figure would be the controller's, not the valve's.
    rng = np.random.default_rng(4)
    pv = rng.normal(0, 1, 800)
    ratio, _ = prediction_error_figures(50 - 3 * pv, pv, integrating=False)
    assert 0.9 < ratio < 1.1


def test_too_short_or_dead_records_give_nan_not_a_number_that_means_something():
    op = 50 + np.arange(4.0 * SKIP - 1)
    assert np.isnan(prediction_error_figures(op, op.copy(), integrating=False)).all()
    figures = prediction_error_figures(50 + np.sin(np.arange(400.0)), np.zeros(400), False)
    assert np.isnan(figures).all()


def test_the_disturbance_filter_inverts_an_integrated_moving_average():
    from stiction_ros.analysis.detection.prediction_error import _noise_filter
    e = np.random.default_rng(1).normal(size=500)
    for c in (0.0, 0.5, 0.95):
        # (1 - c q^-1) / (1 - q^-1) e, from rest: the disturbance the model assumes.
        v = lfilter([1.0, -c], [1.0, -1.0], e)
        k = np.arange(1, 500)
        # The record's first sample is unknown to the filter; its error decays as c^k.
        assert np.allclose(_noise_filter(v, c)[1:], e[1:] - c ** k * e[0], atol=1e-9)


def test_the_shared_gram_fit_matches_one_least_squares_solve_per_window():
    from bench.detector_bench import rss_lstsq
    from stiction_ros.analysis.detection.output_error import sticky_paths, target
    from stiction_ros.analysis.detection.prediction_error import _Predictor
    op, pv = _closed_loop(True, 7, n=600)
    y, u = target(op, pv, False)
    fit = _Predictor(y)
    paths = [u] + [p for _, p in sticky_paths(u, op)][::7]
    # A valve that never moves: its lags are empty columns, left out as lstsq leaves them.
    paths.append(np.full_like(u, 42.0))
    for path in paths:
        fast, naive = fit.rss(path)[0], rss_lstsq(fit, path)
        assert abs(fast - naive) <= 1e-9 * naive

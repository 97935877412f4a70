"""The output-error Hammerstein figures: a slipping valve explains PV however noisy PV is."""

import numpy as np
from scipy.signal import lfilter

from stiction_ros.analysis.detection.output_error import output_error_figures
from stiction_ros.kernels.hammerstein import first_order_lag
from stiction_ros.models.kano import Kano


def _open_loop(sticky: bool, integrating: bool, seed: int = 0, n: int = 1200):
    """OP wanders slowly; PV is a lagged (or integrated) valve position plus white noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)
    op = 50 + 8 * np.sin(2 * np.pi * t / 300) + np.cumsum(rng.normal(0, 0.15, n))
    mv = Kano(S=4.0, J=2.0).simulate(op) if sticky else op.copy()
    if integrating:
        pv = 0.02 * np.cumsum(mv - mv.mean())
        noise = 0.01
    else:
        a = np.exp(-1 / 6.0)
        pv = lfilter([1 - a], [1, -a], mv - mv.mean())
        # Each 4 % slip moves PV by 4 units; the noise is a third of that.
        noise = 1.3
    return op, pv + rng.normal(0, noise, n)


def test_a_slipping_valve_explains_a_noisy_self_regulating_pv_better_than_a_linear_one():
    op, pv = _open_loop(sticky=True, integrating=False)
    ratio, s_rel = output_error_figures(op, pv, integrating=False)
    assert ratio < 0.9
    # The band found lies within a grid step or two of the true S over OP's range.
    true_rel = 4.0 / np.ptp(op)
    assert true_rel / 2 < s_rel < true_rel * 2


def test_a_linear_valve_is_not_beaten_by_a_sticky_one():
    for integrating in (False, True):
        op, pv = _open_loop(sticky=False, integrating=integrating, seed=3)
        ratio, _ = output_error_figures(op, pv, integrating=integrating)
        # A sticky path can only approximate OP; with S at 1 % of the range
        # the loss is small, never a gain worth the name.
        assert ratio > 0.97


def test_an_integrating_level_is_fitted_on_its_increments():
    op, pv = _open_loop(sticky=True, integrating=True, seed=5)
    as_level, _ = output_error_figures(op, pv, integrating=True)
    assert as_level < 0.9


def test_too_short_or_dead_records_give_nan_not_a_number_that_means_something():
    op = 50 + np.arange(15.0)
    ratio, s_rel = output_error_figures(op, op.copy(), integrating=False)
    assert np.isnan(ratio) and np.isnan(s_rel)
    ratio, _ = output_error_figures(50 + np.sin(np.arange(400.0)), np.zeros(400), False)
    assert np.isnan(ratio)


def test_the_compiled_lag_is_scipys_first_order_filter_to_the_bit():
    rng = np.random.default_rng(7)
    for n in (1, 2, 997):
        u = np.ascontiguousarray(3.0 + 7.0 * rng.standard_normal(n))
        for tau in (0.7, 5.0, 80.0):
            a = float(np.exp(-1.0 / tau))
            assert np.array_equal(first_order_lag(u, a), lfilter([1 - a], [1, -a], u))

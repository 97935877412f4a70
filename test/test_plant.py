"""The sampled plant must reproduce the continuous process exactly at the samples."""

import math

import numpy as np
import pytest

from stiction_ros.sim.plant import PlantError, state_space, TransferFunctionPlant, zoh


def test_realisation_and_hold_are_scipy_signals_to_the_bit():
    # The plant writes out tf2ss and cont2discrete(zoh) to spare its node scipy.signal's
    # import: on random stable and integrating processes, with and without zeros, static
    # gains included, they must give scipy.signal's very matrices.
    from scipy import signal
    rng = np.random.default_rng(20261208)
    cases = [([2.0], [4.0]), ([3.0], [1.0, 0.0]), ([1.0, 2.0], [3.0, 4.0, 1.0])]
    for _ in range(60):
        n = int(rng.integers(1, 5))
        den = np.poly(-rng.uniform(0.01, 5.0, n)) * rng.uniform(0.1, 10.0)
        if rng.random() < 0.25:
            den = np.append(den, 0.0)          # a pole at s = 0
        cases.append((rng.normal(size=int(rng.integers(1, den.size + 1))), den))
    for num, den in cases:
        num, den = np.asarray(num, float), np.asarray(den, float)
        ours, ref = state_space(num, den), signal.tf2ss(num, den)
        for a, b in zip(ours, ref):
            np.testing.assert_array_equal(a, b)
        dt = float(rng.uniform(0.01, 3.0))
        phi, gam, *_ = signal.cont2discrete(ref, dt, method='zoh')
        our_phi, our_gam = zoh(ours[0], ours[1], dt)
        np.testing.assert_array_equal(our_phi, phi)
        np.testing.assert_array_equal(our_gam, gam)


@pytest.mark.parametrize('delay', [0.0, 10.0, 2.5, 0.3])
@pytest.mark.parametrize('ts', [1.0, 0.1])
def test_first_order_step_response_is_analytic(delay, ts):
    k, tau = 3.0, 10.0
    p = TransferFunctionPlant([k], [tau, 1.0], delay=delay, sample_time=ts, mv0=50.0, pv0=2.0)
    n = int(round(60.0 / ts))
    pv = p.simulate(np.full(n, 51.0))  # a step of +1 at t = 0, held
    t = np.arange(n) * ts
    expect = 2.0 + k * np.where(t >= delay, 1 - np.exp(-np.clip(t - delay, 0, None) / tau), 0)
    np.testing.assert_allclose(pv, expect, atol=1e-9)


def test_second_order_with_zero_matches_scipy_continuous_response():
    from scipy import signal
    num, den = [2.0, 1.0], [4.0, 2.0, 1.0]
    ts = 0.25
    p = TransferFunctionPlant(num, den, delay=0.75, sample_time=ts, mv0=0.0)
    n = 200
    pv = p.simulate(np.ones(n))
    _, y = signal.step((num, den), T=np.arange(n) * ts)
    expect = np.r_[np.zeros(3), y[:-3]]  # 0.75 s of dead time = 3 samples
    np.testing.assert_allclose(pv, expect, atol=1e-9)


def test_integrating_plant_ramps():
    p = TransferFunctionPlant([0.5], [1.0, 0.0], delay=2.0, sample_time=1.0, mv0=50.0)
    pv = p.simulate(np.full(20, 52.0))
    t = np.arange(20.0)
    np.testing.assert_allclose(pv, 0.5 * 2.0 * np.clip(t - 2.0, 0, None), atol=1e-9)
    assert p.integrating and math.isinf(p.dc_gain)


def test_biproper_plant_feeds_through_previous_sample():
    p = TransferFunctionPlant([2.0, 1.0], [1.0, 1.0], sample_time=0.1, mv0=0.0)
    pv = p.simulate(np.ones(5))
    # (2s+1)/(s+1) = 2 - 1/(s+1): step response 1 + exp(-t), seen one sample late
    assert pv[0] == 0.0 and pv[1] == pytest.approx(1.0 + math.exp(-0.1), abs=1e-12)


def test_noise_and_disturbance():
    p = TransferFunctionPlant([1.0], [1.0, 1.0], sample_time=1.0, noise_std=0.5, seed=4,
                              disturbance_steps=[(10.0, 3.0)])
    pv = p.simulate(np.zeros(4000))
    assert np.std(pv[:10] - 0) < 2.0
    assert np.mean(pv[10:]) == pytest.approx(3.0, abs=0.05)
    assert np.std(pv[10:]) == pytest.approx(0.5, rel=0.05)


@pytest.mark.parametrize('num,den,match', [
    ([1.0, 0.0, 0.0], [1.0, 1.0], 'not proper'),
    ([1.0], [1.0, -1.0], 'unstable'),
    ([1.0], [1.0, 0.0, 0.0], 'double integrator'),
    ([1.0], [0.0, 0.0], 'all zeros'),
    ([float('nan')], [1.0, 1.0], 'finite'),
])
def test_invalid_plants_are_rejected_with_the_reason(num, den, match):
    with pytest.raises(PlantError, match=match):
        TransferFunctionPlant(num, den)


@pytest.mark.parametrize('delay', [10.0, 2.5])
def test_frequency_response_matches_simulated_steady_state_sinusoid(delay):
    ts, w = 1.0, 2 * math.pi / 40.0
    p = TransferFunctionPlant([3.0], [10.0, 1.0], delay=delay, sample_time=ts, mv0=0.0)
    k = np.arange(2000)
    pv = p.simulate(np.cos(w * k * ts))
    tail = k >= 1000
    # fit the steady state to a cos + b sin, i.e. Re(P e^{jwk})
    basis = np.column_stack([np.cos(w * k[tail]), -np.sin(w * k[tail])])
    (re, im), *_ = np.linalg.lstsq(basis, pv[tail], rcond=None)
    expect = p.frequency_response(np.exp(1j * w * ts))[0]
    assert complex(re, im) == pytest.approx(expect, abs=1e-9)
    assert p.frequency_response(1.0)[0] == pytest.approx(3.0)

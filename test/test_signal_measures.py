"""Oscillation and waveform measures on signals whose answer is known."""

import numpy as np
import pytest

from stiction_ros.analysis.measures.limit_cycle import measure_oscillation
from stiction_ros.analysis.measures.waveform import shape_fit
from stiction_ros.sim.sources import Triangle


def test_regular_sine_period_and_amplitude():
    t = np.arange(0, 3000, 0.5)
    noise = np.random.default_rng(0).normal(0, 0.05, t.size)
    x = 3.0 + 2.0 * np.sin(2 * np.pi * t / 73.0) + noise
    osc = measure_oscillation(x, 0.5)
    assert osc.oscillating and osc.regularity > 10
    assert osc.period == pytest.approx(73.0, rel=0.01)
    assert osc.amplitude == pytest.approx(2.0, rel=0.1)


def test_decaying_oscillation_is_not_a_limit_cycle():
    t = np.arange(0, 3000, 1.0)
    x = np.exp(-t / 800) * np.sin(2 * np.pi * t / 60)
    assert not measure_oscillation(x, 1.0).oscillating


def test_noise_alone_is_not_an_oscillation():
    x = np.random.default_rng(1).normal(0, 1, 4000)
    assert not measure_oscillation(x, 1.0).oscillating


def test_shape_fit_tells_triangle_from_sine():
    t = np.arange(0, 300, 1.0)
    tri = Triangle(offset=0, amplitude=1, period=100)
    assert shape_fit(np.array([tri(x) for x in t]), 100, 1.0)['ratio'] > 5
    assert shape_fit(np.sin(2 * np.pi * t / 100 + 0.3), 100, 1.0)['ratio'] < 0.2

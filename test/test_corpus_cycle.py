"""The corpus's upstream cycles: drawn for both labels alike, and what linearity demands."""

import dataclasses

import numpy as np
import pytest

from stiction_ros.sim.corpus import draw_scenario, simulate
from stiction_ros.sim.corpus_signals import upstream_cycle, wave


@pytest.mark.slow
def test_upstream_cycles_are_drawn_for_both_labels_alike_at_judgeable_periods():
    drawn = [draw_scenario(s) for s in range(1500)]
    for label in (False, True):
        share = np.mean([s.cycle_amplitude > 0.0 for s in drawn if s.label == label])
        assert 0.19 < share < 0.31, (label, share)
    for s in drawn:
        if s.cycle_amplitude == 0.0:
            assert (s.cycle_period, s.cycle_shape) == (0.0, '')
            assert not np.any(upstream_cycle(s, 50))
            continue
        # At least 12 samples a cycle and five cycles a record: what the
        # analyzer judges rather than refuses (period sanity).
        assert 12.0 <= s.cycle_period <= s.samples / 5.0
        assert 0.3 <= s.cycle_amplitude <= 3.0
        assert s.cycle_shape in ('sine', 'triangle', 'square')
        # The other label keeps the cycle and its size; its period may differ,
        # as its bound follows the record's length, drawn with the label.
        other = draw_scenario(s.seed, not s.label)
        assert (other.cycle_amplitude, other.cycle_shape) == (s.cycle_amplitude, s.cycle_shape)


def test_unit_waves_have_their_period_and_unit_peak():
    # 600 samples of a 37.5-sample period: exactly 16 cycles, so each shape's
    # strongest frequency is bin 16, and each swings between -1 and 1.
    n, period, phase = 600, 37.5, 0.3
    k = np.arange(n)
    np.testing.assert_allclose(wave('sine', period, phase, n),
                               np.sin(2.0 * np.pi * k / period + phase), atol=1e-12)
    for shape in ('sine', 'triangle', 'square'):
        w = wave(shape, period, phase, n)
        assert np.max(np.abs(w)) <= 1.0 + 1e-12
        # (a sampled triangle misses its peak by up to half a step, 2 / 37.5)
        assert np.max(w) > 0.94 and np.min(w) < -0.94
        assert abs(np.mean(w)) < 0.05
        spectrum = np.abs(np.fft.rfft(w))
        assert int(np.argmax(spectrum[1:])) + 1 == 16, shape


def test_a_linear_loop_answers_a_sine_with_a_sine_of_its_frequency():
    # Superposition: with a linear valve, plant and PI, the record with the
    # cycle minus its twin without is the loop's answer to the cycle alone,
    # which settles to a sine of the cycle's own frequency in OP and in PV (what
    # is left in the second half is a slow loop's start-up transient, under 1 %).
    checked = 0
    for seed in range(300):
        sc = draw_scenario(seed)
        if sc.label or sc.look_alike or sc.rangeability != 1.0 or sc.law:
            continue
        sc = dataclasses.replace(sc, cycle_amplitude=1.0, cycle_period=41.0, cycle_phase=0.4,
                                 cycle_shape='sine', cycle_lag=2.0)
        with_cycle = simulate(sc)
        twin = simulate(dataclasses.replace(sc, cycle_amplitude=0.0))
        n = sc.samples
        k = np.arange(n // 2, n)
        basis = np.column_stack([np.sin(2 * np.pi * k / 41.0), np.cos(2 * np.pi * k / 41.0)])
        for name in ('op', 'pv'):
            diff = with_cycle[name][k] - twin[name][k]
            coef, *_ = np.linalg.lstsq(basis, diff, rcond=None)
            resid = diff - basis @ coef
            assert np.std(diff) > 0.0
            assert np.std(resid) < 1e-2 * np.std(diff), (seed, name)
        checked += 1
        if checked == 8:
            break
    assert checked == 8

"""A corpus loop whose controller runs faster than the record is sampled (``oversample``)."""

import dataclasses

import numpy as np
import pytest

from stiction_ros.sim.corpus import draw_scenario, simulate
from stiction_ros.study import probes


def healthy_linear(integrating, seeds=range(3000)):
    for seed in seeds:
        sc = draw_scenario(seed, False)
        if (sc.valve == 'linear' and sc.integrating is integrating and not sc.look_alike
                and sc.cycle_amplitude == 0.0 and sc.tau > 3.0 * sc.sample_time):
            return sc
    raise AssertionError('no such seed')


@pytest.mark.parametrize('integrating', [False, True])
def test_a_faster_controller_converges_to_the_continuous_loop(integrating):
    # Loads, set point and noise are held over each record sample whatever the
    # rate, so as the controller, valve and plant run finer the record tends to
    # the continuous-time loop's: each doubling moves it less than the one before.
    sc = healthy_linear(integrating)
    pv = [simulate(sc, oversample=m)['pv'] for m in (1, 2, 4, 8, 16)]
    steps = [float(np.max(np.abs(b - a))) for a, b in zip(pv, pv[1:])]
    assert steps[0] > 0.0
    # First order in the step, as a held input's error is: each doubling halves it.
    for a, b in zip(steps, steps[1:]):
        assert 0.4 < b / a < 0.6


def test_the_record_keeps_its_samples_and_set_point_at_any_rate():
    sc = draw_scenario(11)
    as_drawn = simulate(sc)
    for average in (False, True):
        rec = simulate(sc, oversample=5, average=average)
        for key in ('t', 'op', 'pv', 'sp', 'mv'):
            assert rec[key].shape == (sc.samples,)
            assert np.isfinite(rec[key]).all()
        # The set point is held over each sample: its value and its mean agree.
        np.testing.assert_allclose(rec['sp'], as_drawn['sp'], rtol=0, atol=1e-9)
        np.testing.assert_array_equal(rec['t'], as_drawn['t'])


def test_the_interval_mean_lies_between_the_samples_around_it_for_a_monotone_stretch():
    # A mean over (k, k+1) of a PV that rises through the interval lies between
    # the value at its start and at the next start; checked where the snapshot
    # record rises over three samples in a row, on a record with a slow plant.
    sc = dataclasses.replace(healthy_linear(False), noise_std=0.0)
    m = 8
    snap = simulate(sc, oversample=m)['pv']
    mean = simulate(sc, oversample=m, average=True)['pv']
    d = np.diff(snap)
    rising = np.flatnonzero((d[:-1] > 1e-9) & (d[1:] > 1e-9))
    assert len(rising) > 10
    for k in rising:
        assert snap[k] - 1e-9 <= mean[k] <= snap[k + 1] + 1e-9


def test_the_record_is_the_value_at_each_sample_time_from_the_first():
    # The historian's sample k is the loop at k * ts: the first is the loop at rest,
    # the same whatever the rate.
    sc = draw_scenario(11)
    as_drawn = simulate(sc)
    for m in (2, 5):
        rec = simulate(sc, oversample=m)
        assert rec['pv'][0] == as_drawn['pv'][0] and rec['op'][0] == as_drawn['op'][0]


def test_a_frozen_transmitter_freezes_the_same_samples_at_any_rate():
    for seed in range(3000):
        sc = draw_scenario(seed, False)
        if sc.look_alike != 'sensor_fault':
            continue
        pv = simulate(sc)['pv']
        same = np.flatnonzero(np.diff(pv) == 0.0) + 1
        if len(same) >= 30 and same[-1] - same[0] + 1 == len(same):
            break
    else:
        raise AssertionError('no seed with a frozen PV')
    start, end = int(same[0]), int(same[-1]) + 1      # frozen samples start..end-1
    fast = simulate(sc, oversample=4)['pv']
    assert np.all(fast[start:end] == fast[start])
    assert fast[end] != fast[end - 1] and fast[start - 1] != fast[start]


@pytest.mark.parametrize('bad', [0, -1, 2.5])
def test_a_rate_that_is_not_a_whole_number_of_at_least_one_is_refused(bad):
    with pytest.raises(ValueError, match='oversample'):
        simulate(draw_scenario(3), oversample=bad)


def test_the_fast_controller_probe_and_its_twin_are_the_same_drawn_loop():
    for seed in range(6):
        fast, twin = probes.fast_controller(seed), probes.fast_controller(seed, twin=True)
        corpus = simulate(draw_scenario(seed))
        np.testing.assert_array_equal(twin.op, corpus['op'])
        np.testing.assert_array_equal(twin.pv, corpus['pv'])
        assert (fast.label, fast.integrating, fast.sample_time) == (
            twin.label, twin.integrating, twin.sample_time)
        np.testing.assert_allclose(fast.sp, twin.sp, rtol=0, atol=1e-9)
        assert not np.array_equal(fast.op, twin.op)

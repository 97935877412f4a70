"""The training corpus: determinism, valve physics, the sampled plant, labels and ranges."""

from collections import Counter
import dataclasses

import numpy as np
import pytest
from scipy import signal

from stiction_ros.sim.corpus import (
    draw_label, draw_scenario, LOOK_ALIKES, make_corpus, plant_response, Scenario, simulate,
    STICTION_VALVES)

SEEDS = range(200)


@pytest.fixture(scope='module')
def corpus():
    return make_corpus(SEEDS)


def first(pred, label=None, seeds=range(2000)):
    for seed in seeds:
        sc = draw_scenario(seed, label)
        if pred(sc):
            return sc
    raise AssertionError('no seed gives such a scenario')


def test_same_seed_same_record_other_seed_other_record():
    a, b, c = simulate(draw_scenario(7)), simulate(draw_scenario(7)), simulate(draw_scenario(8))
    assert draw_scenario(7) == draw_scenario(7)
    for key in ('t', 'op', 'pv', 'sp', 'mv'):
        assert np.array_equal(a[key], b[key])
    assert a['op'].shape != c['op'].shape or not np.array_equal(a['op'], c['op'])
    assert draw_scenario(7).to_json() == dataclasses.asdict(draw_scenario(7))


def test_forcing_the_label_keeps_the_seed_deterministic():
    assert draw_scenario(3).label == draw_label(3)
    for label in (True, False):
        assert draw_scenario(3, label) == draw_scenario(3, label)
        assert draw_scenario(3, label).label is label


def test_ideal_valve_passes_op_and_a_positioner_rounds_it():
    lin = first(lambda s: s.valve == 'linear')
    d = simulate(lin)
    assert np.array_equal(d['mv'], np.clip(d['op'], 0.0, 100.0))
    q = first(lambda s: s.valve == 'quantised', label=False)
    d = simulate(q)
    steps = d['mv'] / q.quantum
    assert np.allclose(steps, np.round(steps), rtol=0.0, atol=1e-9)
    assert np.ptp(d['mv']) > 0.0


def stuck_blocks(mv):
    """Yield (a, b): mv[a..b] equal, mv moved at a, at least one stuck sample after it."""
    k, n = 1, len(mv)
    while k < n - 1:
        if mv[k] != mv[k - 1] and mv[k + 1] == mv[k]:
            b = k + 1
            while b + 1 < n and mv[b + 1] == mv[k]:
                b += 1
            yield k, b
            k = b + 1
        else:
            k += 1


def test_kano_valve_holds_until_op_passes_the_band():
    # Kano: a valve that came to rest after moving in direction d stays put
    # while OP stays within [-S, +J] of its value at the stop (the deadband
    # plus stickband against d, the slip jump along d), and moves as soon as
    # OP leaves that band.
    checked = 0
    for seed in range(400):
        sc = draw_scenario(seed, True)
        if sc.valve != 'kano':
            continue
        d = simulate(sc)
        op, mv = d['op'], d['mv']
        for a, b in stuck_blocks(mv):
            if mv[a] <= 0.0 or mv[a] >= 100.0:
                continue
            direction = np.sign(op[a] - op[a - 1])
            rel = direction * (op[a + 1:b + 1] - op[a])
            assert rel.max() <= sc.J + 1e-9 and -rel.min() <= sc.S + 1e-9
            if b + 1 < len(mv):
                nxt = direction * (op[b + 1] - op[a])
                assert nxt > sc.J - 1e-9 or -nxt > sc.S - 1e-9
            checked += 1
        if checked > 200:
            break
    assert checked > 200


@pytest.mark.parametrize('integrating, gain, tau, tau2, delay', [
    (True, 0.002, 25.0, 0.0, 24.0),      # integrator + lag, 2.4 samples dead time
    (False, -1.5, 30.0, 12.0, 7.0),      # two lags, dead time under one sample
    (False, 2.0, 1.5, 0.0, 10.0),        # lag far below the sample time
])
def test_sampled_plant_matches_continuous_simulation(integrating, gain, tau, tau2, delay):
    ts, n, fine = 10.0, 80, 100
    sc = dataclasses.replace(draw_scenario(0), integrating=integrating, gain=gain, tau=tau,
                             tau2=tau2, delay=delay, sample_time=ts, samples=n,
                             rangeability=1.0)
    mv = np.full(n, 50.0)
    mv[5:], mv[30:], mv[55:] = 60.0, 45.0, 52.0
    pv = plant_response(sc, mv, mv0=50.0)
    den = np.polymul([tau, 1.0], [tau2, 1.0])
    if integrating:
        den = np.polymul(den, [1.0, 0.0])
    t = np.arange(n * fine + 1) * (ts / fine)
    shift = int(round(delay / ts * fine))
    idx = (np.arange(t.size) - shift) // fine
    u = np.where(idx >= 0, mv[np.clip(idx, 0, n - 1)] - 50.0, 0.0)
    _, y, _ = signal.lsim(([gain], den), u, t, interp=False)
    want = y[::fine][:n]
    assert np.allclose(pv, want, rtol=1e-6, atol=1e-6 * np.abs(want).max())


def test_labels_balance_and_look_alikes(corpus):
    scenarios, _ = corpus
    share = np.mean([s.label for s in scenarios])
    assert 0.4 < share < 0.6
    looks = Counter(s.look_alike for s in scenarios)
    for name in LOOK_ALIKES:
        assert looks[name] >= 3, (name, looks)
    plain = sum(1 for s in scenarios if not s.label and not s.look_alike)
    alike = sum(1 for s in scenarios if not s.label and s.look_alike)
    assert 0.3 < plain / (plain + alike) < 0.7
    for s in scenarios:
        assert s.label == (s.valve in STICTION_VALVES)
        if s.label:
            assert s.S >= 0.3 and s.J >= 0.1 * s.S
        assert s.look_alike in LOOK_ALIKES + ('',)
    few = make_corpus(range(100), label_balance=0.2)[0]
    assert 0.08 < np.mean([s.label for s in few]) < 0.32


def test_records_are_finite_in_range_and_stable(corpus):
    scenarios, records = corpus
    for s, r in zip(scenarios, records):
        assert isinstance(s, Scenario)
        for key in ('t', 'op', 'pv', 'sp', 'mv'):
            assert r[key].shape == (s.samples,) and np.all(np.isfinite(r[key]))
        assert r['op'].min() >= 0.0 and r['op'].max() <= 100.0
        assert np.allclose(np.diff(r['t']), s.sample_time)
        assert 500 <= s.samples <= 2500 and s.Kc > 0.0 and s.Ti > 0.0
        if not s.look_alike and not s.label:
            # A healthy, well-tuned loop never runs away into its OP limits.
            assert np.mean((r['op'] <= 0.0) | (r['op'] >= 100.0)) < 0.02
    inside = np.concatenate([(r['op'] > 5.0) & (r['op'] < 95.0) for r in records])
    assert inside.mean() > 0.97


def test_set_points_are_held_stepped_by_operators_or_remote(corpus):
    # Historian records show all three, and a cascade secondary's remote set point
    # (its master's output) moves at almost every sample; level loops mostly hold theirs.
    scenarios, records = corpus
    kinds = Counter()
    for s, r in zip(scenarios, records):
        moving = float(np.mean(np.diff(r['sp']) != 0.0))
        kind = 'held' if moving == 0.0 else 'remote' if moving > 0.5 else 'steps'
        kinds[kind, s.integrating] += 1
        if kind == 'steps':
            assert np.sum(np.diff(r['sp']) != 0.0) <= 15, s
        if kind == 'remote':
            # a wandering set point, not a ramp: it turns back
            d = np.diff(r['sp'])
            assert np.any(d > 0) and np.any(d < 0), s
    for kind in ('held', 'steps', 'remote'):
        assert kinds[kind, False] >= 10, kinds
    assert kinds['remote', True] == 0, kinds
    integrating = sum(n for (k, i), n in kinds.items() if i)
    assert kinds['held', True] > 0.6 * integrating, kinds

"""The probes: loops the simulator never draws, each from its own generator (make probes)."""

import json
import math

import numpy as np
import pytest
from stiction_ros.analysis.detection.resolve import LIMIT_SWINGS, limit_swings
from stiction_ros.study import probes
from stiction_ros.study.probes import PROBES


def test_each_probe_is_a_function_of_its_seed_alone():
    for _, _, draw in PROBES:
        a, b, c = draw(5), draw(5), draw(6)
        np.testing.assert_array_equal(a.op, b.op)
        np.testing.assert_array_equal(a.pv, b.pv)
        assert not np.array_equal(a.pv, c.pv)
        assert len(a.op) == len(a.pv) == len(a.sp) and np.isfinite(a.op).all()
        assert a.op.min() >= 0.0 and a.op.max() <= 100.0


def test_the_linear_twin_is_the_same_loop_with_only_the_characteristic_taken_out():
    # Every draw the same (label, loop type, the first sample's noise), the
    # records different: only the valve's characteristic is taken out.
    checked = 0
    for seed in range(40):
        eq, lin = probes.equal_percentage(seed), probes.equal_percentage(seed, linear=True)
        assert (eq.label, eq.integrating) == (lin.label, lin.integrating)
        if eq.label:
            continue
        assert eq.pv[0] == lin.pv[0]
        assert not np.array_equal(eq.op, lin.op)
        checked += 1
    assert checked >= 10


def test_the_twins_are_one_generator_the_corpus_loop_as_drawn_read_once():
    twins = [draw for name, _, draw in PROBES if name.endswith(', twin')]
    assert len(twins) == 2 and twins[0] is twins[1] is probes.as_drawn
    for seed in (3, 4):
        a, b = probes.fast_controller(seed, twin=True), probes.as_drawn(seed)
        np.testing.assert_array_equal(a.op, b.op)
        np.testing.assert_array_equal(a.pv, b.pv)


def test_the_long_dead_time_probe_is_the_corpus_loop_with_more_dead_time_and_a_looser_pi():
    from dataclasses import asdict
    from stiction_ros.sim.corpus import draw_scenario
    checked = 0
    for seed in range(40):
        drawn, longer = asdict(draw_scenario(seed)), asdict(draw_scenario(seed, extra_delay=9.0))
        if drawn['look_alike'] in ('aggressive_tuning', 'integrating_cycle'):
            continue        # a ringing look-alike redraws its plant until it rings
        # Only the dead time and what depends on the tuning move.
        moved = {k for k in drawn if drawn[k] != longer[k]}
        assert moved <= {'delay', 'Kc', 'Ti', 'noise_std', 'gap'} and 'delay' in moved
        assert math.isclose(longer['delay'] - drawn['delay'], 9.0 * drawn['sample_time'])
        # Tuned for the longer dead time: a smaller gain, as every rule gives.
        assert longer['Kc'] < drawn['Kc']
        checked += 1
    assert checked >= 30
    a, b = probes.long_dead_time(7), probes.long_dead_time(7, twin=True)
    assert (a.label, a.integrating, a.sample_time) == (b.label, b.integrating, b.sample_time)


def test_a_loop_is_cooled_only_when_its_linear_version_does_not_settle():
    t = np.arange(probes.SETTLE)
    assert probes._settles(lambda kick: kick * 0.999 ** t)
    assert not probes._settles(lambda kick: kick * np.cos(0.3 * t))
    assert not probes._settles(lambda kick: np.minimum(kick * 1.01 ** t, 100.0))


def test_the_gap_controller_barely_moves_op_while_the_level_stays_in_its_gap():
    # Inside the gap a tenth of the gain: OP's steps there are a fraction of those
    # outside, the signature of averaging level control (and not of a valve).
    gap = probes._gap
    assert math.isclose(gap(0.5, 2.0), 0.05) and math.isclose(gap(3.0, 2.0), 1.2)
    assert math.isclose(gap(-3.0, 2.0), -1.2)
    # Continuous at the gap's edges: the law has no jump that could read as a slip.
    assert math.isclose(gap(2.0 - 1e-12, 2.0), gap(2.0 + 1e-12, 2.0), abs_tol=1e-9)
    assert math.isclose(probes._squared(-2.0, 4.0), -1.0)


@pytest.mark.slow
def test_a_detuned_loop_cycling_between_op_limits_is_refused_by_its_rule(tmp_path):
    from stiction_ros.cli.probes import main
    seeds = range(3_960_000, 3_960_002)
    study = probes.run(seeds, jobs=1)
    detuned = [j for j, p in enumerate(PROBES) if p[0] == 'detuned'][0]
    cycling = 0
    for j, seed, label, answer, p, code in study.answers:
        if j == detuned and limit_swings(probes.detuned(seed).op) >= LIMIT_SWINGS:
            assert answer == 'cannot tell' and p is None and code == 'limit_cycling'
            cycling += 1
    assert cycling >= 1
    rows = study.rows()
    assert sum(r['records'] for r in rows) == len(PROBES) * len(seeds)
    for r in rows:
        told = r['stiction'] + r['no_stiction'] + r['balanced'] + sum(r['refused'].values())
        assert told == r['records'] and r['at_half'] <= r['judged'] <= r['records']
    md, js = tmp_path / 'p.md', tmp_path / 'p.json'
    assert main(['--first-seed', '3960000', '--seeds', '1', '--jobs', '1',
                 '--markdown', str(md), '--json', str(js)]) == 0
    assert all(f'| {p[0]} |' in md.read_text() for p in PROBES)
    assert json.loads(js.read_text())['seeds'] == [3_960_000, 3_960_001]
    assert main(['--seeds', '0']) == 2

"""The corpus's equal-percentage valves and level controller laws: physics and draws."""

import dataclasses

import numpy as np
import pytest

from stiction_ros.kernels.corpus import controller_law, installed_flow, LAW_GAP, LAW_PI, \
    LAW_SQUARED
from stiction_ros.sim.corpus import draw_scenario, plant_response, simulate


def test_equal_percentage_flow_has_unit_slope_at_rest_and_gain_growing_r_times():
    r, mv0, h = 30.0, 40.0, 1e-4
    assert installed_flow(mv0, mv0, r) == 0.0
    slope = (installed_flow(mv0 + h, mv0, r) - installed_flow(mv0 - h, mv0, r)) / (2 * h)
    assert slope == pytest.approx(1.0, rel=1e-6)
    x = np.linspace(0.0, 100.0, 201)
    f = np.array([installed_flow(v, mv0, r) for v in x])
    assert np.all(np.diff(f) > 0.0)

    # Equal percentage: equal travel multiplies the slope by the same factor.
    def slope_at(v):
        return (installed_flow(v + h, mv0, r) - installed_flow(v - h, mv0, r)) / (2 * h)
    assert slope_at(90.0) / slope_at(10.0) == pytest.approx(r ** 0.8, rel=1e-5)
    assert slope_at(60.0) / slope_at(30.0) == pytest.approx(slope_at(80.0) / slope_at(50.0))
    # A rangeability of 1 is a linear valve, to the bit.
    assert installed_flow(73.25, mv0, 1.0) == 73.25 - mv0


@pytest.mark.parametrize('law', [LAW_GAP, LAW_SQUARED])
def test_level_laws_are_odd_continuous_and_gentle_inside_the_gap(law):
    gap, inner = 2.0, 0.1
    e = np.linspace(-6.0, 6.0, 1201)
    out = np.array([controller_law(v, law, gap, inner) for v in e])
    assert np.allclose(out, -out[::-1])
    for edge in (gap, -gap):                             # no jump at the gap
        assert abs(controller_law(edge + 1e-9, law, gap, inner)
                   - controller_law(edge - 1e-9, law, gap, inner)) < 1e-7
    assert np.all(np.diff(out) >= 0.0)                   # never acts against the error
    small = np.abs(e) < 0.5 * gap
    assert np.all(np.abs(out[small]) < 0.5 * np.abs(e[small]) + 1e-12)
    assert controller_law(gap, law, gap, inner) == pytest.approx(
        gap if law == LAW_SQUARED else inner * gap)
    assert controller_law(1.7, LAW_PI, gap, inner) == 1.7
    # Never hotter than the PI tuned at the set point: a law that is would turn a
    # tuned loop unstable after one upset.
    assert np.all(np.abs(out) <= np.abs(e) + 1e-12)
    outside = np.abs(e) > gap + 1e-9                     # the full gain beyond the gap
    assert np.allclose(np.abs(out[outside]) - np.abs(e[outside]),
                       -(1.0 - inner) * gap if law == LAW_GAP else 0.0)


def test_equal_percentage_plant_gains_more_opening_than_closing():
    # Same scenario, only the characteristic changed: a step up moves PV further
    # than the same step down, by the ratio the characteristic demands.
    sc = next(s for s in map(draw_scenario, range(500))
              if not s.integrating and s.valve == 'linear' and s.rangeability == 1.0)
    n, mv0, r = 400, 50.0, 25.0
    up, down = np.full(n, mv0), np.full(n, mv0)
    up[10:], down[10:] = mv0 + 10.0, mv0 - 10.0
    lin = dataclasses.replace(sc, samples=n)
    eq = dataclasses.replace(lin, rangeability=r)
    assert np.allclose(plant_response(lin, up, mv0), -plant_response(lin, down, mv0))
    rise, fall = plant_response(eq, up, mv0)[-1], -plant_response(eq, down, mv0)[-1]
    want = (r ** 0.1 - 1.0) / (1.0 - r ** -0.1)
    assert rise / fall == pytest.approx(want, rel=1e-6)
    assert rise / fall > 1.1


@pytest.mark.slow
def test_nonlinearities_are_drawn_for_both_labels_alike_and_leave_other_draws_alone():
    drawn = [draw_scenario(s) for s in range(1500)]
    for label in (False, True):
        group = [s for s in drawn if s.label == label]
        share = np.mean([s.rangeability > 1.0 for s in group])
        assert 0.22 < share < 0.38, (label, share)
        level = [s for s in group if s.integrating]
        laws = np.mean([s.law != '' for s in level])
        assert 0.18 < laws < 0.42, (label, laws)
    for s in drawn:
        assert s.rangeability == 1.0 or 10.0 <= s.rangeability <= 50.0
        assert s.law in ('', 'gap', 'squared')
        assert (s.law == '') == (s.gap == 0.0)
        assert s.law == '' or s.integrating
        # Forcing the other label leaves the valve's characteristic as it was
        # (a look-alike may make the plant integrating, and only those get a law).
        other = draw_scenario(s.seed, not s.label)
        assert other.rangeability == s.rangeability
        if other.integrating == s.integrating:
            assert other.law == s.law


def test_healthy_nonlinear_loops_stay_inside_ops_range():
    checked = 0
    for seed in range(400):
        sc = draw_scenario(seed)
        if sc.label or sc.look_alike or (sc.rangeability == 1.0 and not sc.law):
            continue
        op = simulate(sc)['op']
        assert np.all(np.isfinite(op))
        assert np.mean((op <= 0.0) | (op >= 100.0)) < 0.005, sc
        checked += 1
    assert checked > 20


@pytest.mark.slow
def test_level_laws_keep_even_aggressive_loops_off_ops_limits():
    # Error squared without its cap slammed OP between 0 and 100 % on 7 of 19
    # aggressively tuned level loops (review); capped, a law loop of any label
    # or look-alike saturates no more than its linear twin.
    checked = 0
    for seed in range(4000, 7000):
        sc = draw_scenario(seed)
        if sc.law != 'squared' or sc.tuning != 'aggressive':
            continue
        op = simulate(sc)['op']
        twin = simulate(dataclasses.replace(sc, law='', gap=0.0, inner=1.0))['op']
        share, twin_share = (np.mean((x <= 0.0) | (x >= 100.0)) for x in (op, twin))
        assert share <= twin_share + 0.02, (sc, share, twin_share)
        checked += 1
    assert checked >= 5

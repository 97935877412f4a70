"""Historian holds: rows repeating the previous one are found, dropped, and never invented."""

import numpy as np
import pytest

from stiction_ros.analysis.detection import detect
from stiction_ros.analysis.detection.detect import answer_of
from stiction_ros.analysis.detection.stale import drop_held, MAX_HELD, stale_rows
from stiction_ros.sim.corpus import draw_scenario, simulate


def _healthy_record(first_seed=300):
    for seed in range(first_seed, first_seed + 200):
        sc = draw_scenario(seed, label=False)
        if not sc.look_alike and not sc.integrating and sc.samples >= 700:
            return sc, simulate(sc)
    raise AssertionError('no plain healthy loop drawn')


def _hold(rec, held):
    """Return OP, PV, SP with every ``held`` row a copy of the row before it."""
    op, pv, sp = (np.array(rec[k], dtype=float) for k in ('op', 'pv', 'sp'))
    for k in np.flatnonzero(held):
        op[k], pv[k], sp[k] = op[k - 1], pv[k - 1], sp[k - 1]
    return op, pv, sp


def _blocks(n, length=10, every=32):
    held = np.zeros(n, bool)
    for s in range(5, n - length - 2, every):
        held[s + 1:s + 1 + length] = True
    return held


def test_simulated_loops_hold_no_rows():
    # White and coloured noise, quantised PV and positioner, saturated OP, frozen
    # sensors: none repeats OP and PV together, so training never saw a repair.
    for seed in range(0, 120):
        rec = simulate(draw_scenario(seed))
        assert stale_rows(rec['op'], rec['pv'], rec['sp']).count == 0, seed


def test_held_rows_are_found_exactly_and_dropped():
    sc, rec = _healthy_record()
    n = len(rec['op'])
    rng = np.random.default_rng(3)
    held = _blocks(n) | (rng.random(n) < 0.05)
    held[0] = False
    op, pv, sp = _hold(rec, held)
    before = op.copy()
    found = stale_rows(op, pv, sp)
    np.testing.assert_array_equal(found.held, held)
    op2, pv2, sp2, found = drop_held(op, pv, sp)
    np.testing.assert_array_equal(op, before)          # the input is left alone
    np.testing.assert_array_equal(found.kept, np.flatnonzero(~held))
    for a, b in ((op2, op), (pv2, pv), (sp2, sp)):
        np.testing.assert_array_equal(a, b[~held])
    assert stale_rows(op2, pv2, sp2).count == 0


def test_rows_inserted_by_a_slow_source_give_back_the_source():
    # A transmitter read every 11.5 s into a 10 s export repeats a row now and
    # then without losing one: dropping the repeats returns its own samples.
    sc, rec = _healthy_record()
    op, pv, sp = (np.asarray(rec[k], dtype=float) for k in ('op', 'pv', 'sp'))
    t_source = np.arange(len(op)) * 11.5
    grid = np.arange(0.0, t_source[-1], 10.0)
    latest = np.searchsorted(t_source, grid, side='right') - 1
    assert len(grid) > len(op)
    got = drop_held(op[latest], pv[latest], sp[latest])
    np.testing.assert_array_equal(got[0], op[:latest[-1] + 1])
    np.testing.assert_array_equal(got[1], pv[:latest[-1] + 1])


def test_a_coarse_pv_is_not_read_as_holds():
    # A transmitter on a 1-unit grid: PV repeats while OP moves, and repeats
    # in step with OP by chance; no rows are claimed.
    rng = np.random.default_rng(5)
    pv = np.round(50 + 0.6 * rng.standard_normal(2000))
    op = 40 + np.cumsum(0.01 * (50 - pv))
    op[::7] = np.roll(op, 1)[::7]
    assert stale_rows(op, pv).count == 0


def test_detector_names_the_holds_or_declines():
    sc, rec = _healthy_record()
    n = len(rec['op'])
    some = _blocks(n)
    d = detect(*_hold(rec, some), sc.sample_time, sc.integrating)
    assert d.details['held_rows'] == int(some.sum())
    assert 'held values' in d.evidence[0]
    most = np.zeros(n, bool)
    most[1:int(n * (MAX_HELD + 0.1))] = True
    d = detect(*_hold(rec, most), sc.sample_time, sc.integrating)
    assert d.answer == 'cannot tell' and d.judge.code == 'historian_holds'
    assert d.to_json()['held_rows'] == int(most.sum())


@pytest.mark.parametrize('n', [0, 1, 2])
def test_tiny_records_have_no_holds(n):
    found = stale_rows(np.ones(n), np.ones(n))
    assert found.count == 0 and found.share == 0.0


def _paused(seed, at=20, pause=40):
    """Return the scenario and its detections, clean and with ``pause`` rows held at ``at``."""
    sc = draw_scenario(seed, label=True)
    rec = simulate(sc)
    idx = np.concatenate([np.arange(at + 1), np.full(pause, at),
                          np.arange(at + 1, len(rec['op']))])
    clean = detect(rec['op'], rec['pv'], rec['sp'], sc.sample_time, sc.integrating)
    held = detect(rec['op'][idx], rec['pv'][idx], rec['sp'][idx], sc.sample_time,
                  sc.integrating)
    return sc, clean, held


def test_inserted_holds_change_nothing_but_where_the_evidence_points():
    # A sticky loop whose historian paused for 40 rows early on: the fresh rows
    # are the clean record, so the answer is the same, and every stuck period
    # is reported 40 rows later, where it sits in the record as given.
    at, pause = 20, 40
    sc, clean, held = _paused(321, at, pause)
    # The evidence leans to stiction (at 0.5 or more); held rows change neither it nor the answer.
    assert clean.probability >= 0.5 and held.probability == clean.probability
    assert held.answer == clean.answer == answer_of(clean.probability)
    assert held.details['held_rows'] == pause
    before, after = clean.details['stuck'], held.details['stuck']
    assert before['stuck_periods_s'] and all(a > at * sc.sample_time
                                             for a, _, _ in before['stuck_periods_s'])
    shift = pause * sc.sample_time
    for (a0, b0, t0), (a1, b1, t1) in zip(before['stuck_periods_s'], after['stuck_periods_s']):
        assert (a1, b1, t1) == (a0 + shift, b0 + shift, t0)
    first = before['stuck_periods_s'][0][0]
    assert any(f'stuck period {first + shift:.0f} s' in line for line in held.evidence)


def test_a_slip_events_time_after_held_rows_is_the_records():
    # The signature counts the fresh rows it read; its evidence line names the
    # row of the record as given, 40 rows (of 10 s) later than in the clean record.
    pause = 40
    sc, clean, held = _paused(323, pause=pause)

    def slip_time(d):
        line = next(x for x in d.evidence if x.startswith('slip_events on its own: stiction'))
        return float(line.split('at t = ')[1].split(' s')[0])
    assert slip_time(held) == slip_time(clean) + pause * sc.sample_time


def test_too_short_after_the_holds_says_how_many_rows_the_stretch_had():
    sc, rec = _healthy_record()
    held = np.zeros(330, bool)
    held[1::3] = held[2::9] = True          # 147 of 330 rows: under half
    op, pv, sp = _hold({k: np.asarray(rec[k])[:330] for k in ('op', 'pv', 'sp')}, held)
    fresh = int((~held).sum())
    assert fresh < 200 and held.mean() < 0.5
    d = detect(op, pv, sp, sc.sample_time, sc.integrating)
    assert d.judge.code == 'too_short'
    assert d.judge.reason == (f'too short: {fresh} usable samples, at least 200 needed '
                              f"({int(held.sum())} of the stretch's 330 rows repeat the "
                              'previous row exactly in OP and PV: historian holds, not read)')

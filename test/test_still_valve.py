"""A valve that never breaks away: its size is bounded below only, and no verdict is claimed."""

import json

import numpy as np
import pytest

from stiction_ros.analysis.measures.still import set_point_test, still_valve
from stiction_ros.cli.analyze import main
from stiction_ros.models import Kano
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop, write_csv
from stiction_ros.sim.loop_config import load_loop


def _record(amplitude, S=4.0, J=1.0, n=3601, seed=3):
    # OP wanders slowly around 50 %; Kano's valve, put at rest there, follows if it can.
    rng = np.random.default_rng(seed)
    t = np.arange(n, dtype=float)
    op = 50.0 + amplitude * np.sin(2 * np.pi * t / 600.0) + 0.02 * rng.standard_normal(n)
    valve = Kano(S=S, J=J)
    valve.reset(y0=50.0)
    mv = valve.simulate(op) + 0.1 * rng.standard_normal(n)
    return {'t': t, 'sp': np.zeros(n), 'pv': op - 50.0, 'op': op, 'mv': mv}


def test_a_valve_that_never_breaks_away_is_still_and_one_that_slips_is_not():
    stuck = _record(1.0)                  # OP travels 2 %, less than S = 4 %
    found = still_valve(stuck['op'], stuck['mv'], [(0, len(stuck['op']))])
    assert found is not None and found.op_spread > 1.9 and found.mv_spread < 0.6
    assert abs(found.noise - 0.1) < 0.02
    moving = _record(6.0)                 # OP travels 12 %: it slips every half cycle
    assert still_valve(moving['op'], moving['mv'], [(0, len(moving['op']))]) is None
    # A healthy valve follows OP, however little OP moves, and however noisy its reading.
    quiet = _record(0.5, S=0.0, J=0.0)
    assert still_valve(quiet['op'], quiet['mv'], [(0, len(quiet['op']))]) is None
    op = _record(1.0)['op']                          # 2 % of travel
    noisy = op + 0.5 * np.random.default_rng(5).standard_normal(len(op))
    assert still_valve(op, noisy, [(0, len(op))]) is None


def test_a_frozen_or_stepped_reading_of_a_stuck_valve_is_still_and_a_stop_is_not():
    stuck = _record(1.0)
    whole = [(0, len(stuck['op']))]
    frozen = np.full(len(stuck['op']), 47.3)
    assert still_valve(stuck['op'], frozen, whole) is not None
    stepped = np.round(stuck['mv'] / 0.1) * 0.1          # a 0.1 % transmitter
    found = still_valve(stuck['op'], stepped, whole)
    assert found is not None and found.noise >= 0.1 / np.sqrt(12.0)
    # Held on a stop (a tight shut-off, a travel limit) is not a valve that did not break
    # away.
    assert still_valve(stuck['op'] - 49.0, np.full(len(stuck['op']), 0.4), whole) is None
    # With no noise to measure, OP must travel visibly.
    assert still_valve(50.0 + 0.1 * np.sin(np.arange(3601) / 50.0), frozen, whole) is None


def test_explain_cannot_tell_and_the_size_is_a_lower_bound_on_a_valve_that_never_moved(
        tmp_path, capsys):
    path = tmp_path / 'stuck.csv'
    write_csv(path, _record(1.0))
    out = tmp_path / 'r.json'
    assert main([str(path), '--explain', '--quiet', '--json', str(out)]) == 0
    report = json.loads(out.read_text())
    m = report['mismatch']
    assert m['effect'] == 'cannot_tell' and m['reason'] == 'mv_still' and m['effects'] == []
    assert 'did not break away' in m['explanation']
    st = report['stiction']
    caution = st['size_caution']
    assert 'bounded below only' in caution and 'not a measured size' in caution
    # The headline says what --explain says: MV cannot tell friction from a held valve
    # or a dead reading, however far the fit beats an ideal valve (MV = OP).
    assert max(f['improvement'] for f in report['fits']) > 0.9
    assert st['detected'] is None and st['answer'] == 'cannot tell'
    assert st['cannot_tell'] == 'mv_still' and 'dead position reading' in st['reason']
    assert 'play' not in st
    out = capsys.readouterr().out
    assert 'stuck: cannot tell (MV did not move' in out
    # Its set point never moved: PV cannot say which of the three it is.
    assert 'set_point_test' not in st
    assert 'mismatch: cannot tell' in out


def test_a_valve_that_slips_keeps_the_verdict_of_its_fits(tmp_path):
    path = tmp_path / 'slips.csv'
    write_csv(path, _record(6.0))         # OP travels 12 %, S = 4 %: it slips
    out = tmp_path / 'r.json'
    assert main([str(path), '--quiet', '--json', str(out)]) == 0
    st = json.loads(out.read_text())['stiction']
    assert st['detected'] is True and 'cannot_tell' not in st


def test_a_reading_that_drifts_but_does_not_follow_op_is_still_and_a_sticky_one_is_not():
    # A stuck valve read by a transmitter that drifts 0.3 % over the record: past its noise,
    # but a fiftieth of OP's travel and not with it.
    stuck = _record(6.0, S=20.0)                       # OP travels 12 %, S = 20 %
    n = len(stuck['op'])
    whole = [(0, n)]
    drift = 48.0 + np.linspace(0.0, 0.3, n) + 0.02 * np.random.default_rng(2).standard_normal(n)
    found = still_valve(stuck['op'], drift, whole)
    assert found is not None and found.drifted and found.mv_spread > 8 * found.noise
    assert 'drift of the reading' in found.sentence()
    # A sticky valve that slips moves by most of OP's travel; a reading at a fifth of it
    # (a gain no positioner has, but a response) is not still either.
    assert still_valve(stuck['op'], _record(6.0)['mv'], whole) is None
    fifth = 50.0 + 0.2 * (stuck['op'] - 50.0) + 0.02 * np.random.default_rng(4).standard_normal(n)
    assert still_valve(stuck['op'], fifth, whole) is None


# Set-point moves up and down, large against PV's noise (0.02): what lets PV say whether
# the valve moved while its reading stood still.
UP_DOWN = [[0.0, 0.0], [300.0, 4.0], [900.0, -2.0], [1500.0, 3.2], [2200.0, 0.0]]


def _loop(S, steps=UP_DOWN, dead_reading=False):
    # The chapter's concentration loop under its PI controller, with Kano's valve.
    cfg = load_loop(config_file('concentration_loop.yaml'), overrides={
        'valve': {'model': 'kano', 'S': S, 'J': 0.0},
        'controller': {'mode': 'closed_loop', 'Kc': 0.2, 'Ti': 10.0,
                       'setpoint': {'type': 'steps', 'steps': steps}},
        'noise': {'pv_std': 0.02, 'mv_std': 0.1, 'seed': 1}, 'duration': 3000.0})
    data = dict(simulate_loop(cfg))
    if dead_reading:
        # The valve moves; its position transmitter reads one value and noise.
        rng = np.random.default_rng(0)
        data['mv'] = 50.0 + 0.1 * rng.standard_normal(len(data['mv']))
    return data


def test_a_loop_whose_valve_moves_settles_on_each_set_point_and_a_stuck_one_does_not():
    whole = [(0, 3001)]
    moving = _loop(0.0)
    found = set_point_test(moving['pv'], moving['sp'], whole)
    # Integral action: PV settles on each new set point, up or down.
    assert found.follows and found.steps == (4.0, -6.0, 5.2, -3.2)
    assert all(abs(x - 1.0) < 0.05 for x in found.shares)
    stuck = _loop(100.0)                  # S = 100 %: the valve never breaks away
    assert still_valve(stuck['op'], stuck['mv'], whole) is not None
    found = set_point_test(stuck['pv'], stuck['sp'], whole)
    assert not found.follows and all(abs(x) < 0.05 for x in found.shares)
    # A set point that moved one way only, or not at all, cannot tell.
    for steps in ([[0.0, 0.0], [300.0, 4.0]], [[0.0, 0.0]]):
        one_way = _loop(0.0, steps)
        assert set_point_test(one_way['pv'], one_way['sp'], whole) is None
    # Nor can steps that disagree: a load that moved PV at one step only.
    pv = stuck['pv'].copy()
    pv[1500:] += 5.2
    assert set_point_test(pv, stuck['sp'], whole) is None
    # Only the longest stretch between gaps is read (its steps settle within it).
    pv = moving['pv'].copy()
    pv[2000] = np.nan
    found = set_point_test(pv, moving['sp'], [(0, 2000), (2001, 3001)])
    assert found.follows and found.steps == (4.0, -6.0, 5.2)
    assert set_point_test(pv, moving['sp'], whole) is None       # NaN inside: not read


@pytest.mark.slow
def test_a_dead_position_reading_is_told_from_a_stuck_valve_by_pv(tmp_path, capsys):
    dead, stuck = tmp_path / 'dead.csv', tmp_path / 'stuck.csv'
    data = _loop(0.0, dead_reading=True)
    write_csv(dead, data)
    write_csv(stuck, _loop(100.0))
    # The same loop with no position reading at all: what OP and PV say.
    blind = tmp_path / 'blind.csv'
    write_csv(blind, data, columns=('t', 'sp', 'pv', 'op'))
    reports = {}
    for path in (dead, stuck, blind):
        out = tmp_path / f'{path.stem}.json'
        # The blind copy is read for its verdict alone.
        pages = ([] if path is blind else
                 ['--explain', '--html', str(tmp_path / f'{path.stem}.html')])
        assert main([str(path), '--quiet', '--json', str(out), *pages]) == 0
        reports[path.stem] = json.loads(out.read_text())
    # A dead reading is set aside, kept, and the record judged as the blind copy is.
    report = reports['dead']
    dead_mv = report['mv_dead']
    assert dead_mv['set_point_test']['follows'] and "MV's reading is dead" in dead_mv['reason']
    assert report['fits'] == [] and dead_mv['fits'] and 'mv' in report['signals']
    st, seen = report['stiction'], reports['blind']['stiction']
    assert 'cannot_tell' not in st and st['answer'] == seen['answer']
    assert st['probability'] == seen['probability'] is not None
    assert report['mismatch']['reason'] == 'mv_dead'
    page = (tmp_path / 'dead.html').read_text()
    assert 'MV set aside, so OP and PV decide' in page and 'MV never moved' not in page
    # A stuck valve: PV did not move either, and the fits' verdict is refused.
    st = reports['stuck']['stiction']
    assert st['answer'] == 'cannot tell' and st['cannot_tell'] == 'mv_still'
    assert 'mv_dead' not in reports['stuck'] and reports['stuck']['fits']
    assert st['set_point_test']['follows'] is False
    assert 'the reading is not dead' in st['reason']
    assert reports['stuck']['mismatch']['reason'] == 'mv_still'
    assert 'cannot tell &mdash; MV never moved, so the fits cannot decide' in (
        tmp_path / 'stuck.html').read_text()
    out = capsys.readouterr().out
    assert 'MV:       set aside: MV did not move' in out and 'From PV:' in out


def test_the_dead_reading_check_runs_both_cases_of_a_plain_loop_and_skips_the_others():
    from bench.dead_reading_check import one
    from stiction_ros.sim.corpus import draw_scenario
    rows = {s: one(s) for s in range(6_700_000, 6_700_300)}
    plain = [s for s, r in rows.items() if r]
    assert all([r[1] for r in rows[s]] == ['dead reading', 'stuck valve'] for s in plain)
    assert all(draw_scenario(s).valve != 'linear' or draw_scenario(s).look_alike
               for s, r in rows.items() if not r)
    # The test decides rarely (a set-point move must show PV following it or not), but
    # on these seeds it decides both cases at least once, and where it answers it is right.
    told = [r for s in plain for r in rows[s] if r[3] is not None]
    assert {r[1] for r in told} == {'dead reading', 'stuck valve'}
    assert all(r[2] and r[3] for r in told)

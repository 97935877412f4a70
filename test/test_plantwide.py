"""
Cycles shared between recordings: grouping, the likely source, and the batch analyzer's report.

The pure rules first (periods, clock times, the probability gap), then a
sticky loop whose cycle travels through a vessel into a healthy loop
(``sim.coupled_loops``): read together by ``stiction-analyze`` on a folder,
the sticky loop must be named as the source and the healthy one as carrying it.
"""

from datetime import datetime, timezone
import json
from pathlib import Path
import re

import numpy as np
import pytest

from stiction_ros.analysis.oscillation import detect_oscillation
from stiction_ros.analysis.plantwide import CycleMember, FLOOR, GAP, shared_cycles, TOLERANCE
from stiction_ros.app.batch import cycle_of
from stiction_ros.cli.analyze import main
from stiction_ros.sim.closed_loop import write_csv
from stiction_ros.sim.corpus import draw_scenario
from stiction_ros.sim.coupled_loops import coupled_pair, OWN_CYCLES, vessel

# A pair whose two loops both cycle (the corpus's sticky draws mostly do not).
PAIR_SEED = 6_100_031


def test_loops_cycling_at_one_period_form_one_group_and_others_stay_out():
    members = [CycleMember('a', 100.0, 0.9), CycleMember('b', 100.0 * (1 + TOLERANCE * 0.9), 0.3),
               CycleMember('c', 100.0 * (1 + TOLERANCE * 3), 0.95), CycleMember('d', 400.0, 0.1)]
    shared = shared_cycles(members)
    assert [[m.name for m in g.members] for g in shared.groups] == [['a', 'b']]
    assert shared.group_of('c') is None and shared.group_of('d') is None
    assert shared.groups[0].source == 'a' and not shared.groups[0].clock


def test_no_group_spreads_wider_than_the_tolerance_whatever_the_order():
    rng = np.random.default_rng(0)
    members = [CycleMember(f'p{p}', float(p), q) for p, q in
               zip((100, 110, 120, 126, 132, 300, 310), (0.9, 0.1, 0.2, 0.8, 0.1, 0.5, 0.6))]
    first = shared_cycles(members)
    for g in first.groups:
        periods = [m.period_s for m in g.members]
        assert max(periods) / min(periods) <= 1 + TOLERANCE
    assert sum(len(g.members) for g in first.groups) == 7
    for _ in range(5):
        shuffled = [members[i] for i in rng.permutation(len(members))]
        assert shared_cycles(shuffled).to_json() == first.to_json()


def test_every_two_members_of_a_group_were_recorded_together():
    # C overlaps A and B, D only B: a chain A-C-B-D is no group of four.
    members = [CycleMember('A', 100.0, 0.9, 0.0, 1000.0),
               CycleMember('B', 100.0, 0.1, 2000.0, 3000.0),
               CycleMember('C', 105.0, 0.2, 500.0, 2500.0),
               CycleMember('D', 110.0, 0.3, 2200.0, 2800.0)]
    groups = [sorted(m.name for m in g.members) for g in shared_cycles(members).groups]
    assert groups == [['A', 'C'], ['B', 'D']]
    # Less than four periods in common is no evidence of one cycle.
    short = [CycleMember('x', 100.0, 0.9, 0.0, 1000.0),
             CycleMember('y', 100.0, 0.1, 700.0, 2000.0)]
    assert not shared_cycles(short).groups


def test_clock_times_of_different_bases_are_never_compared_and_clockless_go_together():
    day = 86400.0
    members = [CycleMember('mon', 60.0, 0.9, 0.0, day, 'UTC'),
               CycleMember('mon_no_zone', 60.0, 0.1, 0.0, day, 'no zone'),
               CycleMember('tue', 60.0, 0.1, day + 1, 2 * day, 'UTC'),
               CycleMember('mon2', 61.0, 0.2, day / 2, day, 'UTC'),
               CycleMember('csv', 60.0, 0.5), CycleMember('csv2', 60.5, 0.1)]
    shared = shared_cycles(members)
    assert [sorted(m.name for m in g.members) for g in shared.groups] == [
        ['csv', 'csv2'], ['mon', 'mon2']]
    assert [g.clock for g in shared.groups] == [False, True]


def test_loops_at_one_period_that_the_clocks_keep_apart_are_listed_as_not_compared():
    day = 86400.0
    members = [CycleMember('stamped', 60.0, 0.9, 0.0, day, 'UTC'), CycleMember('plain', 61.0, 0.1),
               CycleMember('local', 60.5, 0.2, 0.0, day, 'no zone'),
               CycleMember('next_day', 59.0, 0.3, day + 10.0, 2 * day, 'UTC'),
               CycleMember('elsewhere', 200.0, 0.3)]
    shared = shared_cycles(members)
    assert not shared.groups
    why = {tuple(sorted(n.names)): n.reason for n in shared.not_compared}
    assert why[('plain', 'stamped')] == 'one has clock times, the other none'
    assert why[('local', 'stamped')] == 'clock times on different bases (UTC, no zone)' or \
        why[('local', 'stamped')] == 'clock times on different bases (no zone, UTC)'
    assert why[('next_day', 'stamped')].startswith('recorded 0 s together')
    assert not any('elsewhere' in names for names in why)
    assert shared.not_compared_json()[0]['names'] and len(why) == 6


def test_the_source_reads_sticky_and_stands_the_gap_above_every_other_member():
    close = shared_cycles([CycleMember('a', 50.0, 0.8), CycleMember('b', 50.0, 0.8 - GAP / 2)])
    g = close.groups[0]
    assert g.source is None and 'within' in g.reason
    assert 'reads sticky on its own (0.800)' in g.note_for('a')
    assert 'cannot be told' in g.note_for('a') and 'cannot be told' in g.note_for('b')
    clear = shared_cycles([CycleMember('a', 50.0, 0.8), CycleMember('b', 50.0, 0.8 - 2 * GAP),
                           CycleMember('c', 52.0, None)])
    g = clear.groups[0]
    assert g.source == 'a' and [m.name for m in g.members] == ['a', 'b', 'c']
    assert 'likely source' in g.note_for('a') and 'carried from a' in g.note_for('b')
    assert 'not compared' in g.note_for('c')
    # Two sticky valves at one period: the second is no carrier.
    both = shared_cycles([CycleMember('a', 50.0, 0.99), CycleMember('b', 50.0, 0.75)])
    assert both.groups[0].source == 'a'
    assert 'second source beside a' in both.groups[0].note_for('b')
    # A source whose own reading says "probably not sticky" is none.
    weak = shared_cycles([CycleMember('a', 50.0, FLOOR - 0.05), CycleMember('b', 50.0, 0.0)])
    assert weak.groups[0].source is None and 'no member reads sticky' in weak.groups[0].reason
    lone = shared_cycles([CycleMember('a', 50.0, 0.9), CycleMember('b', 50.0, float('nan'))])
    assert lone.groups[0].source is None and lone.groups[0].to_json()['members'][1][
        'probability'] is None


def test_a_period_that_is_no_number_of_seconds_or_a_name_twice_is_refused():
    with pytest.raises(ValueError, match='bad'):
        shared_cycles([CycleMember('bad', float('nan'))])
    with pytest.raises(ValueError, match='zero'):
        shared_cycles([CycleMember('zero', 0.0)])
    with pytest.raises(ValueError, match='distinct'):
        shared_cycles([CycleMember('a', 10.0), CycleMember('a', 10.0)])


def _report(start_time=None, period=100.0, samples=1000, window=None):
    return {'stiction': {'oscillation': {'oscillating': True, 'period_s': period}},
            'sample_time': 1.0, 'samples': samples, 'start_time': start_time,
            'signature_window': window or {'start_s': 0.0, 'end_s': samples - 1.0,
                                           'samples': samples}}


def test_a_reports_cycle_is_read_on_the_time_base_it_was_written_in():
    window = {'start_s': 100.0, 'end_s': 899.0, 'samples': 800}
    naive = cycle_of(_report('2024-06-13T21:55:00', window=window))
    aware = cycle_of(_report('2024-06-13T21:55:00+02:00'))
    t0 = datetime(2024, 6, 13, 21, 55, tzinfo=timezone.utc).timestamp()
    assert naive == {'period_s': 100.0, 'start': t0 + 100.0, 'end': t0 + 899.0,
                     'clock': 'no zone'}
    assert aware['clock'] == 'UTC' and aware['start'] == t0 - 7200.0
    assert cycle_of(_report())['clock'] is None
    # Not resolvable in the stretch read (a quarter of 300 samples is 75): no cycle.
    assert cycle_of(_report(window={'start_s': 0.0, 'end_s': 299.0, 'samples': 300})) is None
    off = _report()
    off['stiction']['oscillation']['oscillating'] = False
    assert cycle_of(off) is None


def test_the_vessel_is_a_unit_gain_lag():
    step = vessel(np.ones(400), 10.0)
    assert step[-1] == pytest.approx(1.0, abs=1e-12)
    # One time constant in, a first-order lag has come 1 - 1/e of the way.
    assert step[9] == pytest.approx(1 - np.exp(-1.0), abs=0.01)


@pytest.fixture(scope='module')
def pair():
    return coupled_pair(PAIR_SEED)


def test_the_healthy_loop_carries_the_sticky_loops_cycle(pair):
    assert pair.upstream.label and not pair.downstream.label
    assert pair.downstream.cycle_amplitude == 0.0 and pair.downstream.look_alike not in OWN_CYCLES
    # Run at the sampling its damping was placed at: the draw's own.
    assert draw_scenario(pair.downstream.seed, label=False).sample_time == \
        pair.downstream.sample_time == pair.upstream.sample_time
    ts = pair.upstream.sample_time
    up = detect_oscillation(pair.up['sp'] - pair.up['pv'], ts)
    down = detect_oscillation(pair.down['sp'] - pair.down['pv'], ts)
    assert up.oscillating and down.oscillating
    # A linear vessel and a linear loop keep the period of what passes through them.
    assert abs(np.log(down.period_s / up.period_s)) < np.log1p(TOLERANCE)
    # The same pair again: each record depends on its seed alone.
    again = coupled_pair(PAIR_SEED)
    assert np.array_equal(again.down['pv'], pair.down['pv'])


@pytest.mark.slow
def test_a_folder_audit_names_the_sticky_loop_as_the_source(pair, tmp_path, capsys):
    root = tmp_path / 'unit'
    root.mkdir()
    for name, rec in (('sticky_flow.csv', pair.up), ('tank_level.csv', pair.down)):
        n = len(rec['pv'])
        t = np.arange(n) * pair.upstream.sample_time
        # OP and PV only, as a historian exports them: the valve position is not measured.
        write_csv(root / name, {'t': t, 'sp': rec['sp'], 'pv': rec['pv'], 'op': rec['op']},
                  columns=('t', 'sp', 'pv', 'op'))
    assert main([str(root), '--jobs', '1', '--quiet', '--json', str(tmp_path / 's.json')]) == 0
    summary = json.loads((tmp_path / 's.json').read_text())
    (group,) = summary['shared_cycles']
    assert Path(group['source']).name == 'sticky_flow.csv'
    assert not group['clock_times']
    rows = {Path(r['input']).name: r for r in summary['rows']}
    assert 'likely source' in rows['sticky_flow.csv']['shared_cycle']
    assert 'carried from' in rows['tank_level.csv']['shared_cycle']
    out = capsys.readouterr().out
    assert 'cycle of ' in out and ' s in 2 loops: ' in out
    assert re.search(r'sticky_flow\.csv \(\d\.\d{3}, likely source\), \S*tank_level\.csv '
                     r'\(\d\.\d{3}\)', out), out
    assert all('cycle' in r and 'shared_cycle' in r for r in summary['rows'])
    assert summary['not_compared'] == []


def test_the_study_writes_its_page_json_and_figure(tmp_path, capsys):
    from stiction_ros.cli.shared_cycles import main as study_main
    files = [tmp_path / 'SHARED.md', tmp_path / 'shared.json', tmp_path / 'fig' / 'shared.png']
    args = ['--first-seed', str(PAIR_SEED), '--seeds', '2', '--jobs', '1', '--markdown',
            str(files[0]), '--json', str(files[1]), '--figure', str(files[2])]
    assert study_main(args) == 0
    study = json.loads(files[1].read_text())
    assert [r['seed'] for r in study['rows']] == [PAIR_SEED, PAIR_SEED + 1]
    t = study['tally']
    assert t['pairs'] == 2 and t['source_up'] + t['source_down'] + t['source_not_told'] == \
        t['shared'] <= t['both_cycle'] <= 2
    page = files[0].read_text()
    assert '](fig/shared.png)' in page and files[2].stat().st_size > 1000
    assert study_main(['--seeds', '0']) == 2
    assert 'at least 1 seed' in capsys.readouterr().err

"""
Cycles shared between recordings: grouping, the likely source, and the batch analyzer's report.

The pure rules first (periods, clock times, the probability gap), then a
sticky loop whose cycle travels through a vessel into a healthy loop
(``sim.coupled_loops``): read together by ``stiction-analyze`` on a folder,
the sticky loop must be named as the source and the healthy one as carrying it.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from stiction_ros.analysis.oscillation import detect_oscillation
from stiction_ros.analysis.plantwide import CycleMember, GAP, shared_cycles, TOLERANCE
from stiction_ros.cli.analyze import main
from stiction_ros.sim.closed_loop import write_csv
from stiction_ros.sim.coupled_loops import coupled_pair, vessel

# A pair whose two loops both cycle (the corpus's sticky draws mostly do not).
PAIR_SEED = 6_100_041


def test_loops_cycling_at_one_period_form_one_group_and_others_stay_out():
    members = [CycleMember('a', 100.0, 0.9), CycleMember('b', 100.0 * (1 + TOLERANCE * 0.9), 0.3),
               CycleMember('c', 100.0 * (1 + TOLERANCE * 3), 0.95), CycleMember('d', 400.0, 0.1)]
    shared = shared_cycles(members)
    assert [[m.name for m in g.members] for g in shared.groups] == [['a', 'b']]
    assert shared.group_of('c') is None and shared.group_of('d') is None
    assert shared.groups[0].source == 'a' and not shared.groups[0].clock


def test_records_of_different_hours_share_no_cycle_and_clockless_ones_only_with_each_other():
    day = 86400.0
    members = [CycleMember('mon', 60.0, 0.9, 0.0, day),
               CycleMember('tue', 60.0, 0.1, day + 1, 2 * day),
               CycleMember('mon2', 61.0, 0.2, day / 2, day), CycleMember('csv', 60.0, 0.5)]
    shared = shared_cycles(members)
    assert [sorted(m.name for m in g.members) for g in shared.groups] == [['mon', 'mon2']]
    assert shared.groups[0].clock


def test_the_source_must_stand_the_gap_above_every_other_member():
    close = shared_cycles([CycleMember('a', 50.0, 0.8), CycleMember('b', 50.0, 0.8 - GAP / 2)])
    g = close.groups[0]
    assert g.source is None and 'within' in g.reason
    assert 'cannot be told' in g.note_for('a')
    clear = shared_cycles([CycleMember('a', 50.0, 0.8), CycleMember('b', 50.0, 0.8 - 2 * GAP),
                           CycleMember('c', 52.0, None)])
    g = clear.groups[0]
    assert g.source == 'a' and [m.name for m in g.members] == ['a', 'b', 'c']
    assert 'likely source' in g.note_for('a') and 'carried from a' in g.note_for('b')
    lone = shared_cycles([CycleMember('a', 50.0, 0.9), CycleMember('b', 50.0, None)])
    assert lone.groups[0].source is None


def test_a_period_that_is_no_number_of_seconds_is_refused():
    with pytest.raises(ValueError, match='bad'):
        shared_cycles([CycleMember('bad', float('nan'))])
    with pytest.raises(ValueError, match='zero'):
        shared_cycles([CycleMember('zero', 0.0)])


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
    assert pair.downstream.cycle_amplitude == 0.0 and pair.downstream.look_alike != 'load_cycle'
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
    assert 'shared cycle of' in out and 'sticky_flow.csv (' in out and 'likely source)' in out


def test_the_study_writes_its_page_json_and_figure(tmp_path, capsys):
    from stiction_ros.cli.shared_cycles import main as study_main
    files = [tmp_path / 'SHARED.md', tmp_path / 'shared.json', tmp_path / 'fig' / 'shared.png']
    args = ['--first-seed', str(PAIR_SEED), '--seeds', '2', '--jobs', '1', '--markdown',
            str(files[0]), '--json', str(files[1]), '--figure', str(files[2])]
    assert study_main(args) == 0
    study = json.loads(files[1].read_text())
    assert [r['seed'] for r in study['rows']] == [PAIR_SEED, PAIR_SEED + 1]
    assert study['rows'][0]['source'] == 'up'       # the pair of the folder audit above
    assert study['tally']['source_up'] >= 1
    page = files[0].read_text()
    assert '](fig/shared.png)' in page and files[2].stat().st_size > 1000
    assert study_main(['--seeds', '0']) == 2
    assert 'at least 1 seed' in capsys.readouterr().err

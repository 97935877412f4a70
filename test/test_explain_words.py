"""What --explain's terminal lines say when the valve has no stick-slip: sizes and notes."""

import json

import numpy as np
import pytest

from stiction_ros.cli.analyze import main
from stiction_ros.models import Kano
from stiction_ros.sim.closed_loop import write_csv
from stiction_ros.sim.concealed_cases import concealed_case


@pytest.fixture(scope='module')
def loop():
    d, _ = concealed_case('none', 3, duration=3000.0)
    return d


def _run(d, mv, tmp_path, capsys):
    path = tmp_path / 'loop.csv'
    write_csv(path, {'t': d['t'], 'sp': d['sp'], 'pv': d['pv'], 'op': d['op'], 'mv': mv})
    assert main([str(path), '--explain', '--quiet', '--json', str(tmp_path / 'r.json')]) == 0
    out = ' '.join(capsys.readouterr().out.split())
    return out, json.loads((tmp_path / 'r.json').read_text())


def test_a_calibrated_healthy_valve_gets_no_friction_size(loop, tmp_path, capsys):
    noise = 0.1 * np.random.default_rng(2).standard_normal(len(loop['op']))
    out, report = _run(loop, 2.0 + 0.95 * loop['op'] + noise, tmp_path, capsys)
    assert report['mismatch']['friction'] is False
    assert report['mismatch']['effect'] == 'positioner_calibration'
    assert ('explains MV without friction: this is what a friction model makes of what '
            '--explain found, not a friction size') in out


def test_play_without_a_slip_is_said_to_beat_the_valve_without_friction(loop, tmp_path, capsys):
    valve = Kano(S=3.0, J=0.0)
    valve.reset(y0=float(loop['op'][0]))
    noise = 0.1 * np.random.default_rng(4).standard_normal(len(loop['op']))
    out, report = _run(loop, valve.simulate(loop['op']) + noise, tmp_path, capsys)
    m = report['mismatch']
    assert m['friction'] is False and m['friction_kind'] == 'backlash'
    assert m['effect'] == 'backlash' and 'cannot tell apart' in m['explanation']
    assert 'finds play without a slip jump, not stick-slip' in out
    assert 'no friction beats the best valve without friction' not in out
    # The headline reads the same position and says the same: play, sized, not stick-slip;
    # so no note has to reconcile the two.
    st = report['stiction']
    assert st['detected'] is False and st['score'] == 0.0 and 'cannot_tell' not in st
    assert st['reason'].startswith('play of ') and 'without a slip jump' in st['reason']
    assert abs(st['apparent_S'] - 3.0) < 0.3
    assert 'play without a slip jump (backlash or a pure deadband) beats' not in out


def test_the_notes_reconcile_the_verdict_and_weigh_a_worse_held_out_fit(loop, tmp_path, capsys):
    from stiction_ros.app.report_text import _mismatch_lines
    noise = 0.1 * np.random.default_rng(2).standard_normal(len(loop['op']))
    _, report = _run(loop, 2.0 + 0.95 * loop['op'] + noise, tmp_path, capsys)
    m, b = report['mismatch'], report['baseline']
    # The headline says no stiction, or cannot tell, where --explain claims it: said.
    report['stiction']['detected'], m['friction'] = False, True
    assert 'claims stiction from the valve position itself' in _mismatch_lines(report)
    report['stiction']['detected'] = None
    assert ('cannot tell from valve models without dead time, lead or calibration'
            in _mismatch_lines(report))
    # The headline says stiction where --explain finds play only: said too.
    report['stiction']['detected'], m['friction'], m['friction_kind'] = True, False, 'backlash'
    assert 'play without a slip jump (backlash or a pure deadband) beats' in _mismatch_lines(
        report)
    m['friction_kind'] = 'none'
    # Worse held out by a fraction of a per cent is noise; by a fifth, a warning.
    m['mse_holdout'] = b['mse_holdout'] * 1.004
    assert 'worse held out' not in _mismatch_lines(report)
    m['mse_holdout'] = b['mse_holdout'] * 1.2
    assert 'do not improve the fit on data they were not fitted to' in _mismatch_lines(report)
    # A plain model that fits to the bit, an explained one off in the tenth digit: no worse.
    b['mse_holdout'], m['mse_holdout'] = 0.0, 5e-9
    assert 'worse held out' not in _mismatch_lines(report)
    m['mse_holdout'] = 1e-6
    assert 'worse held out' in _mismatch_lines(report)

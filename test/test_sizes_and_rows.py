"""
What a report says about size and about records it could not judge (a fresh user's trial).

Each case here was a wrong or self-contradicting report: S and J from MV at a
sampling that misses the valve's turning points without a word, a size from a
PV-OP map the same report calls no ellipse, a file without PV called "too
short", batch rows of unjudged records scored 0 (sorted with the healthy),
and "1 runs, the longest 1 rows".
"""

import subprocess
import sys

import numpy as np
import pytest

from stiction_ros.analysis.detection.resolve import cycle_judgeable
from stiction_ros.analysis.detection.stale import stale_rows
from stiction_ros.analysis.signatures.ellipse import MAX_RESIDUAL
from stiction_ros.analysis.signatures.result import Signature
from stiction_ros.analysis.verdict import combine
from stiction_ros.app.analyze import analyze_file, AnalyzeOptions
from stiction_ros.app.batch import analyze_one
from stiction_ros.app.report_text import size_text
from stiction_ros.resources import config_file
from stiction_ros.sim.closed_loop import simulate_loop, write_csv
from stiction_ros.sim.loop_config import load_loop

S_TRUE, J_TRUE = 5.0, 2.0


@pytest.fixture(scope='module')
def sticky_loop():
    # Table 2.1's loop with a 5 % band: a limit cycle of about 140 s at 1 s.
    cfg = load_loop(config_file('concentration_loop.yaml'), overrides={
        'valve': {'model': 'kano', 'S': S_TRUE, 'J': J_TRUE},
        'noise': {'pv_std': 0.02, 'mv_std': 0.02, 'seed': 5}, 'duration': 20000.0})
    return simulate_loop(cfg)


def _every(data, k, path):
    rows = {c: np.asarray(v)[::k] for c, v in data.items() if np.ndim(v) == 1}
    write_csv(path, rows)
    return analyze_file(AnalyzeOptions(input=str(path))).report


def test_mv_sizes_from_a_cycle_of_few_samples_say_they_read_low(sticky_loop, tmp_path):
    fine = _every(sticky_loop, 5, tmp_path / 'every5.csv')
    coarse = _every(sticky_loop, 25, tmp_path / 'every25.csv')
    s_fine = min(fine['fits'], key=lambda f: f['mse'])['S']
    s_coarse = min(coarse['fits'], key=lambda f: f['mse'])['S']
    # The physics the caution states: between samples the valve's turning
    # points are lost, so the band shrinks; the finer record keeps it.
    assert abs(s_fine - S_TRUE) < 0.1 * S_TRUE
    assert s_coarse < s_fine
    assert 'size_caution' not in fine['stiction']
    caution = coarse['stiction']['size_caution']
    assert 'read low' in caution and '25 s' in caution
    assert 'caution: ' + caution in size_text(coarse)


def test_no_size_from_a_pv_op_map_that_is_no_ellipse():
    def sigs(residual):
        ell = Signature('ellipse', 3.2, 1.0, None, 'a map', 'ref',
                        {'fit_residual': residual})
        return {'ellipse': ell}
    assert combine(None, sigs(MAX_RESIDUAL / 2), [])['apparent_S'] == 3.2
    assert combine(None, sigs(MAX_RESIDUAL * 1.6), [])['apparent_S'] is None


def test_a_file_without_pv_or_mv_is_refused_by_name(tmp_path):
    path = tmp_path / 'no_pv.csv'
    t = np.arange(400.0)
    np.savetxt(path, np.c_[t, 50 + np.sin(t / 9), np.full(400, 70.0)], delimiter=',',
               header='time,op,sp', comments='')
    run = subprocess.run([sys.executable, '-m', 'stiction_ros.cli.analyze', str(path)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    assert 'no process value (pv) and no valve position (mv), only op, sp' in run.stderr
    assert '--columns pv=' in run.stderr and 'Traceback' not in run.stderr


def test_batch_rows_of_records_not_judged_have_no_score(tmp_path):
    path = tmp_path / 'short.csv'
    rng = np.random.default_rng(3)
    t = np.arange(150.0)
    op = 50 + rng.normal(0, 1, t.size).cumsum() * 0.1
    np.savetxt(path, np.c_[t, op, op * 0.8 + rng.normal(0, 0.1, t.size), np.full(t.size, 40.0)],
               delimiter=',', header='time,op,pv,sp', comments='')
    row = analyze_one(path, AnalyzeOptions(input=str(path)))
    assert row['ok'] and row['answer'] == 'cannot tell' and row['why_not'] == 'too short'
    assert row['score'] is None and row['probability'] is None


def test_held_rows_are_counted_in_words_that_fit_the_count():
    rng = np.random.default_rng(0)
    op = 50 + 0.3 * rng.normal(size=400).cumsum()
    pv = op + rng.normal(size=400) * 0.1

    def told(rows):
        o, p = op.copy(), pv.copy()
        for k in rows:
            o[k], p[k] = o[k - 1], p[k - 1]
        held = stale_rows(o, p)
        assert held.count == len(rows)
        return held.describe(10.0)
    one = told([50])
    assert one.startswith('1 of 400 rows repeats the previous row') and '(10 s)' in one
    assert '(3 single rows of 10 s each)' in told([50, 150, 250])
    assert '(one run of 3 rows = 30 s)' in told([50, 51, 52])
    assert '(2 runs, the longest 3 rows = 30 s)' in told([50, 51, 52, 200])


def test_an_under_sampled_cycle_is_told_the_sample_time_that_resolves_it():
    judge = cycle_judgeable(True, 144.0, 18.0)
    assert judge.code == 'under_sampled'
    # At least 10 samples a cycle: 14.4 s, what the rule itself asks.
    assert 'at least 10 samples a cycle: record at 14.4 s or faster' in judge.reason


def test_evidence_words_say_what_the_figures_say():
    from types import SimpleNamespace
    from stiction_ros.analysis.detection.detect import evidence_lines, leaned_line
    from stiction_ros.analysis.detection.stuck import StuckResult
    from stiction_ros.analysis.verdict import from_fits
    st = StuckResult(stuck=[(10, 60, 2.0)], ramp_r2=0.02, log_offset=np.log10(189.0))
    yam = Signature('yamashita', 0.9, 0.5, True, '28 of 29 informative samples', 'ref', {})
    ev = {'stuck': st, 'oscillation': SimpleNamespace(oscillating=False), 'period_problem': '',
          'signatures': {'yamashita': yam}}
    lines = evidence_lines(ev, 10.0)
    # An R^2 of 0.02 is no ramp, whatever the held error says.
    assert any('OP moved but not in a straight ramp (R^2 0.02 of a line)' in x for x in lines)
    assert 'yamashita on its own: stiction (28 of 29 informative samples)' in lines
    leaned = {'start': -0.27, 'score': 3.78, 'contributions': [
        {'feature': 'cnn_logit', 'value': 2.35, 'log_odds': 0.87}]}
    assert 'from -0.27, before any figure is read, to +3.78)' in leaned_line(leaned)
    # Named in words beside the name, and the score tied to the probability shown.
    line = leaned_line(leaned, 0.9512)
    assert "small network's reading of the trend (cnn_logit) = 2.35 (+0.87)" in line
    assert 'to +3.78, which the calibration map reads as a probability of 0.95)' in line
    fit = {'model': 'kano', 'S': 2.98, 'J': 0.0, 'mse': 1.3, 'S_interval': [2.74, 3.96],
           'improvement': 0.53}
    assert '(95 % range 2.74-3.96)' in from_fits([fit]).reason


def test_a_record_judged_on_part_of_its_valid_samples_says_so():
    from stiction_ros.app.report_text import judged_text
    report = {'valid_samples': 677, 'signature_window': {
        'start_s': 2600.0, 'end_s': 7490.0, 'samples': 490, 'held': 0}}
    assert judged_text(report) == ('OP and PV on their longest valid stretch only, 490 of 677 '
                                   'valid samples (2600-7490 s); gaps split the rest')
    report['signature_window']['samples'] = 660
    assert judged_text(report) == ''


def test_a_workbook_in_a_folder_is_listed_as_skipped_with_the_fix(tmp_path):
    import zipfile
    from stiction_ros.app.batch import expand
    with zipfile.ZipFile(tmp_path / 'loops.xlsx', 'w') as z:
        z.writestr('xl/workbook.xml', '<workbook/>')
    (tmp_path / '~$loops.xlsx').write_bytes(b'\0' * 165)   # Excel's lock file
    (tmp_path / 'readme.md').write_text('not a recording')
    paths = expand(str(tmp_path))
    assert [p.rsplit('/', 1)[-1] for p in paths] == ['loops.xlsx']
    row = analyze_one(paths[0], AnalyzeOptions(input=paths[0]))
    assert row['skipped'] and not row['ok'] and 'save its sheet as CSV' in row['error']
    # A folder of workbooks alone analysed nothing: that is no audit.
    run = subprocess.run([sys.executable, '-m', 'stiction_ros.cli.analyze', str(tmp_path)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2
    assert run.stdout.splitlines()[-1].endswith(': 1 workbook skipped')


def test_without_pv_the_cycle_is_read_from_op(sticky_loop, tmp_path):
    # OP cycles with the loop: the caution needs no PV.
    rows = {c: np.asarray(v)[::25] for c, v in sticky_loop.items()
            if np.ndim(v) == 1 and c != 'pv'}
    write_csv(tmp_path / 'no_pv.csv', rows, columns=('t', 'op', 'mv', 'sp'))
    rep = analyze_file(AnalyzeOptions(input=str(tmp_path / 'no_pv.csv'))).report
    assert 'read low' in rep['stiction']['size_caution']


def test_a_given_size_gets_no_caution_and_no_invented_range(sticky_loop, tmp_path):
    rows = {c: np.asarray(v)[::25] for c, v in sticky_loop.items() if np.ndim(v) == 1}
    write_csv(tmp_path / 'given.csv', rows)
    rep = analyze_file(AnalyzeOptions(input=str(tmp_path / 'given.csv'), S=S_TRUE,
                                      J=J_TRUE)).report
    assert 'size_caution' not in rep['stiction']
    assert '95 % range' not in rep['stiction']['reason']


def test_a_band_is_stiction_only_with_a_slip_jump_its_range_keeps_off_zero():
    # The chapter's pure deadband (J = 0) is play; a jump whose range reaches zero may be.
    fit = {'model': 'kano', 'S': 3.0, 'J': 0.0, 'mse': 0.01, 'improvement': 0.9,
           'S_interval': [2.9, 3.1], 'J_interval': [0.0, 0.01]}
    play = combine(None, {}, [fit])
    assert (play['detected'], play['answer'], play['score']) == (False, 'no stiction', 0.0)
    assert play['apparent_S'] == play['play'] == 3.0 and 'cannot_tell' not in play
    # Read from an MV that never moved, the band is neither play nor stiction.
    from stiction_ros.analysis.measures.still import Still
    from stiction_ros.analysis.verdict import refuse_still
    refuse_still(play, Still(mv_spread=0.05, op_spread=2.0, noise=0.05), None)
    assert play['cannot_tell'] == 'mv_still' and 'play' not in play
    maybe = combine(None, {}, [{**fit, 'J': 0.2, 'J_interval': [0.02, 0.4]}])
    assert maybe['detected'] is None and maybe['cannot_tell'] == 'slip_unresolved'
    assert 'play' not in maybe
    assert 'cannot be told from none' in maybe['reason']
    sticks = combine(None, {}, [{**fit, 'J': 0.2, 'J_interval': [0.06, 0.4]}])
    assert sticks['detected'] is True and sticks['score'] == 0.9
    # Without the band no jump matters: an ideal valve's fit is no stiction, its score kept.
    flat = combine(None, {}, [{**fit, 'S_interval': [0.0, 0.3], 'improvement': 0.1}])
    assert flat['detected'] is False and flat['score'] == 0.1


def test_stick_slip_under_a_noisy_reading_is_judged_on_what_lies_above_the_noise(tmp_path):
    # Choudhury S 3 %, J 2 %, MV read with 2 % of noise: the fit finds the valve, yet
    # removes only about a fifth of an ideal valve's MSE, most of which is the noise.
    cfg = load_loop(config_file('concentration_loop.yaml'), 'deadband', overrides={
        'valve': {'model': 'choudhury', 'S': 3.0, 'J': 2.0},
        'noise': {'pv_std': 0.02, 'mv_std': 2.0, 'seed': 1000}})
    d = simulate_loop(cfg)
    path = tmp_path / 'noisy.csv'
    write_csv(path, {k: d[k] for k in ('t', 'sp', 'op', 'mv', 'pv')})
    rep = analyze_file(AnalyzeOptions(input=str(path))).report
    st, best = rep['stiction'], min(rep['fits'], key=lambda f: f['mse'])
    assert best['improvement'] < 0.5 and abs(best['J'] - 2.0) < 0.3
    assert abs(best['mv_noise_var'] - 4.0) < 0.8
    # Of what the ideal valve leaves above the noise, the fit removes (nearly) all.
    assert 'of what it leaves above the noise' in st['reason']
    assert st['detected'] is not False and 'play' not in st
    plain = {k: v for k, v in best.items() if k not in ('frictionless', 'calibrated_mse',
                                                        'behind')}
    assert combine(None, {}, [plain])['detected'] is True
    # Here a valve without friction (dead time, lag, calibration) comes within the noise
    # estimate's error of the noise: the two tie.
    assert best['frictionless']['mse'] < 1.2 * best['mv_noise_var']
    assert st['detected'] is None and st['cannot_tell'] == 'frictionless_fits'
    # Read as noisier, so that the excess above the noise is within its error: the fit
    # removes a fifth of a misfit that is mostly noise, and cannot tell.
    hidden = {**plain, 'mv_noise_var': 0.98 * best['ideal_valve_mse']}
    told = combine(None, {}, [hidden])
    assert told['detected'] is None and told['cannot_tell'] == 'noisy_mv'
    # The same fit with a reading that leaves misfit beyond its noise: no stiction.
    rough = {**plain, 'mv_noise_var': best['mse'] / 2}
    assert combine(None, {}, [rough])['detected'] is False


def test_without_stiction_the_caution_says_a_band_may_be_missed():
    from types import SimpleNamespace
    from stiction_ros.analysis.caution import sampling_caution
    rng = np.random.default_rng(1)
    op = 50 + rng.normal(0, 1, 600).cumsum() * 0.05
    held = {'op': op, 'pv': 0.8 * op + rng.normal(0, 0.05, 600), 'sp': np.full(600, 40.0)}
    ringing = SimpleNamespace(oscillating=True, period_s=32.0)
    healthy = sampling_caution(held, ringing, 5.0, sticks=False)
    assert 'a small band may have been missed' in healthy and 'read low' not in healthy
    assert 'read low' in sampling_caution(held, ringing, 5.0, sticks=True)
    assert sampling_caution(held, SimpleNamespace(oscillating=True, period_s=64.0), 5.0,
                            sticks=True) == ''
    # Slammed between its limits every sample: still a cycle the sampling cannot show,
    # though the detector refuses it as cycling against the limits first.
    bang = np.where(np.arange(600) % 2 == 0, 100.0, 0.0)
    flip = {'op': bang, 'pv': 0.3 * bang + rng.normal(0, 0.05, 600), 'sp': np.full(600, 40.0)}
    assert 'alternate from sample to sample' in sampling_caution(flip, None, 5.0, sticks=True)


def test_the_old_rule_does_not_size_or_vote_on_a_map_that_is_no_ellipse():
    from stiction_ros.analysis.signatures.bicoherence import hos_with_pv_op
    nonlinear = Signature('bicoherence', 0.5, 0.1, None, 'nonlinear', 'ref',
                          {'nonlinear': True, 'ngi': 0.2, 'nli': 0.5})

    def vote(residual):
        ell = Signature('ellipse', 3.2, 1.0, None, 'a map', 'ref', {'fit_residual': residual})
        return hos_with_pv_op(nonlinear, ell)
    assert vote(MAX_RESIDUAL / 2).stiction is True and vote(MAX_RESIDUAL / 2).value == 3.2
    rejected = vote(MAX_RESIDUAL * 1.6)
    assert rejected.stiction is None and rejected.value is None


def test_the_signature_table_says_it_read_the_held_rows_the_detector_did_not():
    from stiction_ros.viz.report_html import _signatures
    assert not any('held row' in part for part in _signatures({}, 0))
    note = ' '.join(_signatures({}, 314))
    assert 'the 314 held rows included' in note and 'fresh rows only' in note
    assert 'the held row included' in ' '.join(_signatures({}, 1))


def test_rows_a_historian_interpolated_are_named_and_read_as_they_are():
    from stiction_ros.analysis.detection import detect
    from stiction_ros.analysis.detection.interpolated import interpolated_rows
    from stiction_ros.sim.corpus import draw_scenario, simulate
    rec = simulate(draw_scenario(7, label=False))
    op, pv, sp = (np.asarray(rec[k], float) for k in ('op', 'pv', 'sp'))
    # A noisy loop lands on no midpoint, OP and PV together.
    assert not interpolated_rows(op, pv).any()
    # A historian storing every other sample fills the grid by straight lines.
    lerp_op, lerp_pv = op.copy(), pv.copy()
    inner = np.arange(1, len(op) - 1, 2)
    lerp_op[inner] = 0.5 * (op[inner - 1] + op[inner + 1])
    lerp_pv[inner] = 0.5 * (pv[inner - 1] + pv[inner + 1])
    found = interpolated_rows(lerp_op, lerp_pv)
    assert np.array_equal(np.flatnonzero(found), inner)
    d = detect(lerp_op, lerp_pv, sp, float(draw_scenario(7, label=False).sample_time))
    assert d.judge.ok and d.details['interpolated_rows'] == len(inner)
    # Half the record: said right after what the detector leaned on.
    assert d.evidence[0].startswith('the learned detector leaned most on')
    assert d.evidence[1].startswith(f'{len(inner)} of {len(op)} rows lie exactly midway')


def test_slip_times_count_from_the_records_start_after_a_gap(tmp_path):
    # A gap early on: the signatures read the stretch after it, and every slip they
    # name is given on the record's clock, as the detector's evidence and figures are.
    from data_paths import plant_loops_dir
    from stiction_ros.analysis.readers import load_record
    loops = plant_loops_dir()
    if loops is None:
        pytest.skip('the shared plant loops are not beside this checkout')
    # A sticky valve whose slip-event signature finds slips throughout (7 on the whole).
    (path,) = (loops / 'stiction').glob('*FIC46005_0902*')
    rec = load_record(str(path))
    cols = ('t', 'sp', 'pv', 'op')
    data = np.column_stack([rec.t - rec.t[0]] + [rec.signals[c] for c in cols[1:]])
    data[100:130, 2] = np.nan
    np.savetxt(tmp_path / 'gap.csv', data, delimiter=',', header=','.join(cols), comments='')
    report = analyze_file(AnalyzeOptions(input=str(tmp_path / 'gap.csv'))).report
    win = report['signature_window']
    assert win['start_s'] >= 130 * report['sample_time']
    sig = report['stiction']['signatures']['slip_events']
    events = sig['details']['events']
    assert events and all(win['start_s'] <= e['t'] <= win['end_s'] for e in events)
    assert f"at t = {events[0]['t']:.0f} s" in sig['reason']

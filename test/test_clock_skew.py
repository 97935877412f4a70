"""The clock-skew check: the controller's own law tells when PV and OP were stamped apart."""

import numpy as np
import pytest

from stiction_ros.analysis.detection.timing import alignment, law_profile, law_r2, MARGIN, \
    MAX_SHIFT, MIN_LAW_R2
from stiction_ros.study.distortions import every, shift_pv, Trend


def _loop(seed):
    from stiction_ros.sim.corpus import draw_scenario, simulate
    sc = draw_scenario(seed)
    rec = simulate(sc)
    return sc, Trend(rec['op'], rec['pv'], rec['sp'], sc.sample_time)


@pytest.mark.parametrize('seed', [2, 26, 41])
def test_a_simulated_loop_fits_its_pi_law_exactly_at_no_shift_and_is_read_as_given(seed):
    _, t = _loop(seed)
    a = alignment(t.op, t.pv, t.sp)
    # The simulated controller is that law: only rounding is left.
    assert a.r2_as_given > 1 - 1e-9 and a.shift == 0 and a.best == 0
    op, pv, sp, rows = a.apply(t.op, t.pv, t.sp)
    assert op is t.op and pv is t.pv and rows.tolist() == list(range(len(t.op)))


@pytest.mark.parametrize('k', [1, -1, 3, -3, MAX_SHIFT, -MAX_SHIFT])
def test_a_skewed_record_is_realigned_to_the_rows_the_controller_paired(k):
    _, t = _loop(26)
    skewed = shift_pv(t, k)
    a = alignment(skewed.op, skewed.pv, skewed.sp)
    assert a.shift == k and a.r2_best > 1 - 1e-9 and a.r2_as_given < a.r2_best - MARGIN
    op, pv, sp, rows = a.apply(skewed.op, skewed.pv, skewed.sp)
    # Each OP is paired again with the PV and SP of its own scan: original rows |k|..n-|k|.
    n, m = len(t.op), abs(k)
    np.testing.assert_array_equal(op, t.op[m:n - m])
    np.testing.assert_array_equal(pv, t.pv[m:n - m])
    np.testing.assert_array_equal(sp, t.sp[m:n - m])
    # Rows name the OP rows of the record as given.
    np.testing.assert_array_equal(skewed.op[rows], op)


def test_the_laws_profile_peaks_at_the_skew_and_is_the_fit_at_each_shift():
    _, t = _loop(41)
    skewed = shift_pv(t, 2)
    prof = law_profile(skewed.op, skewed.pv, skewed.sp)
    shifts = np.arange(-MAX_SHIFT, MAX_SHIFT + 1)
    assert prof.shape == shifts.shape and shifts[int(np.nanargmax(prof))] == 2
    for k in (-MAX_SHIFT, 0, 2, MAX_SHIFT):
        assert prof[k + MAX_SHIFT] == law_r2(skewed.op, skewed.pv, skewed.sp, k)


def test_a_skew_beyond_the_rows_looked_for_is_not_guessed_at():
    _, t = _loop(26)
    skewed = shift_pv(t, MAX_SHIFT + 3)
    assert alignment(skewed.op, skewed.pv, skewed.sp).shift == 0


def test_an_op_that_follows_no_law_of_pv_is_read_as_given():
    rng = np.random.default_rng(5)
    pv = np.cumsum(rng.normal(size=600))
    op = 50 + np.cumsum(rng.normal(size=600)) * 0.1
    a = alignment(op, pv, None)
    assert a.checked and a.r2_best < MIN_LAW_R2 and a.shift == 0
    assert a.describe(10.0) == ''


def test_too_few_rows_inside_ops_range_is_no_check_at_all():
    op = np.r_[np.zeros(300), np.full(300, 100.0)]      # saturated throughout
    pv = np.linspace(0.0, 1.0, 600)
    assert np.isnan(law_r2(op, pv, None, 0))
    a = alignment(op, pv, None)
    assert not a.checked and a.shift == 0
    assert a.to_json() == {'shift_rows': 0, 'law_r2_as_given': None, 'law_r2_best': None,
                           'best_shift_rows': 0, 'lag_rows': 0.0, 'lag_found_rows': 0.0,
                           'best_lag_rows': 0.0,
                           'law_r2_lag': None, 'not_realigned_because': None}


def test_a_coarser_export_still_shows_a_one_row_skew():
    # On every second row the law holds only roughly (R² below 1), the case the
    # thresholds were chosen for.
    _, t = _loop(26)
    coarse = every(t, 2)
    skewed = shift_pv(coarse, 1)
    a = alignment(skewed.op, skewed.pv, skewed.sp)
    assert a.shift == 1 and a.r2_best < 1 - 1e-6


def test_the_detector_reads_a_skewed_record_as_the_record_its_controller_saw():
    from stiction_ros.analysis.detection.detect import detect
    sc, t = _loop(26)
    k = 3
    skewed = shift_pv(t, k)
    d = detect(skewed.op, skewed.pv, skewed.sp, t.sample_time, sc.integrating)
    n = len(t.op)
    same = detect(t.op[k:n - k], t.pv[k:n - k], t.sp[k:n - k], t.sample_time, sc.integrating)
    assert d.probability == same.probability and d.answer == same.answer
    assert d.details['timing']['shift_rows'] == k
    assert any('3 rows (30 s) late against OP' in line for line in d.evidence)
    as_given = detect(skewed.op, skewed.pv, skewed.sp, t.sample_time, sc.integrating,
                      realign=False)
    assert as_given.details['timing']['shift_rows'] == 0
    assert as_given.details['timing']['best_shift_rows'] == k
    assert not any('late against OP' in line for line in as_given.evidence)


def test_empty_short_or_gappy_records_are_no_check_and_no_crash():
    assert np.isnan(law_r2(np.empty(0), np.empty(0), None, 0))
    assert not alignment(np.empty(0), np.empty(0), None).checked
    _, t = _loop(26)
    pv = shift_pv(t, 2).pv.copy()
    op = shift_pv(t, 2).op
    pv[100:110] = np.nan                               # a gap: its rows leave the fit
    a = alignment(op, pv, None)
    assert a.shift == 2 and a.r2_best > 0.99


def test_a_skew_in_a_record_with_held_rows_is_named_but_not_made():
    # Once held rows are dropped, rows are no longer evenly spaced in time.
    from stiction_ros.analysis.detection.detect import detect
    sc, t = _loop(26)
    s = shift_pv(t, 2)
    op, pv = s.op.copy(), s.pv.copy()
    for i in range(50, 700, 50):                       # a historian's repeats in both tags
        op[i], pv[i] = op[i - 1], pv[i - 1]
    d = detect(op, pv, s.sp, t.sample_time, sc.integrating)
    timing = d.details['timing']
    assert timing['shift_rows'] == 0 and timing['best_shift_rows'] == 2
    assert 'repeated in OP and PV' in timing['not_realigned_because']
    assert any('PV looks 2 rows (20 s) late against OP' in line and 'read as exported' in line
               for line in d.evidence)


def test_the_stiction_size_reads_the_record_the_verdict_read():
    from stiction_ros.analysis.detection.detect import detect
    from stiction_ros.analysis.pipeline import realigned
    sc, t = _loop(26)
    s = shift_pv(t, 3)
    held = {'op': s.op, 'pv': s.pv, 'sp': s.sp}
    d = detect(s.op, s.pv, s.sp, t.sample_time, sc.integrating)
    x = realigned(held, d)
    n = len(t.op)
    np.testing.assert_array_equal(x['pv'], t.pv[3:n - 3])
    np.testing.assert_array_equal(x['op'], t.op[3:n - 3])
    as_given = detect(s.op, s.pv, s.sp, t.sample_time, sc.integrating, realign=False)
    assert realigned(held, as_given) is held


@pytest.mark.slow
def test_the_shipped_thresholds_are_the_ones_the_training_records_choose():
    from stiction_ros.study.skew import choose, MAX_FALSE
    choice = choose(range(0, 1500), jobs=2)
    assert choice.chosen == (MIN_LAW_R2, MARGIN)
    row = next(r for r in choice.rows if (r['min_r2'], r['margin']) == choice.chosen)
    assert all(row[f'every_{k}']['false'] <= MAX_FALSE for k in (2, 3))


def _record(trend):
    from stiction_ros.analysis.record import Record
    n = len(trend.op)
    return Record(t=np.arange(n) * trend.sample_time, sample_time=trend.sample_time,
                  signals={'op': trend.op, 'pv': trend.pv, 'sp': trend.sp},
                  valid=np.ones(n, bool), source={'path': 'skewed.csv', 'format': 'csv'})


@pytest.mark.parametrize('k', [3, -2])
def test_the_signature_vote_reads_the_record_the_verdict_read(k):
    # Before, the vote read PV as exported and so paired each OP with another scan's PV.
    from stiction_ros.analysis.pipeline import analyze, Options
    from stiction_ros.analysis.signatures.all import compute_signatures
    from stiction_ros.analysis.signature_vote import from_signatures
    sc, t = _loop(48)                  # a Choudhury valve, S 1.8 % J 1.9 %, in a limit cycle
    n, m = len(t.op), abs(k)
    skewed = shift_pv(t, k)
    res = analyze(_record(skewed), Options(hammerstein=False)).report
    assert res['stiction']['detector']['timing']['shift_rows'] == k
    win = res['signature_window']
    assert win['pv_shift_rows'] == k and win['samples'] == n - 2 * m   # shift_pv drops m
    # Times are OP's: PV early leaves OP's first rows without a PV of their own scan.
    assert win['start_s'] == (m * t.sample_time if k < 0 else 0.0)
    osc, sigs = compute_signatures(t.op[m:n - m], t.pv[m:n - m], t.sp[m:n - m],
                                   t.sample_time, integrating=sc.integrating)
    got = res['stiction']['signatures']
    assert got.keys() == sigs.keys()
    for name, sig in sigs.items():
        assert got[name] == sig.to_json(), name
    assert res['stiction']['signature_vote']['score'] == round(
        float(from_signatures(osc, sigs)[1]), 4)
    assert any('PV read' in note and 'paired again' in note for note in res['notes'])
    # What that changes: the skew hides the relay-like cross-correlation from Horch's test
    # and narrows the PV-OP ellipse well below the valve's band.
    _, as_given = compute_signatures(skewed.op, skewed.pv, skewed.sp, t.sample_time,
                                     integrating=sc.integrating)
    assert got['horch']['stiction'] is True and as_given['horch'].stiction is False
    assert abs(got['ellipse']['value'] - sc.S) < 0.1 * sc.S
    assert as_given['ellipse'].value < 0.6 * sc.S

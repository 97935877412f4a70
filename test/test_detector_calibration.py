"""The detector's probability: its calibration map, how it is printed, the cached logits."""

import numpy as np
import pytest

from stiction_ros.analysis.detection import probability_text, stack
from stiction_ros.analysis.detection.train import fit_calibration


def _scores(n_pos, n_neg, seed=0):
    rng = np.random.default_rng(seed)
    raw = np.r_[rng.normal(1.5, 1.0, n_pos), rng.normal(-1.5, 1.0, n_neg)]
    return raw, np.r_[np.ones(n_pos, bool), np.zeros(n_neg, bool)]


def test_no_calibration_step_claims_certainty():
    raw, y = _scores(300, 500)
    cx, cy = fit_calibration(raw, y)
    assert np.all(np.diff(cx) >= 0) and np.all(np.diff(cy) >= -1e-12)
    assert 0.0 < cy.min() and cy.max() < 1.0
    # The lowest step holds only healthy records (the scores overlap only in
    # the middle): it reads their Jeffreys estimate at even odds.
    p = np.interp(raw, cx, cy)
    low = p == cy.min()
    assert low.sum() > 50 and not y[low].any()
    w_pos, w_neg = 0.5 / y.sum(), 0.5 / (~y).sum()
    expected = w_pos * 0.5 / (w_pos * 0.5 + w_neg * (low.sum() + 0.5))
    assert cy.min() == pytest.approx(expected, rel=1e-9)


def test_large_steps_keep_the_isotonic_fraction():
    from sklearn.isotonic import IsotonicRegression
    raw, y = _scores(2000, 2000, seed=1)
    cx, cy = fit_calibration(raw, y)
    w = np.where(y, 0.5 / y.sum(), 0.5 / (~y).sum())
    plain = IsotonicRegression(out_of_bounds='clip').fit(raw, y, sample_weight=w).predict(raw)
    p = np.interp(raw, cx, cy)
    # Half a record of each class moves a step of many records very little,
    # and the even-odds threshold keeps every record on its side.
    assert np.max(np.abs(p - plain)) < 0.05
    assert np.array_equal(p >= 0.5, plain >= 0.5)


def test_a_tail_probability_is_printed_with_a_third_decimal():
    assert probability_text(0.0023) == '0.002'
    assert probability_text(0.9985) in ('0.998', '0.999')
    assert probability_text(0.4567) == '0.46'
    assert probability_text(0.01) == '0.01'


def test_the_large_networks_logits_are_kept_and_read_back(tmp_path):
    seeds = [3, 7]
    fresh = stack.seed_logits(seeds)
    cached = stack.seed_logits(seeds, cache=tmp_path)
    assert np.array_equal(fresh, cached) and np.all(np.isfinite(fresh))
    files = list(tmp_path.glob('large_logits_*.npy'))
    assert len(files) == 1
    # Read back, not recomputed: what the file holds is what comes out.
    np.save(files[0], np.array([11.0, -11.0]))
    assert stack.seed_logits(seeds, cache=tmp_path).tolist() == [11.0, -11.0]
    # Other seeds are another file.
    stack.seed_logits([3], cache=tmp_path)
    assert len(list(tmp_path.glob('large_logits_*.npy'))) == 2


def test_the_reliability_table_finds_a_calibrated_probability_calibrated():
    from stiction_ros.study.accuracy_study import reliability
    rng = np.random.default_rng(2)
    p = rng.uniform(0.0, 1.0, 40000)
    y = rng.uniform(0.0, 1.0, p.size) < p
    rel = reliability(y, p)
    # Uniform p makes the classes equally common, so even odds changes nothing.
    for lo, hi, n, k, stated, seen in rel['rows']:
        assert n == np.sum((p >= lo) & (p < hi)) and k <= n
        assert abs(stated - seen) < 4.0 * np.sqrt(0.25 / n) + 0.01
    assert np.isfinite(rel['log_loss'])
    # One sticky record stated impossible: the log loss says so.
    assert reliability(np.r_[y, True], np.r_[p, 0.0])['log_loss'] == np.inf

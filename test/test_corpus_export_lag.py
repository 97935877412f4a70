"""The corpus's export lag: PV read through a filter the controller never saw."""

import dataclasses

import numpy as np

from stiction_ros.analysis.detection.timing import law_r2, through_lag
from stiction_ros.sim.corpus import draw_scenario, PV_LAGS, simulate


def test_export_lags_are_drawn_for_both_labels_alike_within_their_range():
    drawn = [draw_scenario(s) for s in range(1500)]
    for label in (False, True):
        share = np.mean([s.pv_lag > 0.0 for s in drawn if s.label == label])
        assert 0.19 < share < 0.31, (label, share)
    lags = [s.pv_lag for s in drawn if s.pv_lag > 0.0]
    assert PV_LAGS[0] <= min(lags) and max(lags) <= PV_LAGS[1]
    for s in drawn[:200]:
        # The lag comes from a stream of its own: the other label keeps it.
        assert draw_scenario(s.seed, not s.label).pv_lag == s.pv_lag


def test_the_controller_never_sees_the_export_lag():
    # OP and the valve are the twin's to the bit, and the exported PV is the
    # twin's PV through the analyzer's own lag filter: the lag is the export's.
    checked = 0
    for seed in range(200):
        sc = draw_scenario(seed)
        if sc.pv_lag < 1.0:
            continue
        rec = simulate(sc)
        twin = simulate(dataclasses.replace(sc, pv_lag=0.0))
        assert np.array_equal(rec['op'], twin['op'])
        assert np.array_equal(rec['mv'], twin['mv'])
        np.testing.assert_allclose(rec['pv'], through_lag(twin['pv'], sc.pv_lag),
                                   rtol=0.0, atol=1e-9)
        assert np.std(np.diff(rec['pv'])) < np.std(np.diff(twin['pv']))
        checked += 1
        if checked == 5:
            break
    assert checked == 5


def test_the_law_holds_through_the_drawn_lag_and_not_as_exported():
    # A lag commutes with the PI law: OP and SP through the drawn lag explain
    # the lagged PV as OP explained the PV the controller read.
    checked = 0
    for seed in range(400):
        sc = draw_scenario(seed)
        if sc.pv_lag < 3.0 or sc.label or sc.look_alike or sc.law:
            continue
        rec = simulate(sc)
        through = law_r2(rec['op'], rec['pv'], rec['sp'], 0, lag=sc.pv_lag)
        exported = law_r2(rec['op'], rec['pv'], rec['sp'], 0)
        assert through > 0.99, (seed, through)
        assert exported < through - 0.05, (seed, exported, through)
        checked += 1
        if checked == 4:
            break
    assert checked == 4

"""Sticky simulated records that OP and PV cannot tell from a deadband."""

from dataclasses import replace

import numpy as np

from stiction_ros.analysis.detection import dataset, deadband_like
from stiction_ros.sim.corpus import draw_scenario, simulate


def test_a_deadband_has_no_slip_footprint_and_a_larger_slip_a_larger_one():
    base = draw_scenario(100_014)   # a quiet self-regulating loop, S 6.5 %
    assert base.label and not base.integrating
    slip, full = [], []
    for j_over_s in (0.0, 0.3, 1.0):
        sc = replace(base, valve='kano', J=j_over_s * base.S)
        rec = simulate(sc)
        slip.append(deadband_like.slip_footprint(sc, rec))
        full.append(dataset.stiction_footprint(sc, rec))
    # Every one of them is far from a frictionless valve ...
    assert min(full) > 10.0
    # ... but only the slip sets it apart from a deadband, the more the larger the slip.
    assert slip[0] < 0.05
    assert 1.0 < slip[1] < slip[2]


def test_a_record_without_stiction_has_no_slip_footprint():
    seed = next(s for s in range(100_000, 100_050) if not draw_scenario(s).label)
    sc = draw_scenario(seed)
    assert np.isnan(deadband_like.slip_footprint(sc, simulate(sc)))


def test_only_sticky_records_below_the_bar_are_left_out_and_counted(tmp_path):
    seeds = np.arange(100_000, 100_016)
    y = np.array([draw_scenario(int(s)).label for s in seeds])
    data = {'seed': seeds, 'y': y, 'x': np.random.default_rng(0).normal(size=(16, 3)),
            'kind': np.array(['k'] * 16), 'skipped': {'under_sampled': 2}, 'seconds': 1.0}
    marked = deadband_like.mark(data, jobs=2, cache=tmp_path)
    fp = marked['slip_footprint']
    assert np.all(np.isnan(fp[~y])) and np.all(np.isfinite(fp[y]))
    assert np.array_equal(marked['deadband_like'], y & (fp < dataset.MIN_FOOTPRINT))
    assert marked['deadband_like'].any() and (y & ~marked['deadband_like']).any()
    kept = deadband_like.leave_out(marked)
    keep = ~marked['deadband_like']
    for k in ('seed', 'y', 'x', 'kind', 'slip_footprint'):
        np.testing.assert_array_equal(kept[k], marked[k][keep])
    assert kept['skipped'] == {'under_sampled': 2,
                               deadband_like.SKIP_CODE: int(marked['deadband_like'].sum())}
    assert kept['seconds'] == 1.0
    # Kept under the seeds and the code: read back, not recomputed.
    files = list(tmp_path.glob('slip_footprint_*.npy'))
    assert len(files) == 1
    np.testing.assert_array_equal(np.load(files[0]), fp)
    np.save(files[0], fp + 1.0)
    again = deadband_like.seed_footprints(seeds, jobs=1, cache=tmp_path)
    np.testing.assert_array_equal(again, fp + 1.0)


def test_the_accuracy_page_gives_the_score_with_them_counted_beside_the_one_without():
    from stiction_ros.cli.accuracy_markdown import _deadband_like
    from stiction_ros.study.accuracy_study import score
    truth = [True] * 4 + [False] * 4
    called = [True, True, False, False, False, False, False, True]
    study = {'sim_skipped': {'stiction_hidden': 3, deadband_like.SKIP_CODE: 2},
             'sim_with_deadband_like': score(truth, called), 'sim_deadband_like_called': 1}
    text = ' '.join(_deadband_like(study))
    assert '2 sticky records' in text and 'called 1 of them' in text
    assert '0.625' in text and '2/4 sticky found' in text and '1/4 healthy flagged' in text
    # A study written before the split says nothing of it.
    assert _deadband_like({'sim_skipped': {'stiction_hidden': 3}}) == []

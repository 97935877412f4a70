"""The detector's training set and model are reproducible from their seeds, and cached safely."""

import warnings

import numpy as np
import pytest

from stiction_ros.analysis.detection import dataset, model_file
from stiction_ros.analysis.detection.features import FEATURE_NAMES

pytest.importorskip('sklearn')
SEEDS = range(7000, 7040)


@pytest.fixture(scope='module')
def small(tmp_path_factory):
    # An AVX-512 host without the Makefile's NumPy pin is warned (test_blas.py):
    # these figures need only agree with themselves.
    cache = tmp_path_factory.mktemp('cache')
    with warnings.catch_warnings():
        warnings.filterwarnings('ignore', message='computing the figures on NumPy')
        return dataset.build(SEEDS, jobs=1, progress=False, cache=cache), cache


@pytest.mark.slow
def test_a_set_is_the_same_whether_computed_or_read_from_the_cache(small):
    first, cache = small
    files = list(cache.glob('features_7000_7040_*.npz'))
    assert len(files) == 1 and dataset.code_version() in files[0].name
    again = dataset.build(SEEDS, jobs=1, progress=False, cache=cache)
    for k in ('x', 'y', 'seed', 'kind', 'old_rule'):
        assert np.array_equal(first[k], again[k], equal_nan=(k == 'x')), k
    assert first['skipped'] == again['skipped']
    assert first['x'].shape[1] == len(FEATURE_NAMES)
    # Every seed is either a row or a counted skip: nothing is lost silently.
    assert len(first['y']) + sum(first['skipped'].values()) == len(SEEDS)


def test_two_processes_give_the_same_rows_as_one(small):
    first, _ = small
    two = dataset.build(range(7000, 7012), jobs=2, progress=False)
    rows = np.isin(first['seed'], two['seed'])
    assert np.array_equal(first['x'][rows], two['x'], equal_nan=True)


def test_training_twice_gives_the_same_file(small, tmp_path):
    from stiction_ros.analysis.detection.train import train
    d, _ = small
    half = len(d['y']) // 2
    if len(set(d['y'][:half])) < 2:
        pytest.skip('the small set drew one label only')
    paths = []
    for i in range(2):
        m, _ = train(d['x'][:half], d['y'][:half], d['x'][half:], d['y'][half:], FEATURE_NAMES,
                     {'run': 'test'}, max_iter=20, min_samples_leaf=2)
        paths.append(tmp_path / f'm{i}.npz')
        model_file.save(paths[-1], m)
    a, b = (model_file.load(p, FEATURE_NAMES) for p in paths)
    for k in model_file.ARRAYS:
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    assert np.array_equal(a.probability(d['x']), b.probability(d['x']))


@pytest.mark.slow
def test_the_make_target_writes_a_model_that_names_the_code_its_figures_ran_on(tmp_path):
    # stiction-detector end to end on the fewest records it takes, as `make detector`
    # runs it: with NumPy's code for a processor without AVX-512 where that is x86 code.
    import os
    import platform
    import subprocess
    import sys
    from stiction_ros import _blas
    x86 = platform.machine().lower() in ('x86_64', 'amd64')
    env = {**os.environ, _blas.NUMPY_PIN: ' '.join(_blas.NUMPY_ABOVE_AVX2) if x86 else ''}
    out = tmp_path / 'd.npz'
    # 60 and 20 seeds keep 9 and 3 sticky records: the fewest that train and calibrate.
    res = subprocess.run([sys.executable, '-m', 'stiction_ros.cli.detector', '--train', '60',
                          '--calibration', '20', '--jobs', '1', '--cache',
                          str(tmp_path / 'cache'), '--out', str(out)],
                         env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    model = model_file.load(out, FEATURE_NAMES)
    assert model.meta['train_seeds'] == [dataset.TRAIN.start, dataset.TRAIN.start + 60]
    assert f'figures computed with: {model.meta["kernels"]}' in res.stderr
    if x86 and set(_blas.NEEDS) <= _blas._cpu_flags():
        # The header says the pin held: the Haswell kernels and AVX2 code alone.
        assert model.meta['kernels'].startswith(_blas.KERNEL + ';')
        assert model.meta['kernels'].endswith('; X86_V3')


def test_a_set_too_small_to_train_on_is_refused_with_the_count_it_lacks(capsys):
    from stiction_ros.cli.detector import enough_of_each, main, MIN_TRAIN
    from stiction_ros.errors import TrainingSetError
    assert main(['--train', str(MIN_TRAIN - 1), '--out', '/nonexistent/d.npz']) == 2
    assert f'at least {MIN_TRAIN} training' in capsys.readouterr().err
    enough_of_each(np.array([1, 0, 1, 0, 0]), 2, 'training')
    with pytest.raises(TrainingSetError, match='keeps 1 sticky and 4 healthy.*needs 2 of each'):
        enough_of_each(np.array([1, 0, 0, 0, 0]), 2, 'training')
